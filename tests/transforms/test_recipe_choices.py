"""The recipe's choices reach the library's calls: ``synthesize`` and both transforms take every field of
:class:`darksynth.recipe.ClipRecipe` under its name, with its default, and act on it (blur, flicker, colour cast)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import torch

import darksynth
from darksynth.light.darkening import Darkening, darken
from darksynth.light.tones import ToneTarget, colour_cast, median_noise, tone_quantiles
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.recipe import AUGMENTING, ClipRecipe, RecipeChoices
from darksynth.transforms import LowLight

SODIUM = (1.45, 0.95, 0.60)
"""A sodium-lit street's channel shares (the cast a profile's ``tone.colour`` holds)."""


def _albumentations_transform() -> Callable[..., Any]:
    pytest.importorskip("albumentations")
    from darksynth.transforms import AlbumentationsLowLight

    return AlbumentationsLowLight  # type: ignore[no-any-return]


def test_the_library_s_keywords_are_the_recipe_s_fields() -> None:
    # A field added to the recipe without its keyword fails here (and mypy checks the calls against the keywords).
    fields = {f.name for f in dataclasses.fields(ClipRecipe)} - {"profile"}
    assert set(RecipeChoices.__annotations__) == fields


@pytest.mark.parametrize("call", ["LowLight", "AlbumentationsLowLight"])
def test_a_transform_takes_the_recipe_s_defaults_but_draws(call: str) -> None:
    profile = _lit_profile()
    transform_class = LowLight if call == "LowLight" else _albumentations_transform()
    assert transform_class(profile).recipe == ClipRecipe(profile, jitter=AUGMENTING)
    chosen = transform_class(profile, jitter=False, blur=False, match_colour=True, camera="phone", darkening=None)
    assert chosen.recipe == ClipRecipe(profile, darkening=None, blur=False, match_colour=True, camera="phone")


@pytest.mark.parametrize("call", ["synthesize", "LowLight", "AlbumentationsLowLight"])
def test_a_keyword_that_is_no_choice_of_the_recipe_is_refused(call: str) -> None:
    profile = _lit_profile()
    make: Callable[[], Any] = {
        "synthesize": lambda: darksynth.synthesize(_scene(0), profile, flickr=False),  # type: ignore[call-arg]
        "LowLight": lambda: LowLight(profile, flickr=False),  # type: ignore[call-arg]
        "AlbumentationsLowLight": lambda: _albumentations_transform()(profile, flickr=False),
    }[call]
    with pytest.raises(TypeError, match="unexpected keyword argument 'flickr'"):
        make()


def _lit_profile(tone: ToneTarget | None = None) -> Profile:
    noise = NoiseValues.from_values(
        {"shot": 0.01, "read": 0.002, "quantization": 0.0, "banding": 0.0, "flicker": 0.08, "shake_length": 0.01}
    )
    return Profile(noise=noise, darkening=Darkening(0.3, 0.7), tone=tone)


def _scene(seed: int) -> torch.Tensor:
    generator = np.random.default_rng(seed)
    base = generator.uniform(0.2, 0.9, size=(3, 1, 1))
    texture = generator.uniform(-0.15, 0.15, size=(3, 48, 48))
    return torch.from_numpy(np.clip(base + texture, 0.0, 1.0)).to(torch.float32)


@pytest.mark.parametrize("choice", ["blur", "flicker"])
def test_a_light_choice_switched_off_leaves_its_values_neutral(choice: str) -> None:
    names = {"blur": ("shake_length", "exposure_fraction"), "flicker": ("flicker",)}[choice]
    clip = torch.stack([_scene(0)] * 3)
    on = LowLight(_lit_profile(), seed=1, jitter=False).sample(clip).parameters
    off = LowLight(_lit_profile(), seed=1, jitter=False, **{choice: False}).sample(clip).parameters
    assert isinstance(on, dict) and isinstance(off, dict)
    assert any(on["light"][name] != 0.0 for name in names), on["light"]
    assert all(off["light"][name] == 0.0 for name in names), off["light"]
    # The other light stays.
    other = {"blur": "flicker", "flicker": "shake_length"}[choice]
    assert off["light"][other] == on["light"][other] != 0.0


def _cast_target() -> ToneTarget:
    reference = darken(_scene(9), 0.15, 0.5)
    quantiles = tuple(float(q) for q in tone_quantiles(reference))
    return ToneTarget(quantiles, median_noise(reference), colour=SODIUM)


@pytest.mark.parametrize("seed", [0, 1])
def test_match_colour_gives_the_reference_s_cast_in_both_dtypes(seed: int) -> None:
    profile = dataclasses.replace(_lit_profile(_cast_target()), noise=NoiseValues.from_values({"shot": 0.0}))
    clean = _scene(seed)
    levels = (clean * 255.0).round().to(torch.uint8)
    cast = LowLight(profile, seed=seed, match_colour=True, blur=False, flicker=False)
    plain = LowLight(profile, seed=seed, blur=False, flicker=False)
    from_bytes = cast.sample(levels, seed=3)
    from_floats = cast.sample(levels.to(torch.float32) / 255.0, seed=3)
    assert isinstance(from_bytes.parameters, dict) and "colour_scale" in from_bytes.parameters
    # A float image of 8-bit levels takes the 8-bit route, colour cast included: the same pixels.
    assert isinstance(from_bytes.image, torch.Tensor) and isinstance(from_floats.image, torch.Tensor)
    assert torch.equal(from_bytes.image.to(torch.float32) / 255.0, from_floats.image)
    shares = colour_cast(from_floats.image[None].to(torch.float32))
    assert shares is not None and np.abs(np.subtract(shares, SODIUM)).max() < 0.06, shares
    without = plain.sample(levels.to(torch.float32) / 255.0, seed=3)
    assert isinstance(without.parameters, dict) and "colour_scale" not in without.parameters
    assert isinstance(without.image, torch.Tensor)
    unmatched = colour_cast(without.image[None].to(torch.float32))
    assert unmatched is not None and np.abs(np.subtract(unmatched, SODIUM)).max() > 0.2, unmatched


def test_albumentations_replays_the_colour_cast_and_serialises_every_choice() -> None:
    import albumentations as A

    transform_class = _albumentations_transform()
    profile = _lit_profile(_cast_target())
    image = (_scene(4).permute(1, 2, 0).numpy() * 255.0).round().astype(np.uint8)
    transform = transform_class(profile, p=1.0, match_colour=True, flicker=False, jitter=False)
    first = A.ReplayCompose([transform])(image=image)
    (record,) = first["replay"]["transforms"]
    assert record["params"]["colour_scale"] is not None
    replayed = A.ReplayCompose.replay(first["replay"], image=image)
    assert np.array_equal(first["image"], replayed["image"])
    (rebuilt,) = A.from_dict(A.to_dict(A.Compose([transform], seed=5))).transforms
    assert (rebuilt.match_colour, rebuilt.flicker, rebuilt.jitter, rebuilt.blur) == (True, False, False, True)
    assert rebuilt.recipe == ClipRecipe(profile, match_colour=True, flicker=False, jitter=False)
