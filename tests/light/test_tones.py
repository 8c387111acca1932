"""Darkening from a reference's tone distribution: round trips on images with a known tone distribution."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.errors import DarksynthError
from darksynth.light.darkening import Darkening, darken
from darksynth.light.tones import (
    PROBABILITIES,
    TONE_PRIOR_LOG_QUANTILES,
    TONE_PRIOR_LOG_SPREAD,
    block_medians,
    estimate_darkening,
    estimate_darkening_spread,
    fit_darkening,
    tone_quantiles,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues


def _scene(seed: int, size: int = 192, shift: float = 0.0) -> torch.Tensor:
    """(3, S, S) smooth random scene, constant over 4x4 blocks, whose block values follow the prior's tone
    distribution (shifted in log by ``shift``): a natural-like image made on the spot."""
    generator = torch.Generator().manual_seed(seed)
    coarse = torch.rand(1, 3, size // 16, size // 16, generator=generator)
    field = torch.nn.functional.interpolate(coarse, size=(size // 4, size // 4), mode="bicubic", align_corners=False)
    ranks = field.flatten().argsort().argsort().double() / (field.numel() - 1)
    levels = np.concatenate([[0.0], PROBABILITIES, [1.0]])
    tones = np.exp(np.concatenate([[np.log(1e-3)], np.asarray(TONE_PRIOR_LOG_QUANTILES) + shift, [0.0]]))
    values = torch.from_numpy(np.interp(ranks.numpy(), levels, np.clip(tones, 0.0, 1.0))).float()
    return values.reshape(field.shape)[0].repeat_interleave(4, dim=-2).repeat_interleave(4, dim=-1)


def _noisy(clean: torch.Tensor, darkening: Darkening, read: float, seed: int) -> torch.Tensor:
    values = NoiseValues.from_values({"shot": 0.02, "read": read}, dtype=torch.float32)
    signal = darken(clean, darkening.alpha, darkening.gamma)[None]
    noisy = add_noise(signal, values, generator=torch.Generator().manual_seed(seed))[0]
    return (noisy * 255).round() / 255


def test_block_medians_commute_with_darkening() -> None:
    clean = torch.rand(2, 3, 17, 22, generator=torch.Generator().manual_seed(0))
    medians = block_medians(clean, 4)
    assert medians.shape == (2, 3, 4, 5)
    torch.testing.assert_close(block_medians(darken(clean, 0.2, 0.4), 4), darken(medians, 0.2, 0.4))


def test_prior_tables_are_consistent() -> None:
    assert len(TONE_PRIOR_LOG_QUANTILES) == len(TONE_PRIOR_LOG_SPREAD) == len(PROBABILITIES)
    assert np.all(np.diff(TONE_PRIOR_LOG_QUANTILES) > 0)
    assert np.all(np.asarray(TONE_PRIOR_LOG_SPREAD) > 0)


@pytest.mark.parametrize(("alpha", "gamma"), [(0.05, 0.9), (0.15, 0.5), (0.3, 0.25), (0.2, 1.0)])
def test_noise_free_round_trip_recovers_alpha_and_gamma(alpha: float, gamma: float) -> None:
    clean = _scene(1)
    dark = darken(clean, alpha, gamma)
    result = estimate_darkening(dark, use_prior=False)
    assert result.darkening.alpha == pytest.approx(alpha, rel=0.1)
    assert result.darkening.gamma == pytest.approx(gamma, rel=0.1)
    assert result.fit_rms < 0.1
    assert 0.0 < result.confidence <= 1.0


@pytest.mark.parametrize(("seed", "alpha", "gamma"), [(2, 0.08, 0.7), (3, 0.2, 0.4), (4, 0.25, 0.9)])
def test_noisy_8bit_round_trip_recovers_the_tone_curve(seed: int, alpha: float, gamma: float) -> None:
    clean = _scene(seed)
    true = Darkening(alpha, gamma)
    result = estimate_darkening(_noisy(clean, true, read=0.01, seed=seed))
    estimated = result.darkening
    # alpha and gamma trade off against each other; the tone curve they give is the fair check.
    levels = torch.linspace(0.05, 0.95, 19)
    ours = torch.quantile(darken(clean, estimated.alpha, estimated.gamma).flatten(), levels)
    theirs = torch.quantile(darken(clean, alpha, gamma).flatten(), levels)
    mean_level = float(darken(clean, alpha, gamma).mean())
    assert float((ours - theirs).abs().mean()) / mean_level < 0.25
    assert float(darken(clean, estimated.alpha, estimated.gamma).mean()) == pytest.approx(mean_level, rel=0.2)


def test_a_darker_reference_gives_a_darker_estimate() -> None:
    clean = _scene(5)
    levels = []
    for alpha in (0.05, 0.1, 0.2, 0.3):
        estimated = estimate_darkening(_noisy(clean, Darkening(alpha, 0.6), read=0.01, seed=5)).darkening
        levels.append(float(darken(clean, estimated.alpha, estimated.gamma).mean()))
    assert np.all(np.diff(levels) > 0), levels


def test_scene_brighter_than_the_prior_reads_as_a_larger_alpha() -> None:
    # Content is not identifiable from exposure: a scene brighter than average looks like a brighter exposure.
    plain = estimate_darkening(darken(_scene(6), 0.1, 0.8), use_prior=False).darkening
    bright = estimate_darkening(darken(_scene(6, shift=0.3), 0.1, 0.8), use_prior=False).darkening
    assert bright.alpha > plain.alpha


def test_all_black_reference_is_a_clear_error() -> None:
    with pytest.raises(DarksynthError, match=r"^black.png: too dark or too flat .* 0 of 49 tone quantiles"):
        estimate_darkening(torch.zeros(3, 64, 64), source="black.png")


def test_nearly_black_noisy_reference_is_refused_not_guessed() -> None:
    clean = _scene(7)
    with pytest.raises(DarksynthError, match="too dark"):
        estimate_darkening(_noisy(clean, Darkening(0.05, 0.1), read=0.05, seed=7))


def test_flat_grey_reference_is_refused() -> None:
    with pytest.raises(DarksynthError, match="too flat"):
        fit_darkening(np.full(len(PROBABILITIES), 0.1))


def test_wrong_number_of_quantiles_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="expected 49 quantiles"):
        fit_darkening(np.ones(3))


def test_estimates_are_clipped_to_their_bounds() -> None:
    # A reference brighter than any darkening: alpha would exceed 1.
    quantiles = np.minimum(np.exp(np.asarray(TONE_PRIOR_LOG_QUANTILES) + 0.5), 0.96)
    result = fit_darkening(quantiles, use_prior=False)
    assert result.darkening.alpha == 1.0
    assert result.clipped


def test_regions_give_one_estimate_each() -> None:
    dark = darken(_scene(8), 0.15, 0.6)
    spread = estimate_darkening_spread(dark, regions=2)
    assert len(spread) == 4
    alphas = [e.darkening.alpha for e in spread]
    assert min(alphas) < 0.15 * 1.5 and max(alphas) > 0.15 / 1.5
    assert estimate_darkening_spread(torch.zeros(2, 3, 32, 32)) == []


def test_tone_quantiles_pool_frames_and_channels() -> None:
    frames = torch.stack([torch.full((3, 8, 8), 0.2), torch.full((3, 8, 8), 0.6)])
    quantiles = tone_quantiles(frames)
    assert quantiles[0] == pytest.approx(0.2) and quantiles[-1] == pytest.approx(0.6)


def _line(alpha: float, gamma: float) -> np.ndarray:
    """Tone quantiles of the prior's average scene darkened exactly by alpha and gamma."""
    return np.exp(np.log(alpha) + np.asarray(TONE_PRIOR_LOG_QUANTILES) / gamma)


def test_bounds_hit_say_which_parameter_hit_which_bound() -> None:
    brighter = fit_darkening(np.minimum(np.exp(np.asarray(TONE_PRIOR_LOG_QUANTILES) + 0.5), 0.96), use_prior=False)
    assert brighter.bounds_hit == {"alpha": "upper"}
    flat = fit_darkening(_line(0.3, 5.0), use_prior=False)  # gamma 5 lies above the search range [0.1, 2]
    assert flat.darkening.gamma == 2.0 and flat.bounds_hit == {"gamma": "upper"}
    inside = fit_darkening(_line(0.15, 0.6))
    assert inside.bounds_hit == {} and not inside.clipped


def test_prior_share_grows_as_the_tones_say_less() -> None:
    wide = fit_darkening(_line(0.3, 1.0))  # all 49 quantiles usable
    narrow = fit_darkening(_line(0.15, 0.6))  # the darkest 19 lie below the floor
    for name in ("alpha", "gamma"):
        assert 0.0 < wide.prior_share[name] < narrow.prior_share[name] < 1.0, (wide.prior_share, narrow.prior_share)
    assert wide.prior_share["gamma"] < 0.2
    assert fit_darkening(_line(0.3, 1.0), use_prior=False).prior_share == {}


def test_the_pooled_and_per_frame_estimate_equals_the_separate_calls() -> None:
    from darksynth.errors import DarksynthError
    from darksynth.light.tones import estimate_darkening, estimate_darkening_pooled_and_per_frame

    generator = torch.Generator().manual_seed(0)
    frames = (0.2 * torch.rand(3, 3, 96, 128, generator=generator) ** 2 * 255).round() / 255
    frames[1] *= 0.5
    pooled, per_frame = estimate_darkening_pooled_and_per_frame(frames)
    assert pooled.darkening == estimate_darkening(frames).darkening
    assert [e.darkening if e else None for e in per_frame] == [estimate_darkening(f).darkening for f in frames]
    with pytest.raises(DarksynthError, match="too dark or too flat"):
        estimate_darkening_pooled_and_per_frame(torch.zeros(2, 3, 64, 64))


@pytest.mark.parametrize(("alpha", "gamma"), [(0.1, 0.5), (0.2, 0.7), (0.3, 1.0)])
def test_matching_a_reference_recovers_the_darkening_of_its_own_scene(alpha: float, gamma: float) -> None:
    """Round trip: a scene darkened with known (alpha, gamma) and made noisy is the reference; matched against
    the clean scene (and against another scene, shifted in tone: the fit then follows that scene's tones)."""
    from darksynth.light.exposure import match_darkening
    from darksynth.light.tones import median_noise

    clean = _scene(3)
    reference = _noisy(clean, Darkening(alpha, gamma), read=0.004, seed=1)
    quantiles, noise = tone_quantiles(reference), median_noise(reference)
    found = match_darkening(quantiles, noise, clean).darkening
    assert found.alpha == pytest.approx(alpha, rel=0.08) and found.gamma == pytest.approx(gamma, rel=0.08)
    # Another, darker scene gets a brighter curve, so that its darkened tones are the reference's (read where the
    # reference's 8-bit rounding leaves them a few levels apart).
    darker = _scene(4, shift=-0.3)
    matched = match_darkening(quantiles, noise, darker).darkening
    ours = tone_quantiles(darken(darker, matched.alpha, matched.gamma))
    usable = (quantiles > 0.02) & (quantiles < 0.95)
    assert usable.sum() >= 10
    assert np.abs(np.log(ours[usable]) - np.log(quantiles[usable])).mean() < 0.08
    unmatched = tone_quantiles(darken(darker, alpha, gamma))
    assert np.abs(np.log(unmatched[usable]) - np.log(quantiles[usable])).mean() > 0.2


def test_matching_against_a_uniform_input_is_refused_naming_why() -> None:
    from darksynth.light.exposure import match_darkening
    from darksynth.light.tones import median_noise

    reference = _noisy(_scene(3), Darkening(0.2, 0.7), read=0.004, seed=1)
    grey = torch.full((3, 96, 96), 0.4)
    with pytest.raises(
        DarksynthError, match=r"^input: its usable tone quantiles \(\d+\) face tones that span a factor"
    ):
        match_darkening(tone_quantiles(reference), median_noise(reference), grey, source="input")
