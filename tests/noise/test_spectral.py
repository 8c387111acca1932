"""noise/spectral.py: the measured-spectrum model, its draws measured through the spectral fit's statistics."""

from __future__ import annotations

import pytest
import torch

from darksynth.estimation.noise.spectral_statistics import measure
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
    first = SpectralGrid(spectral_tables(covariances, temporal, 3, 64, 80, device="cpu"), 3, 64, 80)
    second = SpectralGrid(spectral_tables(covariances.clone(), temporal.clone(), 3, 64, 80, device="cpu"), 3, 64, 80)
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
