"""The pure statistics of the sRGB fit (noise/fit.py) against independent constructions."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.noise.correlated import kernel_autocorrelation, structured_normal
from darksynth.noise.fit import (
    LENGTH_GRID,
    PoissonGaussian,
    autocorrelation,
    channel_correlations,
    clipped,
    fit_correlation_length,
    length_for_lag1,
    model_std,
    oracle_poisson_gaussian,
    values_of_law,
    weighted_line,
)
from darksynth.noise.values import NoiseValues


def test_weighted_line_recovers_a_line_and_keeps_both_terms_non_negative() -> None:
    level = np.linspace(0.1, 0.9, 9)
    a, b = weighted_line(level, 2e-3 * level + 1e-4, np.ones_like(level))
    assert a == pytest.approx(2e-3) and b == pytest.approx(1e-4)
    falling_a, falling_b = weighted_line(level, 1e-3 - 5e-4 * level, np.ones_like(level))
    assert falling_a == 0.0 and falling_b > 0.0
    through_zero_a, through_zero_b = weighted_line(level, 3e-3 * level - 2e-4, np.ones_like(level))
    assert through_zero_b == 0.0 and through_zero_a > 0.0


def test_the_law_of_a_noise_map_and_its_values() -> None:
    generator = torch.Generator().manual_seed(0)
    clean = torch.linspace(0.05, 0.8, 256, dtype=torch.float64).view(1, 1, -1).expand(3, 256, -1)
    law = PoissonGaussian(a=(2e-3, 1e-3, 5e-4), b=(4e-5, 1e-5, 1e-5))
    noisy = clean + torch.randn(clean.shape, generator=generator, dtype=torch.float64) * law.std(clean)
    fitted = oracle_poisson_gaussian(noisy, clean)
    assert fitted.a[1] == pytest.approx(1e-3, rel=0.1)
    values = values_of_law(fitted, clean)
    assert values.scalar("shot") == pytest.approx(1e-3**0.5, rel=0.05)
    red, blue = values["channel_gain"].tolist()
    assert red > 1.2 and blue < 0.9
    assert model_std(clean, values)[1].mean() == pytest.approx(float(law.std(clean)[1].mean()), rel=0.05)


def test_length_and_channel_correlations_of_structured_noise() -> None:
    shape = (1, 3, 256, 256)
    lengths = torch.tensor([1.0], dtype=torch.float64)
    pairs = torch.tensor([0.6, 0.2, 0.4], dtype=torch.float64)
    generator = torch.Generator().manual_seed(1)
    unit = structured_normal(
        shape, lengths[0], pairs, torch.ones(2, dtype=torch.float64), generator=generator, dtype=torch.float64
    )[0]
    assert fit_correlation_length(autocorrelation(unit)) == pytest.approx(1.0, abs=0.1)
    assert channel_correlations(unit) == pytest.approx([0.6, 0.2, 0.4], abs=0.05)


def test_length_for_lag1_inverts_the_kernel_theory() -> None:
    for length in (0.0, 0.5, 1.2, 2.0):
        assert length_for_lag1(kernel_autocorrelation(length, 1)) == pytest.approx(length, abs=0.021)
    assert max(LENGTH_GRID) == 4.0


def test_clipped_uses_the_table_bounds() -> None:
    assert clipped("channel_correlation", -2.0) == -0.45
    assert clipped("shot", 5.0) == 1.0
    assert NoiseValues.from_values({"shot": clipped("shot", 0.1)}).scalar("shot") == 0.1
