"""The blocks the noise is measured on (estimation/noise/flat_blocks.py): the denoiser's strength read on them must
follow noise that grows with the level to where it is strongest."""

from __future__ import annotations

import torch

from darksynth.estimation.noise.flat_blocks import (
    FLAT_BLOCK,
    denoiser_strength,
    flat_block_std,
    stated_denoiser_strength,
)


def _frame(levels: list[float], stds: list[float], textured: list[bool], seed: int = 0) -> torch.Tensor:
    """One (1, 3, H, W) frame of 32-px blocks in rows: row r at ``levels[r]`` with white noise of ``stds[r]``
    (8-bit levels), and, where ``textured[r]``, a fine checkerboard of 20 levels on top (texture, not noise)."""
    generator = torch.Generator().manual_seed(seed)
    rows = []
    for level, std, texture in zip(levels, stds, textured, strict=True):
        row = torch.full((3, FLAT_BLOCK, 12 * FLAT_BLOCK), level)
        if texture:
            y, x = torch.meshgrid(torch.arange(FLAT_BLOCK), torch.arange(12 * FLAT_BLOCK), indexing="ij")
            row = row + ((x // 2 + y // 2) % 2).to(row) * (20 / 255) - 10 / 255
        rows.append(row + torch.randn(row.shape, generator=generator) * std / 255)
    return torch.cat(rows, dim=1).clamp(0.0, 1.0)[None]


def test_noise_that_grows_with_the_level_sets_the_strength_where_it_is_strongest() -> None:
    # Shot noise: std as sqrt(level), 2 levels at 0.05 and 4.2 at 0.22 (fewer blocks there): the strength follows
    # the bright, noisier segment, as a dark reference's denoiser must (set from its darkest blocks, it left the
    # noise in place).
    frame = _frame([0.05, 0.05, 0.05, 0.22], [2.0, 2.0, 2.0, 4.2], [False] * 4)
    strength = flat_block_std(frame)
    assert 3.6 < strength < 4.8, strength


def test_the_stated_strength_is_the_profile_s_and_else_the_rule_on_the_first_frame() -> None:
    generator = torch.Generator().manual_seed(4)
    frames = (0.3 + 0.02 * torch.randn(2, 3, 96, 96, generator=generator)).clamp(0.0, 1.0)
    frames[1] += 0.1  # a second frame the rule must not read
    assert stated_denoiser_strength({"spectrum": {"denoiser_strength_8bit": 7.5}}, frames) == 7.5
    rule = denoiser_strength(frames[:1])
    assert stated_denoiser_strength({}, frames) == rule
    assert stated_denoiser_strength({"spectrum": {}}, frames) == rule
