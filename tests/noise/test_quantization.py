"""Quantization noise: one-sided uniform U(0, q) on a grid of 256 levels."""

from __future__ import annotations

import math

import scipy.stats
import torch

from darksynth.noise.quantization import QUANTIZATION_LEVELS, quantization_noise
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues

STEP = 0.02


def _draw(shape: tuple[int, ...], step: torch.Tensor | float, seed: int) -> torch.Tensor:
    return quantization_noise(shape, step, generator=torch.Generator().manual_seed(seed))


def test_values_lie_in_half_open_interval_and_fill_it() -> None:
    noise = _draw((1, 3, 256, 256), STEP, seed=1)
    assert noise.dtype == torch.float32
    assert (noise >= 0.0).all()
    assert (noise < STEP).all()
    # With ~200k draws every one of the 256 levels occurs, so the extremes are the outermost bin midpoints.
    assert math.isclose(noise.min().item(), 0.5 * STEP / QUANTIZATION_LEVELS, rel_tol=1e-5)
    assert math.isclose(noise.max().item(), 255.5 * STEP / QUANTIZATION_LEVELS, rel_tol=1e-5)


def test_values_sit_on_the_256_level_grid_with_equal_frequencies() -> None:
    noise = _draw((1, 3, 256, 256), STEP, seed=2).double()
    levels = noise / (STEP / QUANTIZATION_LEVELS) - 0.5
    assert (levels - levels.round()).abs().max().item() < 1e-3
    counts = torch.bincount(levels.round().long().flatten(), minlength=QUANTIZATION_LEVELS)
    assert counts.numel() == QUANTIZATION_LEVELS
    # Chi-square test of equal frequencies: under uniformity the p-value is uniform, so 1e-3 is a rare miss.
    assert scipy.stats.chisquare(counts.numpy()).pvalue > 1e-3


def test_mean_and_variance_of_uniform() -> None:
    noise = _draw((2, 3, 256, 256), STEP, seed=3).double()
    n = noise.numel()
    # Mean of U(0, q) is q / 2 with standard error q / sqrt(12 n); 5 of them.
    assert abs(noise.mean().item() - STEP / 2) < 5.0 * STEP / math.sqrt(12.0 * n)
    # The 256 bin midpoints have variance q^2 / 12 * (1 - 1 / 256^2). The sample variance's standard error is
    # sqrt((mu4 - sigma^4) / n) with mu4 = q^4 / 80 for a uniform law; 5 of them.
    expected_var = STEP**2 / 12.0 * (1.0 - 1.0 / QUANTIZATION_LEVELS**2)
    se_var = STEP**2 * math.sqrt(1.0 / 80.0 - 1.0 / 144.0) / math.sqrt(n)
    assert abs(noise.var().item() - expected_var) < 5.0 * se_var


def test_zero_step_gives_exact_zeros() -> None:
    noise = _draw((1, 3, 32, 32), 0.0, seed=4)
    assert torch.equal(noise, torch.zeros(1, 3, 32, 32))


def test_per_clip_steps() -> None:
    steps = (0.004, 0.05)
    noise = _draw((2, 1, 3, 128, 128), torch.tensor(steps), seed=5).double()
    n = noise[0].numel()
    for clip, step in enumerate(steps):
        assert (noise[clip] < step).all()
        assert noise[clip].max().item() > 0.99 * step
        assert abs(noise[clip].mean().item() - step / 2) < 5.0 * step / math.sqrt(12.0 * n)


def test_composer_adds_the_one_sided_offset() -> None:
    # The paper's model is one-sided: a flat signal gains q / 2 on average, it is not re-centred.
    signal = torch.full((1, 3, 128, 128), 0.25)
    values = NoiseValues.from_values({"quantization": STEP}, dtype=torch.float32)
    noise = noise_sum(signal, values, generator=torch.Generator().manual_seed(6)).double()
    assert (noise >= 0.0).all() and (noise < STEP).all()
    assert abs(noise.mean().item() - STEP / 2) < 5.0 * STEP / math.sqrt(12.0 * noise.numel())


def test_same_seed_same_draw_different_seed_different_draw() -> None:
    a = _draw((1, 3, 32, 32), STEP, seed=7)
    assert torch.equal(a, _draw((1, 3, 32, 32), STEP, seed=7))
    assert not torch.equal(a, _draw((1, 3, 32, 32), STEP, seed=8))
