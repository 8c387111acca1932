"""darksynth.evaluation.measures.structure: band powers of known noise, their ratios and summary, and the temporal lag
correlation of clips with a known persistence."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from darksynth.evaluation.measures.structure import (
    BAND_LABELS,
    BANDS,
    band_powers,
    band_ratios,
    band_summary,
    gaussian_blur,
    prior_band_shares,
    prior_bands,
    relative_to_white,
    temporal_lag_correlation,
)

SIGMA = 0.02


def white(shape: tuple[int, ...], seed: int) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, SIGMA, shape)


def test_bands_run_fine_to_coarse_and_cover_every_frequency_from_1_64() -> None:
    assert len(BANDS) == len(BAND_LABELS) == 5
    assert BANDS[0] == (1 / 4, 0.71) and BANDS[-1] == (1 / 64, 1 / 32)
    assert all(fine[0] == coarse[1] for fine, coarse in itertools.pairwise(BANDS))
    assert math.hypot(0.5, 0.5) < BANDS[0][1]


@pytest.mark.parametrize("seed", [0, 1])
def test_white_noise_has_its_variance_in_every_band(seed: int) -> None:
    powers = band_powers(white((1024, 1024, 3), seed))
    for component in ("brightness", "colour"):
        assert powers[component] == pytest.approx([SIGMA**2] * 5, rel=0.05)
        assert powers[f"{component}_variance"] == pytest.approx(SIGMA**2, rel=0.01)
        assert relative_to_white(powers)[component] == pytest.approx([1.0] * 5, rel=0.05)


def test_blurred_noise_has_more_coarse_and_less_fine_power() -> None:
    noise = gaussian_blur(white((512, 512, 3), 2), sigma=1.5, axes=(0, 1))
    relative = relative_to_white(band_powers(noise))
    for component in ("brightness", "colour"):
        bands = relative[component]
        assert np.all(np.diff(bands) > 0), f"{component} should rise from fine to coarse: {bands}"
        assert bands[0] < 0.1 and bands[-1] > 5.0


def test_colour_only_coarse_noise_shows_only_in_the_colour_bands() -> None:
    base = white((512, 512, 3), 3)
    # Opposite in R and B, absent in G: no brightness at all, only the (R-B) colour component.
    chroma = gaussian_blur(white((512, 512), 4), sigma=8.0, axes=(0, 1)) * 20.0
    synthetic = base + np.stack([chroma, np.zeros_like(chroma), -chroma], axis=-1)
    ratios = band_ratios(band_powers(synthetic), band_powers(base))
    assert ratios["brightness"] == pytest.approx([1.0] * 5, rel=1e-9)
    assert ratios["colour"][0] == pytest.approx(1.0, abs=0.01)
    assert ratios["colour"][-1] > 3.0 and ratios["colour"][-2] > 1.5


def test_identical_noise_has_ratio_one_and_no_error() -> None:
    powers = band_powers(white((128, 160, 3), 5))
    ratios = band_ratios(powers, powers)
    assert ratios["brightness"].tolist() == [1.0] * 5 and ratios["colour"].tolist() == [1.0] * 5
    summary = band_summary([ratios, ratios])
    assert summary == {"band_ratio": {"brightness": [1.0] * 5, "colour": [1.0] * 5}, "band_rms_log_error": 0.0}


def test_summary_takes_the_median_over_pairs_then_the_rms_of_the_logs() -> None:
    rows = [
        {"brightness": np.full(5, 2.0), "colour": np.full(5, 0.5)},
        {"brightness": np.full(5, 4.0), "colour": np.full(5, 0.5)},
        {"brightness": np.full(5, 100.0), "colour": np.array([0.5, 0.5, 0.5, 0.5, np.nan])},
    ]
    summary = band_summary(rows)
    assert summary["band_ratio"] == {"brightness": [4.0] * 5, "colour": [0.5] * 5}
    assert summary["band_rms_log_error"] == pytest.approx(math.sqrt((5 * math.log(4) ** 2 + 5 * math.log(2) ** 2) / 10))
    assert band_summary([]) == {}


def test_an_image_too_small_for_the_coarsest_band_gives_nan_there() -> None:
    powers = band_powers(white((24, 24, 3), 6))  # the filterwarnings=error setting would catch a mean of nothing
    assert np.isnan(powers["brightness"][-1]) and np.all(np.isfinite(powers["brightness"][:-1]))
    ratios = band_ratios(powers, powers)
    assert band_summary([ratios])["band_ratio"]["colour"][-1] is None


def test_band_powers_refuse_a_map_that_is_not_rgb() -> None:
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        band_powers(np.zeros((16, 16)))


# ----------------------------------------------------------------------------------------------------------------
# Temporal lag correlation


def ar1_noise(rho: float, frames: int, shape: tuple[int, int], seed: int) -> np.ndarray:
    """n_t = rho n_(t-1) + sqrt(1 - rho^2) e_t: every frame has std SIGMA, frames t and t+1 correlate by rho."""
    rng = np.random.default_rng(seed)
    noise = [rng.normal(0.0, SIGMA, (*shape, 3))]
    for _ in range(frames - 1):
        noise.append(rho * noise[-1] + math.sqrt(1 - rho**2) * rng.normal(0.0, SIGMA, (*shape, 3)))
    return np.stack(noise)


def smooth_scene(height: int, width: int) -> np.ndarray:
    """Gradients and a disc with a sharp edge, (H, W, 3) in [0, 1]."""
    y, x = np.mgrid[0:height, 0:width] / max(height, width)
    scene = np.stack([0.2 + 0.5 * x, 0.3 + 0.4 * y, 0.4 + 0.1 * np.sin(6 * x)], axis=-1)
    disc = (x - 0.5) ** 2 + (y - 0.4) ** 2 < 0.04
    scene[disc] += 0.2
    return scene


def test_independent_frames_have_no_lag_correlation() -> None:
    clip = 0.5 + ar1_noise(0.0, 6, (128, 128), seed=10)
    assert abs(temporal_lag_correlation(clip)) < 0.03


@pytest.mark.parametrize("rho", [0.3, 0.6, 0.9])
@pytest.mark.parametrize("scene", ["flat", "static"])
def test_ar1_noise_reads_its_rho(rho: float, scene: str) -> None:
    background = 0.5 if scene == "flat" else smooth_scene(128, 128)
    clip = background + ar1_noise(rho, 6, (128, 128), seed=int(rho * 10))
    assert temporal_lag_correlation(clip) == pytest.approx(rho, abs=0.04)


def test_lag_two_of_ar1_noise_reads_rho_squared() -> None:
    clip = 0.5 + ar1_noise(0.8, 8, (128, 128), seed=11)
    assert temporal_lag_correlation(clip, lag=2) == pytest.approx(0.64, abs=0.05)


def test_static_texture_with_independent_noise_is_not_read_as_persistence() -> None:
    y, x = np.mgrid[0:128, 0:128]
    # A 16-pixel sinusoid over the left half, flat on the right: the residual of the texture is the same in every
    # frame, and would read as persistent noise if its pixels were used.
    texture = 0.5 + 0.2 * np.sin(2 * np.pi * x / 16) * np.sin(2 * np.pi * y / 12) * (x < 64)
    clip = texture[..., None] + ar1_noise(0.0, 6, (128, 128), seed=12)
    assert abs(temporal_lag_correlation(clip)) < 0.05


def test_fine_texture_over_the_whole_frame_is_the_documented_limit() -> None:
    y, x = np.mgrid[0:128, 0:128]
    checker = 0.5 + 0.05 * ((x + y) % 2)
    clip = checker[..., None] + ar1_noise(0.0, 6, (128, 128), seed=13)
    assert temporal_lag_correlation(clip) > 0.5  # a static pattern everywhere looks like fully persistent noise


def test_temporal_lag_correlation_refuses_bad_clips() -> None:
    with pytest.raises(ValueError, match=r"\(T, H, W, 3\)"):
        temporal_lag_correlation(np.zeros((4, 32, 32)))
    with pytest.raises(ValueError, match="lag"):
        temporal_lag_correlation(np.zeros((2, 32, 32, 3)), lag=2)
    with pytest.raises(ValueError, match="sigma"):
        gaussian_blur(np.zeros((32, 32, 3)), sigma=0.0, axes=(0, 1))


def test_bands_from_the_first_unread_octave_on_are_the_priors_and_their_share_is_counted_per_pair() -> None:
    # Octave k of the spectral model sits at 2 ** (k + 1.5) px, the centre of band k: an estimate that read 3
    # brightness octaves (to 11 px) and 4 colour octaves took the 16-32 and 32-64 px brightness bands from its prior.
    flags = prior_bands({"brightness": 3, "colour": 4})
    assert flags == {"brightness": [False, False, False, True, True], "colour": [False, False, False, False, True]}
    assert prior_bands({"brightness": 6, "colour": 6}) == {c: [False] * len(BANDS) for c in ("brightness", "colour")}
    shares = prior_band_shares([flags, prior_bands({"brightness": 6, "colour": 6})])
    assert shares == {"brightness": [0.0, 0.0, 0.0, 0.5, 0.5], "colour": [0.0, 0.0, 0.0, 0.0, 0.5]}
    assert prior_band_shares([]) == {}
