"""The darkening line fitted between tone distributions: against the clean-scene prior, its bounds and the prior's
share; against a clean input (the exposure match), round trips on scenes with a known tone distribution."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.errors import DarksynthError
from darksynth.exposure import match_darkening
from darksynth.light.darkening import Darkening, darken
from darksynth.light.tone_fit import TONE_PRIOR_LOG_QUANTILES, TONE_PRIOR_LOG_SPREAD, fit_darkening
from darksynth.light.tones import PROBABILITIES, median_noise, tone_quantiles
from tests.tone_scenes import noisy_8bit, prior_scene


def test_prior_tables_are_consistent() -> None:
    assert len(TONE_PRIOR_LOG_QUANTILES) == len(TONE_PRIOR_LOG_SPREAD) == len(PROBABILITIES)
    assert np.all(np.diff(TONE_PRIOR_LOG_QUANTILES) > 0)
    assert np.all(np.asarray(TONE_PRIOR_LOG_SPREAD) > 0)


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


@pytest.mark.parametrize(("alpha", "gamma"), [(0.1, 0.5), (0.2, 0.7), (0.3, 1.0)])
def test_matching_a_reference_recovers_the_darkening_of_its_own_scene(alpha: float, gamma: float) -> None:
    """Round trip: a scene darkened with known (alpha, gamma) and made noisy is the reference; matched against
    the clean scene (and against another scene, shifted in tone: the fit then follows that scene's tones)."""
    clean = prior_scene(3)
    reference = noisy_8bit(clean, Darkening(alpha, gamma), read=0.004, seed=1)
    quantiles, noise = tone_quantiles(reference), median_noise(reference)
    found = match_darkening(quantiles, noise, clean).darkening
    assert found.alpha == pytest.approx(alpha, rel=0.08) and found.gamma == pytest.approx(gamma, rel=0.08)
    # Another, darker scene gets a brighter curve, so that its darkened tones are the reference's (read where the
    # reference's 8-bit rounding leaves them a few levels apart).
    darker = prior_scene(4, shift=-0.3)
    matched = match_darkening(quantiles, noise, darker).darkening
    ours = tone_quantiles(darken(darker, matched.alpha, matched.gamma))
    usable = (quantiles > 0.02) & (quantiles < 0.95)
    assert usable.sum() >= 10
    assert np.abs(np.log(ours[usable]) - np.log(quantiles[usable])).mean() < 0.08
    unmatched = tone_quantiles(darken(darker, alpha, gamma))
    assert np.abs(np.log(unmatched[usable]) - np.log(quantiles[usable])).mean() > 0.2


def test_matching_against_a_uniform_input_is_refused_naming_why() -> None:
    reference = noisy_8bit(prior_scene(3), Darkening(0.2, 0.7), read=0.004, seed=1)
    grey = torch.full((3, 96, 96), 0.4)
    with pytest.raises(
        DarksynthError, match=r"^input: its usable tone quantiles \(\d+\) face tones that span a factor"
    ):
        match_darkening(tone_quantiles(reference), median_noise(reference), grey, source="input")
