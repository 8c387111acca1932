"""Heteroscedastic noise: N(0, shot^2 * x + read^2) at every pixel."""

from __future__ import annotations

import math

import pytest
import scipy.stats
import torch

from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_std
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues

SHOT = 0.1
READ = 0.02


def _variance_band(variance: float, n: int) -> float:
    # The sample variance of n Gaussian draws has standard error variance * sqrt(2 / (n - 1)); 5 of them.
    return 5.0 * variance * math.sqrt(2.0 / (n - 1))


@pytest.mark.parametrize("level", [0.0, 0.05, 0.3, 1.0])
def test_flat_image_variance_mean_and_gaussian_shape(level: float) -> None:
    signal = torch.full((1, 3, 128, 128), level)
    noise = heteroscedastic_noise(signal, SHOT, READ, generator=torch.Generator().manual_seed(11))
    n = noise.numel()
    expected_var = SHOT**2 * level + READ**2

    assert abs(noise.var().item() - expected_var) < _variance_band(expected_var, n)
    # Mean zero within 5 standard errors sqrt(var / n).
    assert abs(noise.mean().item()) < 5.0 * math.sqrt(expected_var / n)

    standardised = (noise / math.sqrt(expected_var)).flatten().double().numpy()
    # Kurtosis of a normal is 3, its estimator's standard error is sqrt(24 / n); 5 of them.
    assert abs(scipy.stats.kurtosis(standardised, fisher=False) - 3.0) < 5.0 * math.sqrt(24.0 / n)
    # Skewness 0 with standard error sqrt(6 / n).
    assert abs(scipy.stats.skew(standardised)) < 5.0 * math.sqrt(6.0 / n)
    # Under the null hypothesis the KS p-value is uniform, so a fixed seed fails with probability 1e-3.
    assert scipy.stats.kstest(standardised, "norm").pvalue > 1e-3


def test_kolmogorov_smirnov_rejects_a_wrong_law() -> None:
    # Power check of the band above: uniform noise of the same variance must be rejected.
    generator = torch.Generator().manual_seed(0)
    uniform = (torch.rand(3 * 128 * 128, generator=generator) - 0.5) * math.sqrt(12.0)
    assert scipy.stats.kstest(uniform.double().numpy(), "norm").pvalue < 1e-6


def test_ramp_least_squares_recovers_shot_and_read() -> None:
    width, rows, channels = 64, 2048, 2
    levels = torch.linspace(0.0, 1.0, width)
    signal = levels.expand(1, channels, rows, width).contiguous()
    noise = heteroscedastic_noise(signal, SHOT, READ, generator=torch.Generator().manual_seed(3))

    samples = noise.permute(3, 0, 1, 2).reshape(width, -1).double()
    n = samples.shape[1]
    column_var = samples.var(dim=1)
    design = torch.stack([levels.double(), torch.ones(width, dtype=torch.float64)], dim=1)
    solution = torch.linalg.lstsq(design, column_var[:, None]).solution[:, 0]
    shot_sq, read_sq = solution.tolist()

    # Standard errors of the ordinary least-squares coefficients from the sampling distribution of each
    # column's variance, Var(s^2) = 2 sigma^4 / (n - 1): Cov = (X'X)^-1 X' diag(v) X (X'X)^-1.
    true_var = SHOT**2 * levels.double() + READ**2
    gram_inv = torch.linalg.inv(design.T @ design)
    covariance = gram_inv @ design.T @ torch.diag(2.0 * true_var**2 / (n - 1)) @ design @ gram_inv
    se_shot_sq, se_read_sq = covariance.diagonal().sqrt().tolist()

    assert abs(shot_sq - SHOT**2) < 5.0 * se_shot_sq
    assert abs(read_sq - READ**2) < 5.0 * se_read_sq
    # The bands are tight enough to tell the parameters apart from a model with a constant variance.
    assert 5.0 * se_shot_sq < 0.1 * SHOT**2
    assert 5.0 * se_read_sq < 0.5 * READ**2
    # Every column's mean is zero within 5 standard errors.
    assert (samples.mean(dim=1).abs() < 5.0 * (true_var / n).sqrt()).all()


def test_per_clip_parameters_with_a_batch_dimension() -> None:
    shots = (0.05, 0.2)
    signal = torch.full((2, 1, 3, 96, 96), 0.5)
    noise = heteroscedastic_noise(signal, torch.tensor(shots), READ, generator=torch.Generator().manual_seed(5))
    n = noise[0].numel()
    for clip, shot in enumerate(shots):
        expected = shot**2 * 0.5 + READ**2
        assert abs(noise[clip].var().item() - expected) < _variance_band(expected, n)


def test_per_clip_read_noise_in_the_composer() -> None:
    signal = torch.zeros(2, 2, 3, 64, 64)
    values = NoiseValues.from_values({"read": torch.tensor([[0.01], [0.05]])}, batch_shape=(2,), dtype=torch.float32)
    noise = noise_sum(signal, values, generator=torch.Generator().manual_seed(8))
    n = noise[0].numel()
    for clip, read in enumerate((0.01, 0.05)):
        assert abs(noise[clip].var().item() - read**2) < _variance_band(read**2, n)


def test_std_formula_and_black_clamp() -> None:
    signal = torch.tensor([-0.5, 0.0, 0.25, 1.0]).reshape(1, 1, 1, 4)
    std = heteroscedastic_std(signal, 0.3, 0.04)
    # Below black the variance stays at the read-noise floor, never below it.
    expected = torch.tensor([0.04, 0.04, math.sqrt(0.09 * 0.25 + 0.0016), math.sqrt(0.09 + 0.0016)])
    torch.testing.assert_close(std.flatten(), expected, rtol=1e-6, atol=0.0)


def test_zero_parameters_give_zero_noise() -> None:
    signal = torch.rand(1, 3, 16, 16, generator=torch.Generator().manual_seed(0))
    noise = heteroscedastic_noise(signal, 0.0, 0.0, generator=torch.Generator().manual_seed(0))
    assert torch.equal(noise, torch.zeros_like(signal))
