"""estimation/self_check.py: the flattest in-range blocks, and the ratio and supported level factor of a profile's
noise put back on a denoised reference."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.estimation.self_check import (
    CHECK_MEAN_RANGE,
    checked_blocks,
    checked_blocks_per_intensity,
    self_consistency,
)


def _scene(height: int = 256, width: int = 320) -> torch.Tensor:
    """(3, H, W): grey steps from dark to mid-grey, one a 32-px block column, a strong grating in the bottom rows."""
    x = torch.linspace(0.05, 0.6, width // 32, dtype=torch.float64).repeat_interleave(32)
    scene = x.expand(3, height, width).clone()
    scene[:, height // 2 :, :] += 0.2 * torch.sin(torch.arange(width, dtype=torch.float64) * 1.3)
    return scene.clamp(0, 1)


def _noisy(scene: torch.Tensor, std: float, seed: int) -> torch.Tensor:
    return scene + std * torch.randn(scene.shape, generator=torch.Generator().manual_seed(seed), dtype=scene.dtype)


def test_checked_blocks_are_the_flattest_tenth_inside_the_mean_range() -> None:
    scene = _scene()
    scene[:, :64, :64] = 0.0  # crushed black: the flattest blocks of all, and outside the range
    chosen = checked_blocks(scene).reshape(8, 10)
    assert not bool(chosen[:2, :2].any())
    assert int(chosen.sum()) == round(0.1 * (80 - 4))
    assert not bool(chosen[4:].any())  # the grating's rows are never the flattest
    assert CHECK_MEAN_RANGE == (8 / 255, 247 / 255)


@pytest.mark.parametrize("factor", [0.5, 1.0, 3.0])
def test_the_ratio_and_the_supported_factor_read_a_scaled_noise_back(factor: float) -> None:
    scene = _scene()
    real = _noisy(scene, 0.01, 0)
    synthetic = _noisy(scene, 0.01 * factor, 1)
    check = self_consistency(real, scene, synthetic)
    assert check.ratio == pytest.approx(factor, rel=0.05)
    assert check.supported == pytest.approx(1 / factor, rel=0.05)
    assert check.consistent == (factor == 1.0)


def test_blocks_per_intensity_cover_every_segment_with_enough_blocks() -> None:
    chosen = checked_blocks_per_intensity(_scene())
    assert len(chosen) >= 3
    for blocks in chosen.values():
        assert int(blocks.sum()) >= 3


def test_a_scene_the_denoiser_kept_rougher_than_the_reference_supports_no_factor() -> None:
    scene = _scene()
    check = self_consistency(scene, _noisy(scene, 0.02, 0), _noisy(scene, 0.03, 1))
    assert math.isnan(check.supported)
