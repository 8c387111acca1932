"""The recipe's camera option: a whole camera drawn per clip from the prior or a preset, given the profile's
measured values when it has them, after every draw a recipe without it makes."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from darksynth.cameras.presets import CAMERA_CHOICES, camera_source
from darksynth.cameras.prior import BLIND_OCTAVES, LEVEL_RANGE_8BIT
from darksynth.errors import DarksynthError
from darksynth.noise.components import noise_parameter
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.spectral_components import SPECTRUM_REPLACES
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import ClipRecipe, draw_clip_parameters
from tests.conftest import measured_profile

SPECTRAL_NAMES = ("level_curve", "octave_power", "octave_correlation", "compression")


def _seeded(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def test_without_a_camera_the_draws_are_those_of_the_profile_alone() -> None:
    profile = load_profile(default_profile_path())
    ranged = dataclasses.replace(profile, ranges={"shot": ((0.02, 0.08),), "alpha": ((0.1, 0.3),)})
    generator, alone = _seeded(5), _seeded(5)
    chosen = ClipRecipe(ranged, jitter=True).choose(generator)
    expected = draw_clip_parameters(ranged, generator=alone)
    assert chosen == expected and "camera" not in chosen.to_json()
    # The generator is left where the draws without the option leave it, so the noise that follows is the same.
    assert torch.equal(generator.get_state(), alone.get_state())


def test_the_camera_is_drawn_after_the_draws_every_recipe_makes() -> None:
    profile = dataclasses.replace(load_profile(default_profile_path()), ranges={"alpha": ((0.1, 0.3),)})
    for seed in range(5):
        plain = ClipRecipe(profile, jitter=True).choose(_seeded(seed))
        with_camera = ClipRecipe(profile, jitter=True, camera="prior").choose(_seeded(seed))
        assert with_camera.darkening == plain.darkening
        for name in ("quantization", "banding", "temporal_banding", "periodic"):
            assert torch.equal(with_camera.noise[name], plain.noise[name]), name


@pytest.mark.parametrize("camera", CAMERA_CHOICES)
def test_a_seed_fixes_the_camera_and_other_seeds_draw_others(camera: str) -> None:
    recipe = ClipRecipe(load_profile(default_profile_path()), camera=camera)
    first, again = recipe.choose(_seeded(11)), recipe.choose(_seeded(11))
    assert first.to_json() == again.to_json()
    curves = {tuple(recipe.choose(_seeded(seed)).noise["level_curve"].tolist()) for seed in range(20)}
    assert len(curves) == 20
    assert first.to_json()["camera"] == {"source": camera, "given_profile": False}


def test_a_whole_camera_replaces_the_heteroscedastic_values_and_keeps_the_rest() -> None:
    profile = load_profile(default_profile_path())
    drawn = ClipRecipe(profile, camera="prior", jitter=False).choose(_seeded(2))
    for name in SPECTRUM_REPLACES:
        assert drawn.noise.is_neutral(noise_parameter(name)), name
    assert bool((drawn.noise["level_curve"] > 0).all())
    for name in ("quantization", "banding", "temporal_banding", "periodic", "temporal_correlation"):
        assert torch.equal(drawn.noise[name], profile.noise[name]), name
    assert drawn.darkening == profile.darkening


def test_a_measured_profile_keeps_its_level_jpeg_and_finer_octaves_and_draws_the_coarse() -> None:
    profile = measured_profile()
    recipe = ClipRecipe(profile, camera="dslr-jpeg", jitter=False)
    draws = [recipe.choose(_seeded(seed)) for seed in range(12)]
    finer = slice(0, BLIND_OCTAVES * 3)
    coarse = slice(BLIND_OCTAVES * 3, OCTAVES * 3)
    for drawn in draws:
        assert drawn.to_json()["camera"] == {"source": "dslr-jpeg", "given_profile": True}
        for name in ("level_curve", "compression", "temporal_correlation", "banding", "periodic", "quantization"):
            assert torch.equal(drawn.noise[name], profile.noise[name]), name
        for name in ("octave_power", "octave_correlation"):
            assert torch.equal(drawn.noise[name][finer], profile.noise[name][finer]), name
        assert drawn.darkening == profile.darkening
    for name in ("octave_power", "octave_correlation"):
        coarse_draws = {tuple(drawn.noise[name][coarse].tolist()) for drawn in draws}
        assert len(coarse_draws) == len(draws), name


def test_whole_cameras_spread_as_the_prior_does() -> None:
    # 1000 draws: each camera's loudness (mean log std over the curve) is log-uniform over LEVEL_RANGE_8BIT, so its
    # quartiles sit at a quarter, half and three quarters of the log span (standard error of a quartile about 1.4 %
    # of the span); the curve's shape about it spreads as the prior's shape features do given the loudness.
    count = 1000
    prior = camera_source("prior")
    recipe = ClipRecipe(load_profile(default_profile_path()), camera="prior")
    curves = torch.stack([recipe.choose(_seeded(seed)).noise["level_curve"] for seed in range(count)])
    logs = curves.log()
    loudness = logs.mean(1)
    low, high = (math.log(level / 255.0) for level in LEVEL_RANGE_8BIT)
    quartiles = torch.quantile(loudness, torch.tensor([0.25, 0.5, 0.75], dtype=logs.dtype))
    expected = torch.tensor([low + q * (high - low) for q in (0.25, 0.5, 0.75)], dtype=logs.dtype)
    assert torch.allclose(quartiles, expected, atol=0.05 * (high - low))
    shape = logs - loudness[:, None]
    level = prior.slices()["level_curve"]
    scale_index = level.start
    others = torch.arange(level.start + 1, level.stop)
    gain = prior.covariance[others, scale_index] / prior.covariance[scale_index, scale_index]
    conditional = prior.covariance.diagonal()[others] - gain * prior.covariance[others, scale_index]
    total = conditional + gain**2 * (high - low) ** 2 / 12
    assert torch.allclose(shape.var(0), total, rtol=0.2)


def test_an_unknown_camera_is_refused_with_the_choices() -> None:
    with pytest.raises(DarksynthError, match=r"unknown camera 'nikon'; choose one of prior, phone, dslr, dslr-jpeg"):
        ClipRecipe(load_profile(default_profile_path()), camera="nikon")


def test_without_a_generator_each_clip_gets_its_own_camera_and_the_global_generator_is_left_alone() -> None:
    recipe = ClipRecipe(load_profile(default_profile_path()), camera="prior")
    state = torch.random.get_rng_state()
    curves = {tuple(recipe.choose(None).noise["level_curve"].tolist()) for _ in range(3)}
    assert len(curves) == 3
    assert torch.equal(torch.random.get_rng_state(), state)
