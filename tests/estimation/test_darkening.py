"""The darkening of a reference read off its tone distribution: round trips on images with a known tone
distribution."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.errors import DarksynthError
from darksynth.estimation.darkening_reading import (
    estimate_darkening,
    estimate_darkening_pooled_and_per_frame,
    estimate_darkening_spread,
)
from darksynth.light.darkening import Darkening, darken
from tests.tone_scenes import noisy_8bit, prior_scene


@pytest.mark.parametrize(("alpha", "gamma"), [(0.05, 0.9), (0.15, 0.5), (0.3, 0.25), (0.2, 1.0)])
def test_noise_free_round_trip_recovers_alpha_and_gamma(alpha: float, gamma: float) -> None:
    clean = prior_scene(1)
    dark = darken(clean, alpha, gamma)
    result = estimate_darkening(dark, use_prior=False)
    assert result.darkening.alpha == pytest.approx(alpha, rel=0.1)
    assert result.darkening.gamma == pytest.approx(gamma, rel=0.1)
    assert result.fit_rms < 0.1
    assert 0.0 < result.confidence <= 1.0


@pytest.mark.parametrize(("seed", "alpha", "gamma"), [(2, 0.08, 0.7), (3, 0.2, 0.4), (4, 0.25, 0.9)])
def test_noisy_8bit_round_trip_recovers_the_tone_curve(seed: int, alpha: float, gamma: float) -> None:
    clean = prior_scene(seed)
    true = Darkening(alpha, gamma)
    result = estimate_darkening(noisy_8bit(clean, true, read=0.01, seed=seed))
    estimated = result.darkening
    # alpha and gamma trade off against each other; the tone curve they give is the fair check.
    levels = torch.linspace(0.05, 0.95, 19)
    ours = torch.quantile(darken(clean, estimated.alpha, estimated.gamma).flatten(), levels)
    theirs = torch.quantile(darken(clean, alpha, gamma).flatten(), levels)
    mean_level = float(darken(clean, alpha, gamma).mean())
    assert float((ours - theirs).abs().mean()) / mean_level < 0.25
    assert float(darken(clean, estimated.alpha, estimated.gamma).mean()) == pytest.approx(mean_level, rel=0.2)


def test_a_darker_reference_gives_a_darker_estimate() -> None:
    clean = prior_scene(5)
    levels = []
    for alpha in (0.05, 0.1, 0.2, 0.3):
        estimated = estimate_darkening(noisy_8bit(clean, Darkening(alpha, 0.6), read=0.01, seed=5)).darkening
        levels.append(float(darken(clean, estimated.alpha, estimated.gamma).mean()))
    assert np.all(np.diff(levels) > 0), levels


def test_scene_brighter_than_the_prior_reads_as_a_larger_alpha() -> None:
    # Content is not identifiable from exposure: a scene brighter than average looks like a brighter exposure.
    plain = estimate_darkening(darken(prior_scene(6), 0.1, 0.8), use_prior=False).darkening
    bright = estimate_darkening(darken(prior_scene(6, shift=0.3), 0.1, 0.8), use_prior=False).darkening
    assert bright.alpha > plain.alpha


def test_all_black_reference_is_a_clear_error() -> None:
    with pytest.raises(DarksynthError, match=r"^black.png: too dark or too flat .* 0 of 49 tone quantiles"):
        estimate_darkening(torch.zeros(3, 64, 64), source="black.png")


def test_nearly_black_noisy_reference_is_refused_not_guessed() -> None:
    clean = prior_scene(7)
    with pytest.raises(DarksynthError, match="too dark"):
        estimate_darkening(noisy_8bit(clean, Darkening(0.05, 0.1), read=0.05, seed=7))


def test_regions_give_one_estimate_each() -> None:
    dark = darken(prior_scene(8), 0.15, 0.6)
    spread = estimate_darkening_spread(dark, regions=2)
    assert len(spread) == 4
    alphas = [e.darkening.alpha for e in spread]
    assert min(alphas) < 0.15 * 1.5 and max(alphas) > 0.15 / 1.5
    assert estimate_darkening_spread(torch.zeros(2, 3, 32, 32)) == []


def test_the_pooled_and_per_frame_estimate_equals_the_separate_calls() -> None:

    generator = torch.Generator().manual_seed(0)
    frames = (0.2 * torch.rand(3, 3, 96, 128, generator=generator) ** 2 * 255).round() / 255
    frames[1] *= 0.5
    pooled, per_frame = estimate_darkening_pooled_and_per_frame(frames)
    assert pooled.darkening == estimate_darkening(frames).darkening
    assert [e.darkening if e else None for e in per_frame] == [estimate_darkening(f).darkening for f in frames]
    with pytest.raises(DarksynthError, match="too dark or too flat"):
        estimate_darkening_pooled_and_per_frame(torch.zeros(2, 3, 64, 64))
