"""Noise-distribution metrics: histogram KL divergences, AKLD, channel statistics, FID, KID and the t interval."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from darksynth.evaluation.measures.metrics import (
    AKLD_WINDOW_SIGMA,
    NAFLOW_EPS,
    _trace_sqrt_product_factors,
    _trace_sqrt_product_sqrtm,
    average_kl_divergence,
    channel_correlations,
    channel_moments,
    frechet_distance,
    kernel_inception_distance,
    kl_divergence_naflow,
    kl_divergence_noise_flow,
    kl_divergence_srgb,
    local_noise_variance,
    mean_and_interval,
    naflow_histogram,
    noise_flow_histogram,
    pooled_std,
    srgb_histogram,
)

BIN = 0.2 / 64


def _centre(index: int) -> float:
    """Centre of the Noise Flow interior bin ``index`` (0..63), far from any edge."""
    return -0.1 + (index + 0.5) * BIN


def _gaussian_kl(sigma_p: float, sigma_q: float) -> float:
    return math.log(sigma_q / sigma_p) + sigma_p**2 / (2.0 * sigma_q**2) - 0.5


# --- Noise Flow KL ---------------------------------------------------------------------------------------------


def test_noise_flow_kl_of_identical_samples_is_zero_and_of_independent_same_distribution_near_zero() -> None:
    rng = np.random.default_rng(0)
    real = rng.normal(0.0, 0.03, size=(200, 300, 3))
    assert kl_divergence_noise_flow(real, real.copy()) == 0.0
    other = rng.normal(0.0, 0.03, size=(200, 300, 3))
    # 66 bins, 180,000 values each: the plug-in estimate's bias is about 65 / (2 * 180,000) = 2e-4.
    assert abs(kl_divergence_noise_flow(real, other)) < 1e-3


def test_noise_flow_kl_grows_with_std_mismatch_and_approaches_the_gaussian_kl() -> None:
    rng = np.random.default_rng(1)
    real = rng.normal(0.0, 0.02, size=10**6)
    values = [kl_divergence_noise_flow(real, rng.normal(0.0, sigma, size=10**6)) for sigma in (0.022, 0.03, 0.04)]
    assert values[0] < values[1] < values[2]
    # Bins of width 0.003 against a std of 0.02 barely smooth the densities: the histogram KL is within 5% of
    # the closed-form KL between the Gaussians (the overflow bins hold < 0.5% of the N(0, 0.04) mass).
    assert values[1] == pytest.approx(_gaussian_kl(0.02, 0.03), rel=0.05)
    assert values[2] == pytest.approx(_gaussian_kl(0.02, 0.04), rel=0.05)


def test_noise_flow_kl_matches_a_hand_computed_value() -> None:
    a, b = _centre(32), _centre(48)
    real = np.array([a, a, b, 0.2])  # p: a 1/2, b 1/4, overflow-high 1/4
    synthetic = np.array([a, b, b, -0.3])  # q: a 1/4, b 1/2, overflow-low 1/4
    # Only bins a and b are non-zero in both: 1/2 ln 2 + 1/4 ln(1/2) = ln(2) / 4.
    assert kl_divergence_noise_flow(real, synthetic) == pytest.approx(math.log(2.0) / 4.0, abs=1e-12)
    # Torch tensors give the same value.
    assert kl_divergence_noise_flow(torch.tensor(real), torch.tensor(synthetic)) == pytest.approx(math.log(2.0) / 4.0)


def test_noise_flow_overflow_bins_catch_values_beyond_a_tenth() -> None:
    c = _centre(10)
    real = np.array([c, 0.15, 0.15, -0.5])  # p: c 1/4, high 1/2, low 1/4
    synthetic = np.array([c, 7.0, -0.2, -np.inf])  # q: c 1/4, high 1/4, low 1/2
    # Were the out-of-range values dropped, both histograms would be all in bin c and the KL would be 0.
    expected = 0.5 * math.log(2.0) + 0.25 * math.log(0.5)
    assert kl_divergence_noise_flow(real, synthetic) == pytest.approx(expected, abs=1e-12)

    histogram = noise_flow_histogram(np.array([-0.1000001, -0.1, 0.1, 0.1000001]))
    assert histogram.shape == (66,)
    # -0.1 and 0.1 themselves are inside (first and last interior bins); just beyond them is overflow.
    np.testing.assert_allclose(histogram[[0, 1, 64, 65]], [0.25, 0.25, 0.25, 0.25])


def test_noise_flow_kl_refuses_nan() -> None:
    with pytest.raises(ValueError, match="NaN"):
        kl_divergence_noise_flow(np.array([0.0, np.nan]), np.zeros(2))


# --- sRGB KL ---------------------------------------------------------------------------------------------------


def test_srgb_kl_matches_a_hand_computed_value_with_add_one_smoothing() -> None:
    real = np.array([2.0, 2.0]) / 255.0  # 8-bit value 2: bin [0, 4)
    synthetic = np.array([-10.0, -10.0]) / 255.0  # bin [-12, -8)
    # 130 bins; p has 3 in its bin and 1 elsewhere (total 132), q likewise in another bin.
    # KL = 3/132 ln 3 + 1/132 ln(1/3) + 128 terms of 1/132 ln 1 = (2/132) ln 3.
    assert kl_divergence_srgb(real, synthetic) == pytest.approx(2.0 / 132.0 * math.log(3.0), abs=1e-12)
    histogram = srgb_histogram(real)
    assert histogram.shape == (130,)
    assert histogram[65] == pytest.approx(3.0 / 132.0)


def test_srgb_kl_is_finite_when_the_synthetic_sample_leaves_bins_empty() -> None:
    rng = np.random.default_rng(2)
    real = rng.normal(0.0, 0.05, size=50_000)
    synthetic = np.zeros(50_000)  # one bin filled, 129 empty
    value = kl_divergence_srgb(real, synthetic)
    assert math.isfinite(value)
    assert value > 1.0
    # Without smoothing (the Noise Flow recipe) only the common bin would count; the sRGB recipe is much larger.
    assert value > kl_divergence_noise_flow(real, synthetic) + 1.0


def test_srgb_kl_is_near_zero_for_one_distribution_and_grows_with_std_mismatch() -> None:
    rng = np.random.default_rng(3)
    real = rng.normal(0.0, 0.05, size=10**6)
    same = kl_divergence_srgb(real, rng.normal(0.0, 0.05, size=10**6))
    wider = kl_divergence_srgb(real, rng.normal(0.0, 0.07, size=10**6))
    widest = kl_divergence_srgb(real, rng.normal(0.0, 0.1, size=10**6))
    assert abs(same) < 1e-3
    assert same < wider < widest
    # Bins of 4/255 against a std of 0.05 (12.75 levels): close to the Gaussian KL.
    assert wider == pytest.approx(_gaussian_kl(0.05, 0.07), rel=0.1)


# --- confidence interval ---------------------------------------------------------------------------------------


def test_mean_and_interval_matches_a_known_t_interval() -> None:
    mean, low, high = mean_and_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    # s = sqrt(2.5), sem = sqrt(0.5), t(0.975, 4) = 2.7764451 (tables: 2.776).
    half = 2.7764451051977987 * math.sqrt(0.5)
    assert mean == pytest.approx(3.0)
    assert low == pytest.approx(3.0 - half, rel=1e-9)
    assert high == pytest.approx(3.0 + half, rel=1e-9)
    assert all(type(value) is float for value in (mean, low, high))
    # 99%: t(0.995, 4) = 4.604095.
    _, low99, _ = mean_and_interval(np.array([1.0, 2.0, 3.0, 4.0, 5.0]), confidence=0.99)
    assert low99 == pytest.approx(3.0 - 4.604095 * math.sqrt(0.5), abs=1e-6)


def test_mean_and_interval_of_one_value_or_equal_values_is_a_point() -> None:
    assert mean_and_interval([0.25]) == (0.25, 0.25, 0.25)
    assert mean_and_interval(torch.tensor([2.0, 2.0, 2.0])) == (2.0, 2.0, 2.0)
    with pytest.raises(ValueError):
        mean_and_interval([])


# --- FID -------------------------------------------------------------------------------------------------------


def test_fid_of_one_gaussian_is_small_and_of_a_shifted_gaussian_is_the_squared_shift() -> None:
    rng = np.random.default_rng(4)
    dim = 8
    mixing = rng.normal(size=(dim, dim))  # a non-diagonal covariance
    a = rng.normal(size=(20_000, dim)) @ mixing
    b = rng.normal(size=(20_000, dim)) @ mixing
    same = frechet_distance(a, b)
    assert 0.0 <= same < 0.05
    shift = np.array([1.0, -1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0])  # ||shift||² = 2.25
    shifted = frechet_distance(a, b + shift)
    # Equal covariances: the trace terms cancel and FID = ||mu_a - mu_b||².
    assert shifted == pytest.approx(2.25 + same, abs=0.1)
    assert shifted == pytest.approx(2.25, rel=0.05)


def test_fid_of_isotropic_gaussians_with_different_scales_is_the_closed_form() -> None:
    rng = np.random.default_rng(5)
    dim = 6
    a = rng.normal(scale=1.0, size=(30_000, dim))
    b = rng.normal(scale=2.0, size=(30_000, dim))
    # tr(S_a + S_b - 2 sqrt(S_a S_b)) = D (1 + 4 - 2 * 2) = D.
    assert frechet_distance(torch.tensor(a), torch.tensor(b)) == pytest.approx(dim, rel=0.03)


def test_fid_trace_from_factors_equals_sqrtm_and_handles_fewer_vectors_than_dimensions() -> None:
    rng = np.random.default_rng(6)
    dim = 32
    a = np.abs(rng.normal(size=(40, dim)))
    b = np.abs(rng.normal(size=(50, dim))) * 1.3 + 0.1
    sigma_a, sigma_b = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    assert _trace_sqrt_product_factors(a, b) == pytest.approx(_trace_sqrt_product_sqrtm(sigma_a, sigma_b), rel=1e-6)

    few_a, few_b = a[:10], b[:12]  # rank-deficient covariances: the product is singular
    fid_few = frechet_distance(few_a, few_b)
    by_sqrtm = _trace_sqrt_product_sqrtm(np.cov(few_a, rowvar=False), np.cov(few_b, rowvar=False))
    by_factors = _trace_sqrt_product_factors(few_a, few_b)
    assert by_factors == pytest.approx(by_sqrtm, rel=1e-4)
    assert math.isfinite(fid_few) and fid_few > 0.0
    assert frechet_distance(few_a, few_a) == pytest.approx(0.0, abs=1e-9)


def test_fid_refuses_mismatched_or_degenerate_inputs() -> None:
    with pytest.raises(ValueError, match="dimensions"):
        frechet_distance(np.zeros((5, 3)), np.zeros((5, 4)))
    with pytest.raises(ValueError, match="at least 2"):
        frechet_distance(np.zeros((1, 3)), np.zeros((5, 3)))


# --- KID -------------------------------------------------------------------------------------------------------


def _unbiased_mmd2_by_loops(x: np.ndarray, y: np.ndarray) -> float:
    m, dim = x.shape

    def k(u: np.ndarray, v: np.ndarray) -> float:
        return float((u @ v / dim + 1.0) ** 3)

    xx = sum(k(x[i], x[j]) for i in range(m) for j in range(m) if i != j) / (m * (m - 1))
    yy = sum(k(y[i], y[j]) for i in range(m) for j in range(m) if i != j) / (m * (m - 1))
    xy = sum(k(x[i], y[j]) for i in range(m) for j in range(m)) / (m * m)
    return float(xx + yy - 2.0 * xy)


def test_kid_with_full_subsets_equals_the_unbiased_mmd_written_out() -> None:
    rng = np.random.default_rng(7)
    x = rng.normal(size=(7, 3))
    y = rng.normal(loc=0.5, size=(7, 3))
    mean, std = kernel_inception_distance(x, y, subsets=3)  # subset_size = 7: every subset is the full set
    assert mean == pytest.approx(_unbiased_mmd2_by_loops(x, y), rel=1e-10)
    assert std == pytest.approx(0.0, abs=1e-10)


def test_kid_is_near_zero_for_one_distribution_and_positive_for_a_shifted_one() -> None:
    rng = np.random.default_rng(8)
    dim = 16
    a = np.abs(rng.normal(size=(800, dim)))
    b = np.abs(rng.normal(size=(800, dim)))
    same_mean, same_std = kernel_inception_distance(a, b, subsets=20, subset_size=200, seed=1)
    shifted_mean, shifted_std = kernel_inception_distance(a, b + 0.3, subsets=20, subset_size=200, seed=1)
    assert abs(same_mean) < 0.02
    assert shifted_mean > 1.0
    assert shifted_mean > 50 * abs(same_mean)
    assert same_std > 0.0 and shifted_std > 0.0
    # The seed fixes the subsets.
    assert kernel_inception_distance(a, b, subsets=20, subset_size=200, seed=1) == (same_mean, same_std)
    assert kernel_inception_distance(a, b, subsets=20, subset_size=200, seed=2) != (same_mean, same_std)


def test_kid_default_subset_size_is_bounded_by_the_smaller_set() -> None:
    rng = np.random.default_rng(9)
    a = torch.tensor(rng.normal(size=(30, 4)))
    b = torch.tensor(rng.normal(size=(12, 4)))
    mean, _ = kernel_inception_distance(a, b, subsets=5)
    assert math.isfinite(mean)
    with pytest.raises(ValueError, match="subset_size"):
        kernel_inception_distance(a, b, subset_size=13)


# --- NAFlow-recipe KL ------------------------------------------------------------------------------------------

NAFLOW_BIN = 2.0 / 256


def _naflow_centre(index: int) -> float:
    """Centre of the NAFlow bin ``index`` (0..255)."""
    return -1.0 + (index + 0.5) * NAFLOW_BIN


def test_naflow_kl_of_identical_samples_is_zero_and_of_independent_same_distribution_near_zero() -> None:
    rng = np.random.default_rng(0)
    real = rng.normal(0.0, 0.03, size=(200, 300, 3))
    assert kl_divergence_naflow(real, real) == 0.0
    assert kl_divergence_naflow(real, rng.normal(0.0, 0.03, size=(200, 300, 3))) < 1e-3
    assert kl_divergence_naflow(real, rng.normal(0.0, 0.045, size=(200, 300, 3))) > 0.05


def test_naflow_kl_matches_a_hand_computed_value() -> None:
    # p = (1/2, 1/2) and q = (1/4, 3/4) on two neighbouring bins; the epsilon shifts the value by ~1e-9 only.
    real = np.array([_naflow_centre(130)] * 2 + [_naflow_centre(131)] * 2)
    synthetic = np.array([_naflow_centre(130)] + [_naflow_centre(131)] * 3)
    expected = 0.5 * math.log(0.5 / 0.25) + 0.5 * math.log(0.5 / 0.75)
    assert kl_divergence_naflow(real, synthetic) == pytest.approx(expected, rel=1e-6)
    histogram = naflow_histogram(synthetic)
    assert histogram.shape == (256,) and histogram.sum() == pytest.approx(1.0)
    assert histogram[131] == pytest.approx(0.75, rel=1e-6) and histogram[0] == pytest.approx(NAFLOW_EPS, rel=1e-6)


def test_naflow_kl_counts_mass_the_synthetic_sample_leaves_out_where_noise_flow_ignores_it() -> None:
    # Half the real mass sits in a bin the synthetic sample never fills: Noise Flow drops that bin, NAFlow's
    # epsilon makes it cost 1/2 log(1/2 / eps).
    real = np.array([_naflow_centre(128), _naflow_centre(140)])
    synthetic = np.array([_naflow_centre(128)] * 2)
    value = kl_divergence_naflow(real, synthetic)
    assert math.isfinite(value)
    assert value == pytest.approx(0.5 * math.log(0.5) + 0.5 * math.log(0.5 / NAFLOW_EPS), rel=1e-6)
    assert kl_divergence_noise_flow(real, synthetic) < 0.0  # only the shared bin: 1/2 log(1/2 / 1)


def test_naflow_histogram_covers_the_whole_range_of_unit_scale_noise() -> None:
    histogram = naflow_histogram(np.array([-1.0, 1.0, 0.999, -0.5]))
    assert histogram[0] == pytest.approx(0.25, rel=1e-6) and histogram[-1] == pytest.approx(0.5, rel=1e-6)
    assert histogram[64] == pytest.approx(0.25, rel=1e-6)


# --- AKLD -------------------------------------------------------------------------------------------------------


def test_local_variance_window_is_normalised_and_has_danets_width() -> None:
    assert abs(AKLD_WINDOW_SIGMA - 1.4) < 1e-12
    constant = torch.full((3, 20, 24), 0.05)
    assert torch.allclose(local_noise_variance(constant), torch.full((3, 20, 24), 0.0025, dtype=torch.float64))
    impulse = torch.zeros(1, 15, 15)
    impulse[0, 7, 7] = 1.0
    spread = local_noise_variance(impulse)[0]
    # The centre weight of a normalised 7-tap Gaussian of sigma 1.4, squared (separable window).
    taps = np.exp(-(np.arange(-3, 4) ** 2) / (2 * 1.4**2))
    assert float(spread[7, 7]) == pytest.approx((taps[3] / taps.sum()) ** 2, rel=1e-9)
    assert float(spread.sum()) == pytest.approx(1.0, rel=1e-7)  # plus the variance floor on every pixel


def test_akld_of_identical_noise_is_zero() -> None:
    noise = torch.randn(3, 64, 64, generator=torch.Generator().manual_seed(0)) * 0.03
    assert average_kl_divergence(noise, noise) == 0.0


def test_akld_of_constant_sigma_fields_matches_the_gaussian_closed_form() -> None:
    generator = torch.Generator().manual_seed(0)
    real = torch.randn(3, 256, 256, generator=generator) * 0.02
    synthetic = torch.randn(3, 256, 256, generator=generator) * 0.04
    # Local variances from a 7x7 window (about 25 effective samples) scatter; E[1/var] then exceeds 1/sigma^2
    # by about 8%, so the estimate sits ~0.01 above the closed form log 2 + 1/8 - 1/2 = 0.318.
    assert average_kl_divergence(real, synthetic) == pytest.approx(_gaussian_kl(0.02, 0.04), abs=0.02)
    # The direction is KL(real || synthetic): the other one is log(1/2) + 2 - 1/2 = 0.81 and more.
    assert average_kl_divergence(synthetic, real) > 0.75


def test_akld_refuses_maps_of_different_shapes() -> None:
    with pytest.raises(ValueError, match="differ in shape"):
        average_kl_divergence(torch.zeros(3, 16, 16), torch.zeros(3, 16, 17))
    with pytest.raises(ValueError, match=r"\(C, H, W\)"):
        average_kl_divergence(torch.zeros(16, 16), torch.zeros(16, 16))


# --- Channel statistics -----------------------------------------------------------------------------------------


def test_pooled_std_of_moments_summed_over_maps_is_the_std_of_all_values() -> None:
    rng = np.random.default_rng(0)
    first, second = rng.normal(0.01, 0.02, (3, 30, 40)), rng.normal(-0.01, 0.05, (3, 20, 10))
    pooled = pooled_std(channel_moments(first) + channel_moments(second))
    every = np.concatenate([first.reshape(3, -1), second.reshape(3, -1)], axis=1)
    np.testing.assert_allclose(pooled, every.std(axis=1), rtol=1e-10)


def test_channel_correlations_are_near_zero_for_independent_channels_and_one_for_shared_noise() -> None:
    generator = torch.Generator().manual_seed(0)
    independent = channel_correlations(torch.randn(3, 128, 128, generator=generator))
    assert list(independent) == ["rg", "gb", "rb"]
    assert all(abs(value) < 0.03 for value in independent.values())
    shared = torch.randn(1, 128, 128, generator=generator)
    mixed = torch.cat([shared, 0.5 * shared, -shared])
    assert channel_correlations(mixed) == pytest.approx({"rg": 1.0, "gb": -1.0, "rb": -1.0})
    flat = channel_correlations(torch.cat([shared, torch.zeros(1, 128, 128), shared]))
    assert math.isnan(flat["rg"]) and flat["rb"] == pytest.approx(1.0)
