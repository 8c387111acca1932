"""The DEN's fixed noise statistics, checked on flat clips with noise of known strength from darksynth.noise."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.models.statistics import (
    LEVEL_BINS,
    LEVEL_MAX,
    STATISTICS_SIZE,
    column_noise_statistics,
    noise_statistics,
    pixel_noise_statistics,
)
from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.heteroscedastic import heteroscedastic_noise
from darksynth.noise.periodic import periodic_noise

# Layout of pixel_noise_statistics: three blocks of LEVEL_BINS.
MEAN_SQUARE, SHARE = 0, 2 * LEVEL_BINS
# Layout of column_noise_statistics.
ALL, SHARED, OWN, COSINE, SINE, SHARED_PERIODIC, FRAME_SPREAD, FLOOR, INVERSE_FRAMES = range(9)

BIN_WIDTH = LEVEL_MAX / LEVEL_BINS


def _centre(bin_index: int) -> float:
    return (bin_index + 0.5) * BIN_WIDTH


def _flat(level: float, shape: tuple[int, ...]) -> torch.Tensor:
    return torch.full(shape, level)


def _with_read_noise(signal: torch.Tensor, read: float, generator: torch.Generator) -> torch.Tensor:
    return signal + heteroscedastic_noise(signal, 0.0, read, generator=generator)


@pytest.mark.parametrize("bin_index", [1, 3, 6])
@pytest.mark.parametrize(("shot", "read"), [(0.0, 0.01), (0.0, 0.02), (0.08, 0.0), (0.05, 0.01)])
def test_pixel_statistic_is_log10_of_the_noise_variance_in_the_matching_bin(
    bin_index: int, shot: float, read: float
) -> None:
    level = _centre(bin_index)
    signal = _flat(level, (1, 4, 3, 64, 64))
    clip = signal + heteroscedastic_noise(signal, shot, read, generator=torch.Generator().manual_seed(bin_index))
    statistics = pixel_noise_statistics(clip)[0]
    # ~48k differences: the sample variance is within ~1% (0.003 in log10) of the true one.
    assert statistics[MEAN_SQUARE + bin_index].item() == pytest.approx(math.log10(shot**2 * level + read**2), abs=0.02)


def test_doubling_read_noise_raises_the_mean_square_statistic_by_log10_of_four() -> None:
    bin_index = 3
    signal = _flat(_centre(bin_index), (1, 4, 3, 64, 64))
    generator = torch.Generator().manual_seed(7)
    single = pixel_noise_statistics(_with_read_noise(signal, 0.01, generator))[0, MEAN_SQUARE + bin_index]
    double = pixel_noise_statistics(_with_read_noise(signal, 0.02, generator))[0, MEAN_SQUARE + bin_index]
    assert (double - single).item() == pytest.approx(math.log10(4.0), abs=0.02)


def test_pixels_are_binned_by_level_and_bright_ones_fall_in_the_last_bin() -> None:
    generator = torch.Generator().manual_seed(1)
    for level, expected_bin in ((_centre(2), 2), (0.8, LEVEL_BINS - 1)):
        clip = _with_read_noise(_flat(level, (1, 2, 3, 48, 48)), 0.003, generator)
        statistics = pixel_noise_statistics(clip)[0]
        shares = torch.tensor(10.0) ** statistics[SHARE : SHARE + LEVEL_BINS]
        assert shares[expected_bin].item() == pytest.approx(1.0, abs=1e-4)
        assert statistics[MEAN_SQUARE + expected_bin].item() == pytest.approx(math.log10(0.003**2), abs=0.03)


CLIP_SHAPE = (8, 6, 3, 128, 64)
SIGMA = 0.02
READ = 0.01


def _column_statistics(noise: torch.Tensor, seed: int) -> torch.Tensor:
    """Statistics of flat clips with the given column noise and weak read noise (floor ~ READ^2 / H).

    The energies of the 8 clips are averaged (then logged again) so that the bands below stay narrow: 8 clips
    of 6 frames and 3 channels are 144 independent draws of each random coefficient.
    """
    signal = _flat(0.2, CLIP_SHAPE)
    statistics = column_noise_statistics(_with_read_noise(signal + noise, READ, torch.Generator().manual_seed(seed)))
    return torch.log10((10.0**statistics).mean(0))


def test_temporal_banding_shows_as_shared_column_energy() -> None:
    noise = temporal_banding_noise(CLIP_SHAPE, SIGMA, generator=torch.Generator().manual_seed(10))
    statistics = _column_statistics(noise, seed=11)
    # The second difference of independent columns has variance 1.5 sigma^2.
    assert statistics[SHARED].item() == pytest.approx(math.log10(1.5 * SIGMA**2), abs=0.1)
    assert statistics[SHARED] - statistics[OWN] > 2.0


def test_per_frame_banding_shows_as_own_column_energy() -> None:
    noise = banding_noise(CLIP_SHAPE, SIGMA, generator=torch.Generator().manual_seed(12))
    statistics = _column_statistics(noise, seed=13)
    # The per-frame part is rescaled by T / (T - 1), so it estimates the full 1.5 sigma^2.
    assert statistics[OWN].item() == pytest.approx(math.log10(1.5 * SIGMA**2), abs=0.05)
    # The mean over T independent frames keeps only 1 / T of the energy: log10(6) ~ 0.78 below.
    assert statistics[OWN] - statistics[SHARED] > 0.5


@pytest.mark.parametrize(
    ("sigmas", "strong", "weak"), [((0.0, SIGMA, 0.0), COSINE, SINE), ((0.0, 0.0, SIGMA), SINE, COSINE)]
)
def test_period_four_wave_projects_on_its_own_phase(sigmas: tuple[float, ...], strong: int, weak: int) -> None:
    noise = periodic_noise(CLIP_SHAPE, torch.tensor(sigmas), generator=torch.Generator().manual_seed(14))
    statistics = _column_statistics(noise, seed=15)
    # Mean square amplitude sigma^2: each frame and channel draws one coefficient.
    assert statistics[strong].item() == pytest.approx(math.log10(SIGMA**2), abs=0.2)
    assert statistics[strong] - statistics[weak] > 2.0


def test_constant_periodic_term_shows_as_frame_to_frame_spread_of_channel_means() -> None:
    noise = periodic_noise(CLIP_SHAPE, torch.tensor([SIGMA, 0.0, 0.0]), generator=torch.Generator().manual_seed(16))
    statistics = _column_statistics(noise, seed=17)
    assert statistics[FRAME_SPREAD].item() == pytest.approx(math.log10(SIGMA**2), abs=0.2)
    # A column-constant offset has no column pattern: the high-passed energy stays near the pixel floor.
    assert statistics[FRAME_SPREAD] - statistics[ALL] > 2.0


def test_floor_is_the_pixel_variance_over_the_height() -> None:
    statistics = _column_statistics(torch.zeros(CLIP_SHAPE), seed=18)
    assert statistics[FLOOR].item() == pytest.approx(math.log10(READ**2 / CLIP_SHAPE[-2]), abs=0.02)
    assert statistics[INVERSE_FRAMES].item() == pytest.approx(1 / CLIP_SHAPE[1])


def test_single_frame_has_no_per_frame_part_and_no_frame_spread() -> None:
    signal = _flat(0.2, (2, 1, 3, 64, 64))
    noise = banding_noise(signal.shape, SIGMA, generator=torch.Generator().manual_seed(19))
    statistics = column_noise_statistics(signal + noise)
    torch.testing.assert_close(statistics[:, SHARED], statistics[:, ALL])
    assert (statistics[:, OWN] < -9).all()
    assert (statistics[:, FRAME_SPREAD] < -9).all()
    assert statistics[:, INVERSE_FRAMES].tolist() == [1.0, 1.0]


def test_noise_statistics_concatenates_pixel_and_column_statistics() -> None:
    clip = torch.rand(2, 3, 3, 40, 44, generator=torch.Generator().manual_seed(20))
    combined = noise_statistics(clip)
    assert combined.shape == (2, STATISTICS_SIZE)
    torch.testing.assert_close(combined, torch.cat([pixel_noise_statistics(clip), column_noise_statistics(clip)], -1))
