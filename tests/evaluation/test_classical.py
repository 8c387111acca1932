"""The baselines' classical estimators: round trips on images with known noise laws."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.evaluation.methods.classical import (
    PoissonGaussian,
    add_poisson_gaussian,
    blind_gaussian_sigma,
    blind_poisson_gaussian,
    oracle_poisson_gaussian,
    weighted_line,
)
from darksynth.tensors import to_8bit_levels

LAW = PoissonGaussian(a=(1e-3, 2e-3, 5e-4), b=(1e-4, 4e-4, 2.5e-5))


def smooth_scene(size: int = 384) -> torch.Tensor:
    """A smooth (3, H, W) scene covering levels 0.1-0.9: little texture, as the blind fit needs."""
    y, x = torch.meshgrid(
        torch.linspace(0, 1, size, dtype=torch.float64), torch.linspace(0, 1, size, dtype=torch.float64), indexing="ij"
    )
    ramp = 0.1 + 0.8 * (0.7 * x + 0.3 * y)
    return torch.stack([ramp, ramp.flip(-1), 0.5 + 0.3 * torch.sin(3 * x) * torch.cos(2 * y)])


def test_weighted_line_recovers_a_line_and_keeps_both_terms_non_negative() -> None:
    level = np.linspace(0.1, 0.9, 9)
    a, b = weighted_line(level, 2e-3 * level + 1e-4, np.ones_like(level))
    assert a == pytest.approx(2e-3) and b == pytest.approx(1e-4)
    falling_a, falling_b = weighted_line(level, 1e-3 - 5e-4 * level, np.ones_like(level))
    assert falling_a == 0.0 and falling_b > 0.0
    through_zero_a, through_zero_b = weighted_line(level, 3e-3 * level - 2e-4, np.ones_like(level))
    assert through_zero_b == 0.0 and through_zero_a > 0.0


def test_to_8bit_levels_rounds_and_clips() -> None:
    levels = to_8bit_levels(torch.tensor([-0.2, 0.5, 0.50001, 1.3], dtype=torch.float64))
    assert torch.equal(levels * 255, (levels * 255).round())
    assert levels.min() == 0.0 and levels.max() == 1.0


def test_added_noise_follows_the_variance_law() -> None:
    clean = torch.full((3, 256, 256), 0.0, dtype=torch.float64)
    generator = torch.Generator().manual_seed(0)
    for level in (0.2, 0.6):
        noisy = add_poisson_gaussian(clean + level, LAW, generator)
        variance = (noisy - level).var(dim=(1, 2))
        expected = torch.tensor(LAW.a) * level + torch.tensor(LAW.b) + 1 / (12 * 255**2)
        assert torch.allclose(variance, expected.double(), rtol=0.05)


def test_oracle_fit_recovers_the_law() -> None:
    clean = to_8bit_levels(smooth_scene())
    noisy = add_poisson_gaussian(clean, LAW, torch.Generator().manual_seed(1))
    fitted = oracle_poisson_gaussian(noisy, clean)
    for got, want in zip(fitted.a, LAW.a, strict=True):
        assert got == pytest.approx(want, rel=0.1)
    # b is an extrapolation to black; the law itself is judged over the levels the scene has.
    for level in (0.2, 0.8):
        got = fitted.std(torch.full((3, 1, 1), level, dtype=torch.float64)).flatten()
        want = LAW.std(torch.full((3, 1, 1), level, dtype=torch.float64)).flatten()
        assert torch.allclose(got, want, rtol=0.05)


def test_blind_fit_recovers_the_law_from_the_noisy_image_alone() -> None:
    clean = smooth_scene()
    noisy = add_poisson_gaussian(clean, LAW, torch.Generator().manual_seed(2))
    fitted = blind_poisson_gaussian(noisy)
    for channel in range(3):
        # Compare standard deviations at mid-grey, what the synthetic noise is judged on.
        got = (fitted.a[channel] * 0.5 + fitted.b[channel]) ** 0.5
        want = (LAW.a[channel] * 0.5 + LAW.b[channel]) ** 0.5
        assert got == pytest.approx(want, rel=0.15)
    # The slope tells shot from read noise: the green channel's law is the steepest.
    assert fitted.a[1] > fitted.a[2]


def test_blind_gaussian_sigma_recovers_white_noise() -> None:
    clean = smooth_scene()
    noisy = clean + 0.03 * torch.randn(clean.shape, generator=torch.Generator().manual_seed(3), dtype=clean.dtype)
    sigmas = blind_gaussian_sigma(noisy)
    assert sigmas == pytest.approx((0.03, 0.03, 0.03), rel=0.1)
