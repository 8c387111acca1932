"""noise/spectral.py and noise/spectral_fit.py: the measured-spectrum model, its statistics and its fit."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.estimation.spectral_fit import (
    SpectralStatistics,
    band_fields,
    fit_by_resynthesis,
    knot_binning,
    knot_variances,
    measure,
    measure_weight,
    oracle_spectral_fit,
    quantised,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import (
    LEVEL_KNOTS,
    OCTAVES,
    OPPONENT_BASIS,
    TABLE_CACHE_SIZE,
    SpectralGrid,
    level_std,
    octave_covariances,
    spectral_tables,
)
from darksynth.noise.values import NoiseValues


def _values(**spectral: object) -> NoiseValues:
    base: dict[str, object] = {"level_curve": [0.05] * 24}
    base.update(spectral)
    return NoiseValues.from_values(base, dtype=torch.float32)  # type: ignore[arg-type]


def _noise(values: NoiseValues, shape: tuple[int, ...], seed: int, level: float = 0.5) -> torch.Tensor:
    signal = torch.full(shape, level)
    return add_noise(signal, values, generator=torch.Generator().manual_seed(seed)) - signal


def test_neutral_shape_is_white_noise_with_the_curves_std_and_independent_channels() -> None:
    noise = _noise(_values(), (1, 8, 3, 256, 256), seed=0)[0]
    std = noise.std(dim=(0, 2, 3))
    assert torch.allclose(std, torch.full((3,), 0.05), rtol=0.02)
    correlation = torch.corrcoef(noise.permute(1, 0, 2, 3).reshape(3, -1))
    assert (correlation - torch.eye(3)).abs().max() < 0.02
    statistics = measure(noise, torch.full_like(noise, 0.5))
    # White noise has the power of white noise in every band, in every component, and no cross-power.
    relative = statistics.cross_power / 0.05**2
    # (The second-coarsest band of eight 256-px frames holds about 600 independent frequencies: its sampling error
    # is about 4 %; the coarsest's about 8 %.)
    diagonal = relative.diagonal(dim1=-2, dim2=-1)
    assert torch.allclose(diagonal[:5], torch.ones(5, 3, dtype=torch.float64), rtol=0.12)
    assert torch.allclose(diagonal[5], torch.ones(3, dtype=torch.float64), rtol=0.3)
    off_diagonal = (relative - torch.diag_embed(diagonal)).abs()
    assert off_diagonal[:5].max() < 0.1
    assert off_diagonal[5].max() < 0.25  # about 300 frequencies: a cross-power's sampling error is about 6 %


def test_coarse_colour_power_lands_in_the_coarse_colour_bands_and_keeps_each_channels_std() -> None:
    power = torch.ones(OCTAVES, 3)
    power[3:, 1:] = 30.0  # colour mottle at 23-90 px
    noise = _noise(_values(octave_power=power.flatten()), (1, 2, 3, 384, 384), seed=1)[0]
    assert torch.allclose(noise.std(dim=(0, 2, 3)), torch.full((3,), 0.05), rtol=0.05)
    diagonal = measure(noise, torch.full_like(noise, 0.5)).cross_power.diagonal(dim1=-2, dim2=-1)
    colour_over_brightness = diagonal[:, 1:].mean(1) / diagonal[:, 0]
    assert colour_over_brightness[4] > 15.0 and colour_over_brightness[0] < 2.0
    # Channels are less alike at coarse scales: the colour dominates there.
    assert diagonal[5, 1] > 10 * diagonal[0, 1]


def test_octave_correlation_correlates_brightness_and_colour_as_the_normalised_covariance_says() -> None:
    correlation = torch.zeros(OCTAVES, 3)
    correlation[:, 0] = 0.8
    noise = _noise(_values(octave_correlation=correlation.flatten()), (1, 2, 3, 256, 256), seed=2)[0]
    cross = measure(noise, torch.full_like(noise, 0.5)).cross_power
    measured = cross[:, 0, 1] / (cross[:, 0, 0] * cross[:, 1, 1]).sqrt()
    # The covariance is that of the spectrum before each RGB channel is scaled to unit variance; the scaling
    # (here the same at every octave) changes the correlation to what this computes.
    covariance = octave_covariances(torch.ones(OCTAVES * 3), correlation.flatten())[0]
    rgb = OPPONENT_BASIS.T @ covariance @ OPPONENT_BASIS
    scale = rgb.diagonal().rsqrt()
    opponent = OPPONENT_BASIS @ (rgb * scale[:, None] * scale[None, :]) @ OPPONENT_BASIS.T
    expected = float(opponent[0, 1] / (opponent[0, 0] * opponent[1, 1]).sqrt())
    assert expected > 0.3
    assert torch.allclose(measured[:4], torch.full((4,), expected, dtype=torch.float64), atol=0.05)


def test_level_curve_is_piecewise_linear_between_its_knots() -> None:
    curve = torch.linspace(0.01, 0.08, 24)
    knots = torch.tensor(LEVEL_KNOTS)
    midpoints = torch.cat([(knots[:-1] + knots[1:]) * 0.5, torch.ones(1)])
    image = torch.stack([knots, midpoints]).reshape(1, 2, 8).expand(3, 2, 8)
    std = level_std(image, curve)
    table = curve.reshape(3, 8)
    assert torch.allclose(std[:, 0], table)
    assert torch.allclose(std[:, 1, :7], 0.5 * (table[:, :-1] + table[:, 1:]))
    grey = level_std(image[:1], curve)
    assert torch.allclose(grey[0, 0], table[1])


def _level_std_by_search(signal: torch.Tensor, curve: torch.Tensor) -> torch.Tensor:
    """The level curve the plain way, in float64: the knot segment by a search, linear within it."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64)
    table = curve.reshape(3, 8).to(torch.float64)
    if signal.shape[-3] == 1:
        table = table[1:2]
    x = signal.to(torch.float64).clamp(0.0, 1.0)
    index = torch.bucketize(x, knots[1:-1])
    fraction = (x - knots[index]) / (knots[index + 1] - knots[index])
    rows = torch.arange(table.shape[0]).reshape(-1, 1, 1).expand_as(x)
    return table[rows, index] * (1.0 - fraction) + table[rows, index + 1] * fraction


@pytest.mark.parametrize("channels", [3, 1])
def test_level_std_by_arithmetic_equals_the_curve_found_by_search(channels: int) -> None:
    """The piece is floor(49 x) (every knot lies on the 1/49 grid): the same curve as a search of the knots, on
    continuous values, on the knots themselves, outside [0, 1] and on the 256 levels of an 8-bit image."""
    generator = torch.Generator().manual_seed(0)
    curve = 0.002 + 0.08 * torch.rand(24, generator=generator)
    continuous = torch.rand(2, channels, 64, 64, generator=generator) * 1.2 - 0.1
    knots = torch.tensor(LEVEL_KNOTS).reshape(1, 1, 1, 8).expand(1, channels, 1, 8)
    levels = (torch.arange(256) / 255.0).reshape(1, 1, 1, 256).expand(1, channels, 1, 256)
    darkened = 0.2 * levels.pow(1 / 0.7)
    for signal in (continuous, knots, levels, darkened):
        assert torch.allclose(level_std(signal, curve).double(), _level_std_by_search(signal, curve), atol=1e-7)


def test_grids_of_one_spectrum_share_their_tables_and_the_cache_stays_small() -> None:
    covariances = octave_covariances(torch.ones(OCTAVES * 3), torch.zeros(OCTAVES * 3))
    temporal = torch.zeros(OCTAVES)
    first = SpectralGrid(covariances, temporal, 3, 64, 80, device="cpu")
    second = SpectralGrid(covariances.clone(), temporal.clone(), 3, 64, 80, device="cpu")
    assert first.tables is second.tables
    # Each grid has its own work arrays and state: two clips of one spectrum draw independently.
    generator = torch.Generator().manual_seed(0)
    assert not torch.equal(first.frame(generator), second.frame(generator))
    others = [
        spectral_tables(covariances * (2.0 + k), temporal, 3, 64, 80, device="cpu") for k in range(TABLE_CACHE_SIZE)
    ]
    assert others[-1] is spectral_tables(covariances * (1.0 + TABLE_CACHE_SIZE), temporal, 3, 64, 80, device="cpu")
    assert spectral_tables(covariances, temporal, 3, 64, 80, device="cpu") is not first.tables


def test_temporal_correlation_is_the_ar1_coefficient_and_a_stream_draws_the_clips_bits() -> None:
    values = _values(temporal_correlation=[0.7] * OCTAVES)
    clip = _noise(values, (8, 3, 128, 128), seed=3)
    temporal = measure(clip, torch.full_like(clip, 0.5)).temporal
    assert temporal is not None
    assert torch.allclose(temporal[:4], torch.full((4,), 0.7, dtype=torch.float64), atol=0.05)
    # Frame by frame, holding the state, as the streaming synthesizer does: the same numbers.
    generator = torch.Generator().manual_seed(3)
    held: dict[str, object] = {}
    signal = torch.full((1, 3, 128, 128), 0.5)
    frames = [add_noise(signal, values, generator=generator, held=held)[0] - 0.5 for _ in range(8)]
    assert torch.allclose(torch.stack(frames), clip, atol=1e-6)
    # Without the held state every frame is independent.
    independent = _noise(_values(), (8, 3, 128, 128), seed=3)
    lagged = measure(independent, torch.full_like(independent, 0.5)).temporal
    assert lagged is not None and lagged[:4].abs().max() < 0.03


def test_the_unit_variance_does_not_depend_on_the_frame_size() -> None:
    power = torch.ones(OCTAVES, 3)
    power[:3] = 0.2  # most power in the coarse octaves, the hardest case for a small frame
    values = _values(octave_power=power.flatten())
    large = _noise(values, (1, 3, 512, 512), seed=4).std()
    small = torch.stack([_noise(values, (1, 3, 96, 96), seed=s).std() for s in range(8)]).pow(2).mean().sqrt()
    # The small frame misses the part of the coarsest octave that does not fit in it, nothing else.
    assert 0.85 < float(small / large) <= 1.02


def test_inconsistent_correlations_are_repaired_to_a_valid_covariance() -> None:
    correlation = torch.tensor([0.99, 0.99, -0.99] * OCTAVES)
    covariances = octave_covariances(torch.ones(OCTAVES * 3), correlation)
    assert bool((torch.linalg.eigvalsh(covariances) > -1e-9).all())
    assert torch.allclose(covariances.diagonal(dim1=-2, dim2=-1), torch.ones(OCTAVES, 3, dtype=torch.float64))


@pytest.mark.parametrize("seed", [0, 1])
def test_round_trip_of_a_random_spectrum_through_the_clean_aided_fit(seed: int) -> None:
    generator = torch.Generator().manual_seed(100 + seed)
    truth = {
        "level_curve": (0.01 + 0.04 * torch.rand(24, generator=generator)).tolist(),
        "octave_power": (torch.rand(OCTAVES * 3, generator=generator) * 4 - 1.5).exp().tolist(),
        "octave_correlation": (torch.rand(OCTAVES * 3, generator=generator) * 0.8 - 0.4).tolist(),
    }
    clean = (torch.rand(1, 3, 1, 1, generator=generator) * 0.4 + 0.1).expand(1, 3, 256, 256)
    gradient = torch.linspace(0.0, 0.5, 256).reshape(1, 1, 1, 256)
    clean = quantised(clean + gradient)
    truth_values = NoiseValues.from_values(truth, dtype=torch.float32)  # type: ignore[arg-type]
    noisy = quantised(add_noise(clean[None], truth_values, generator=torch.Generator().manual_seed(7))[0])
    fitted = NoiseValues.from_values(oracle_spectral_fit(noisy[0], clean[0], compressions=(0.0,)))
    check = quantised(
        add_noise(clean[None], fitted.to(dtype=torch.float32), generator=torch.Generator().manual_seed(99))[0]
    )
    real, synthetic = measure(noisy - clean, clean), measure(check - clean, clean)
    ratio = synthetic.cross_power.diagonal(dim1=-2, dim2=-1) / real.cross_power.diagonal(dim1=-2, dim2=-1)
    # Every octave's power of every component within 10 % in the median, within 35 % at worst, from another draw
    # (the coarse bands of a 256-px image hold a few hundred frequencies: their own sampling error is ~10 %).
    assert float(ratio[:5].log().abs().median()) < math.log(1.1)
    assert float(ratio[:5].log().abs().max()) < math.log(1.35)


def test_the_fit_converges_on_its_own_simulator() -> None:
    """fit_by_resynthesis moves a wrong start onto the target when the simulator is exact (common draws)."""
    target_parameters = torch.diag_embed(torch.tensor([[2.0, 0.5, 0.5]] * OCTAVES, dtype=torch.float64))

    def simulate(parameters: object, draw: int) -> SpectralStatistics:
        covariances = parameters.covariances  # type: ignore[attr-defined]
        curve = parameters.curve  # type: ignore[attr-defined]
        return SpectralStatistics(covariances * 1.3, curve.square() * 0.8, None)

    target = SpectralStatistics(target_parameters * 1.3, torch.full((3, 8), 0.01 * 0.8, dtype=torch.float64), None)
    fitted, left = fit_by_resynthesis(target, simulate, iterations=3, draws=1)
    assert torch.allclose(fitted.covariances, target_parameters, rtol=1e-6)
    assert torch.allclose(fitted.curve, torch.full((3, 8), 0.1, dtype=torch.float64), rtol=1e-6)
    assert left >= 0.0


def _knot_variances_by_hats(noise: torch.Tensor, intensity: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """The definition: each knot's hat weight (1 at the knot, falling linearly to 0 at its neighbours) per pixel."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64)
    x = intensity.to(torch.float64).clamp(0.0, 1.0)[..., None]
    left = torch.cat([knots[:1] - 1.0, knots[:-1]])
    right = torch.cat([knots[1:], knots[-1:] + 1.0])
    hats = torch.minimum((x - left) / (knots - left), (right - x) / (right - knots)).clamp(0.0, 1.0)
    hats = hats * weight[:, None, ..., None]
    centred = noise.double() - noise.double().mean(dim=(0, 2, 3), keepdim=True)
    mass = hats.sum(dim=(0, 2, 3))
    return torch.einsum("tchw,tchwk->ck", centred.square(), hats) / mass


def test_knot_variances_and_band_products_equal_their_definitions() -> None:
    generator = torch.Generator().manual_seed(12)
    noise = torch.randn(2, 3, 48, 40, generator=generator) * 0.02
    # Every knot reached, the knots themselves and the ends included.
    intensity = torch.rand(2, 3, 48, 40, generator=generator).square()
    intensity[0, :, 0, : len(LEVEL_KNOTS)] = torch.tensor(LEVEL_KNOTS)
    intensity[1, 0, 0, :2] = torch.tensor([0.0, 1.0])
    weight = (torch.rand(2, 48, 40, generator=generator) > 0.3).double()
    expected = _knot_variances_by_hats(noise, intensity, weight)
    found = knot_variances(noise, intensity, weight)
    # The top knot holds too little weight here to be read (nan, as the estimators expect); every other is read.
    assert bool(torch.isnan(found[:, -1]).all()) and not bool(torch.isnan(found[:, :-1]).any())
    assert torch.allclose(found[:, :-1], expected[:, :-1], rtol=1e-10)
    fields, share = band_fields(noise)
    products = torch.einsum("tbihw,tbjhw,thw->bij", fields, fields, weight) / weight.sum()
    statistics = measure(noise, intensity, weight)
    assert torch.allclose(statistics.cross_power, products / share.clamp_min(1e-12)[:, None, None], rtol=1e-10)
    # The knots found once for many measurements give the same variances.
    binning = knot_binning(intensity, measure_weight(2, 48, 40, weight, noise.device))
    again = measure(noise, intensity, weight, binning=binning).knot_variance
    assert torch.equal(torch.isnan(again), torch.isnan(statistics.knot_variance))
    assert torch.allclose(again.nan_to_num(), statistics.knot_variance.nan_to_num(), rtol=1e-12)


def test_unmeasured_octaves_continue_the_colour_roll_off_of_a_gaussian_low_pass() -> None:
    from darksynth.estimation.spectral_fit import SpectralParameters, continue_octaves
    from darksynth.noise.spectral import OCTAVE_FREQUENCIES

    # Octaves 0-2 measured: white noise through a Gaussian low-pass of f0 = 0.1 cycles/px in colour 1, a falling
    # colour 2, a rising brightness; octaves 3-5 unmeasured (garbage that must be replaced).
    frequency = torch.tensor(OCTAVE_FREQUENCIES, dtype=torch.float64)
    low_pass = 5.0 * torch.exp(-((frequency / 0.1) ** 2))
    power = torch.stack([torch.linspace(1.0, 3.0, OCTAVES), low_pass, torch.linspace(4.0, 1.0, OCTAVES)], dim=-1)
    correlation = torch.tensor([[1.0, 0.3, -0.2], [0.3, 1.0, 0.1], [-0.2, 0.1, 1.0]], dtype=torch.float64)
    covariances = correlation * power.sqrt()[:, :, None] * power.sqrt()[:, None, :]
    covariances[3:] = 77.0 * torch.eye(3, dtype=torch.float64)
    temporal = torch.tensor([0.1, 0.2, 0.3, 0.9, 0.9, 0.9], dtype=torch.float64)
    parameters = SpectralParameters(covariances, torch.ones(3, 8, dtype=torch.float64), temporal)
    continued = continue_octaves(parameters, 3)
    diagonal = continued.covariances.diagonal(dim1=-2, dim2=-1)
    # The low-pass is recovered exactly from its two last measured octaves; its coarse limit is 5.
    assert torch.allclose(diagonal[3:, 1], low_pass[3:], rtol=1e-9)
    assert bool((diagonal[3:, 1] < 5.0).all()) and bool((diagonal[3:, 1] > power[2, 1]).all())
    # Brightness and a colour falling toward coarse scales are held at the last measured octave.
    assert torch.allclose(diagonal[3:, 0], power[2, 0].expand(3))
    assert torch.allclose(diagonal[3:, 2], power[2, 2].expand(3))
    std = diagonal.sqrt()
    assert torch.allclose(continued.covariances[4] / (std[4][:, None] * std[4][None, :]), correlation)
    assert torch.allclose(continued.temporal[3:], torch.full((3,), 0.3, dtype=torch.float64))
    assert torch.equal(continued.covariances[:3], covariances[:3])


def test_unmeasured_knots_follow_the_prior_curve_through_the_measured_ones() -> None:
    from darksynth.estimation.spectral_fit import fill_knots_along

    prior = torch.linspace(1.0, 8.0, 8, dtype=torch.float64).expand(3, 8).clone()
    curve = 2.0 * prior
    measured = torch.zeros(3, 8, dtype=torch.bool)
    measured[:, 3:6] = True
    curve[:, :3] = 0.01  # what a clipped knot would have read: it must not be kept, nor continued flat
    filled = fill_knots_along(curve, measured, prior)
    assert torch.allclose(filled, 2.0 * prior)
    # Between measured knots the log ratio is interpolated: ratios 2 and 8 give 4 half-way.
    curve = prior.clone()
    curve[:, 2], curve[:, 6] = 2.0 * prior[:, 2], 8.0 * prior[:, 6]
    between = torch.zeros(3, 8, dtype=torch.bool)
    between[:, [2, 6]] = True
    assert torch.allclose(fill_knots_along(curve, between, prior)[:, 4], 4.0 * prior[:, 4])
    # A channel with no measured knot takes the others' median ratio.
    only = measured.clone()
    only[2] = False
    assert torch.allclose(fill_knots_along(2.0 * prior, only, prior)[2], 2.0 * prior[2])


@pytest.mark.parametrize("signal", [-0.05, -0.01, 0.0, 0.02, 0.1, 0.97, 1.01])
def test_the_uncensored_signal_is_the_mean_before_the_clip(signal: float) -> None:
    from darksynth.estimation.spectral_fit import uncensored_signal

    std = 0.03
    clipped = (signal + std * torch.randn(400_000, generator=torch.Generator().manual_seed(1))).clamp(0.0, 1.0)
    found = uncensored_signal(clipped.mean()[None], torch.tensor([std]))
    assert abs(float(found[0]) - signal) < 0.002


def test_uncensored_signal_searches_only_where_the_cut_reaches() -> None:
    """The signal under a clipped mean: far from 0 it is the mean itself, near 0 the table's inversion, as a full
    search of every pixel gives."""
    from darksynth.estimation.spectral_fit import _CENSORED_MEAN, _CENSORED_T, uncensored_signal

    generator = torch.Generator().manual_seed(0)
    observed = torch.rand(3, 40, 40, generator=generator) ** 3
    observed[0, :4] = 0.0
    observed[1, :2] = 1.0
    std = 0.002 + 0.05 * torch.rand(3, 40, 40, generator=generator)

    def searched(mean: torch.Tensor) -> torch.Tensor:
        ratio = (mean / std.clamp_min(1e-6)).to(torch.float64)
        index = torch.searchsorted(_CENSORED_MEAN, ratio.clamp(float(_CENSORED_MEAN[0]), float(_CENSORED_MEAN[-1])))
        index = index.clamp(1, len(_CENSORED_T) - 1)
        low, high = _CENSORED_MEAN[index - 1], _CENSORED_MEAN[index]
        t = _CENSORED_T[index - 1] + ((ratio - low) / (high - low)).clamp(0.0, 1.0) * (
            _CENSORED_T[index] - _CENSORED_T[index - 1]
        )
        t = torch.where(ratio >= float(_CENSORED_MEAN[-1]), ratio, t)
        return (t * std.to(torch.float64)).to(mean.dtype)

    assert torch.equal(uncensored_signal(observed, std), 1.0 - searched(1.0 - searched(observed)))
