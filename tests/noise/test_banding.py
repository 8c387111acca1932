"""Column banding: per-frame (banding) and held over a clip (temporal_banding)."""

from __future__ import annotations

import math

import torch

from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues

SIGMA = 0.03


def _values(**nonzero: float) -> NoiseValues:
    return NoiseValues.from_values(nonzero, dtype=torch.float32)


def _correlation(a: torch.Tensor, b: torch.Tensor) -> float:
    a, b = a.flatten().double(), b.flatten().double()
    return torch.corrcoef(torch.stack([a, b]))[0, 1].item()


def _std_band(sigma: float, n: int) -> float:
    # The sample standard deviation of n Gaussian draws has standard error sigma / sqrt(2 (n - 1)); 5 of them.
    return 5.0 * sigma / math.sqrt(2.0 * (n - 1))


def test_banding_is_constant_down_columns_and_varies_across_columns_channels_frames() -> None:
    signal = torch.full((2, 4, 3, 24, 512), 0.5)
    noise = noise_sum(signal, _values(banding=SIGMA), generator=torch.Generator().manual_seed(1))
    assert noise.shape == signal.shape
    # Every row of every frame equals that frame's first row.
    assert torch.equal(noise, noise[..., :1, :].expand_as(noise))

    rows = noise[..., 0, :]  # (2, 4, 3, 512): one draw per clip, frame, channel and column
    n = rows.shape[-1]
    # Columns are independent: neighbouring columns are uncorrelated (5 standard errors 1 / sqrt(n) of a
    # correlation estimate, here over all 2*4*3*511 neighbour pairs).
    pairs = rows[..., :-1].numel()
    assert abs(_correlation(rows[..., :-1], rows[..., 1:])) < 5.0 / math.sqrt(pairs)
    # Channels, frames and clips each get their own pattern: uncorrelated, 5 standard errors.
    assert abs(_correlation(rows[:, :, 0], rows[:, :, 1])) < 5.0 / math.sqrt(2 * 4 * n)
    assert abs(_correlation(rows[:, 0], rows[:, 1])) < 5.0 / math.sqrt(2 * 3 * n)
    assert abs(_correlation(rows[0], rows[1])) < 5.0 / math.sqrt(4 * 3 * n)
    # Column offsets are zero-mean with std sigma over all columns.
    assert abs(rows.std().item() - SIGMA) < _std_band(SIGMA, rows.numel())
    assert abs(rows.mean().item()) < 5.0 * SIGMA / math.sqrt(rows.numel())


def test_banding_function_returns_a_row_pattern_with_std_sigma() -> None:
    pattern = banding_noise((8, 3, 100, 1024), SIGMA, generator=torch.Generator().manual_seed(2))
    assert pattern.shape == (8, 3, 1, 1024)
    assert abs(pattern.std().item() - SIGMA) < _std_band(SIGMA, pattern.numel())


def test_banding_per_clip_sigma() -> None:
    sigmas = (0.01, 0.04)
    pattern = banding_noise((2, 4, 3, 8, 1024), torch.tensor(sigmas), generator=torch.Generator().manual_seed(3))
    for clip, sigma in enumerate(sigmas):
        assert abs(pattern[clip].std().item() - sigma) < _std_band(sigma, pattern[clip].numel())


def test_temporal_banding_is_identical_in_every_frame_of_a_clip() -> None:
    signal = torch.full((2, 6, 3, 16, 512), 0.5)
    noise = noise_sum(signal, _values(temporal_banding=SIGMA), generator=torch.Generator().manual_seed(4))
    assert torch.equal(noise, noise[:, :1].expand_as(noise))
    assert torch.equal(noise, noise[..., :1, :].expand_as(noise))

    rows = noise[:, 0, :, 0, :]  # (2, 3, 512)
    # The two clips of the batch have independent patterns: correlation 0 within 5 standard errors.
    assert abs(_correlation(rows[0], rows[1])) < 5.0 / math.sqrt(rows[0].numel())
    assert abs(_correlation(rows[:, 0], rows[:, 1])) < 5.0 / math.sqrt(rows[:, 0].numel())
    assert abs(rows.std().item() - SIGMA) < _std_band(SIGMA, rows.numel())


def test_temporal_banding_differs_between_draws() -> None:
    generator = torch.Generator().manual_seed(5)
    shape = (4, 3, 16, 1024)
    first = temporal_banding_noise(shape, SIGMA, generator=generator)
    second = temporal_banding_noise(shape, SIGMA, generator=generator)
    assert first.shape == (1, 3, 1, 1024)
    assert abs(_correlation(first, second)) < 5.0 / math.sqrt(first.numel())
    both = torch.cat([first, second])
    assert abs(both.std().item() - SIGMA) < _std_band(SIGMA, both.numel())


def test_temporal_banding_per_clip_sigma() -> None:
    sigmas = (0.005, 0.02)
    pattern = temporal_banding_noise(
        (2, 5, 3, 8, 2048), torch.tensor(sigmas), generator=torch.Generator().manual_seed(6)
    )
    assert pattern.shape == (2, 1, 3, 1, 2048)
    for clip, sigma in enumerate(sigmas):
        assert abs(pattern[clip].std().item() - sigma) < _std_band(sigma, pattern[clip].numel())
