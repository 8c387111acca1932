"""The reference's exposure carried by the profile and matched per input by ``apply``."""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from darksynth.apply import ApplyOptions, apply
from darksynth.errors import ProfileError
from darksynth.exposure import (
    compass_search,
    fit_output_darkening,
    match_darkening,
    matched_colour,
    matched_darkening,
    output_model,
    simulated_luminance_quantiles,
    sorted_quantiles,
)
from darksynth.light.darkening import Darkening, darken
from darksynth.light.tones import (
    PROBABILITIES,
    ToneTarget,
    colour_cast,
    luminance_quantiles,
    median_noise,
    sampled_tone_quantiles,
    tone_quantiles,
)
from darksynth.noise.level import channel_noise_std
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, parse_profile, profile_to_dict
from darksynth.recipe import ClipRecipe
from darksynth.synthesize import synthesize


def _scene(seed: int, scale: float) -> np.ndarray:
    """(96, 128, 3) uint8 smooth scene with a spread of tones, its brightness scaled by ``scale``."""
    rng = np.random.default_rng(seed)
    coarse = rng.random((6, 8, 3))
    image = np.kron(coarse, np.ones((16, 16, 1)))
    ramp = np.linspace(0.2, 1.0, 128)[None, :, None]
    return np.clip(image * ramp * scale * 255.0, 0, 255).round().astype(np.uint8)


def _chw(pixels: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(pixels).permute(2, 0, 1).to(torch.float32) / 255.0


def _profile(tone: ToneTarget | None) -> Profile:
    noise = NoiseValues.from_values({"shot": 0.01, "read": 0.002, "quantization": 0.0, "banding": 0.0})
    return Profile(noise=noise, darkening=Darkening(0.2, 0.6), tone=tone)


def _target() -> ToneTarget:
    reference = darken(_chw(_scene(1, 1.0)), 0.15, 0.5)
    return ToneTarget(tuple(float(q) for q in tone_quantiles(reference)), median_noise(reference))


def test_the_tone_target_round_trips_through_the_document_and_bad_ones_are_refused() -> None:
    profile = _profile(_target())
    document = profile_to_dict(profile)
    assert len(document["tone"]["quantiles"]) == 49
    assert parse_profile(json.loads(json.dumps(document))).tone == profile.tone
    assert parse_profile(profile_to_dict(_profile(None))).tone is None
    falling = dict(document, tone={"quantiles": list(reversed(document["tone"]["quantiles"])), "noise": 0.001})
    with pytest.raises(ProfileError, match=r"^x: tone.quantiles must be 49 non-decreasing numbers in \[0, 1\]"):
        parse_profile(falling, source="x")
    with pytest.raises(
        ProfileError, match=r"^x: tone must be an object with quantiles, noise and optionally colour and luminance"
    ):
        parse_profile(dict(document, tone=[0.1]), source="x")


def test_apply_darkens_each_input_to_the_reference_s_tones(tmp_path: Path) -> None:
    """Two scenes, one bright and one dim: with the tone target each is darkened to the reference's tones (their
    own alpha and gamma, in the manifest); with the profile's one darkening they stay apart; --alpha/--gamma still
    fix it."""
    folder = tmp_path / "in"
    folder.mkdir()
    Image.fromarray(_scene(2, 1.0)).save(folder / "bright.png")
    Image.fromarray(_scene(3, 0.35)).save(folder / "dim.png")
    target = _target()

    def run(name: str, profile: Profile, darkening: Darkening | str = "profile") -> dict[str, dict[str, float]]:
        options = ApplyOptions(recipe=ClipRecipe(profile, darkening=darkening), seed=0)  # type: ignore[arg-type]
        apply(folder, tmp_path / name, options)
        manifest = json.loads((tmp_path / name / "darksynth-manifest.json").read_text())
        return {record["input"]: record["parameters"]["darkening"] for record in manifest["files"]}

    def gap(name: str, file: str) -> float:
        pixels = np.array(Image.open(tmp_path / name / file).convert("RGB"))
        found = tone_quantiles(_chw(pixels))
        usable = (np.asarray(target.quantiles) > 0.02) & (np.asarray(target.quantiles) < 0.95)
        return float(np.abs(np.log(found[usable]) - np.log(np.asarray(target.quantiles)[usable])).mean())

    matched = run("matched", _profile(target))
    assert matched["bright.png"] != matched["dim.png"]  # each its own
    assert matched["dim.png"]["gamma"] > matched["bright.png"]["gamma"]  # the dim one is lifted
    fixed = run("fixed", _profile(None))
    assert fixed["bright.png"] == fixed["dim.png"] == {"alpha": 0.2, "gamma": 0.6}
    for file in ("bright.png", "dim.png"):
        assert gap("matched", file) < 0.12
    assert max(gap("fixed", f) for f in ("bright.png", "dim.png")) > 2 * max(
        gap("matched", f) for f in ("bright.png", "dim.png")
    )
    chosen = run("chosen", _profile(target), Darkening(0.25, 0.8))
    assert chosen["bright.png"] == chosen["dim.png"] == {"alpha": 0.25, "gamma": 0.8}


def test_no_target_or_a_uniform_input_keeps_the_profile_s_darkening(caplog: pytest.LogCaptureFixture) -> None:
    grey = torch.full((3, 64, 64), 120, dtype=torch.uint8)
    assert matched_darkening(grey, None) is None
    with caplog.at_level(logging.WARNING, logger="darksynth.exposure"):
        assert matched_darkening(grey, _target(), source="grey.png") is None
    assert any("grey.png" in r.getMessage() and "profile's darkening is used" in r.getMessage() for r in caplog.records)
    # uint8 and the same frame as float give the same match.
    scene = torch.from_numpy(_scene(4, 0.8)).permute(2, 0, 1)
    tone = _target()
    assert matched_darkening(scene, tone) == matched_darkening(scene.to(torch.float32) / 255.0, tone)
    assert dataclasses.is_dataclass(matched_darkening(scene, tone))


def test_synthesize_darkens_each_clip_to_the_reference_s_tones_too() -> None:
    """The library call (what the training transforms run) matches as apply does; a given darkening wins."""
    profile = _profile(_target())
    bright, dim = (torch.from_numpy(_scene(seed, scale)).permute(2, 0, 1) for seed, scale in ((2, 1.0), (3, 0.35)))
    records = [
        synthesize(image, profile, generator=torch.Generator().manual_seed(0)).parameters for image in (bright, dim)
    ]
    darkenings = [r["darkening"] for r in records if isinstance(r, dict)]
    assert len(darkenings) == 2 and darkenings[0] != darkenings[1]
    assert darkenings[1]["gamma"] > darkenings[0]["gamma"]
    fixed = synthesize(bright, profile, darkening=Darkening(0.25, 0.8)).parameters
    assert isinstance(fixed, dict) and fixed["darkening"] == {"alpha": 0.25, "gamma": 0.8}
    assert synthesize(bright, _profile(None)).parameters["darkening"] == {"alpha": 0.2, "gamma": 0.6}  # type: ignore[call-overload]


def test_large_inputs_are_matched_on_every_k_th_block_with_the_same_quantiles_within_two_levels() -> None:
    small = _chw(_scene(5, 0.9))
    assert np.array_equal(sampled_tone_quantiles(small), tone_quantiles(small))
    rng = np.random.default_rng(6)
    coarse = rng.random((34, 60, 3))
    large = torch.from_numpy(np.kron(coarse, np.ones((32, 32, 1)))).permute(2, 0, 1).to(torch.float32)
    large = large * torch.linspace(0.3, 1.0, large.shape[-1])
    assert large.shape[-2:] == (1088, 1920)
    gap = np.abs(sampled_tone_quantiles(large) - tone_quantiles(large))
    # (The first block of each group lies on the dark side of the ramp: a bias of about half a level.)
    assert gap.max() < 2.0 / 255.0 and gap.mean() < 1.0 / 255.0


SODIUM = (1.45, 0.95, 0.60)
"""A sodium-lit street's channel shares."""


def _orange_target() -> ToneTarget:
    return dataclasses.replace(_target(), colour=SODIUM)


def test_the_colour_cast_round_trips_and_a_bad_one_is_refused() -> None:
    document = profile_to_dict(_profile(_orange_target()))
    assert document["tone"]["colour"] == list(SODIUM)
    assert parse_profile(json.loads(json.dumps(document))).tone == _orange_target()
    bad = dict(document, tone=dict(document["tone"], colour=[1.0, 1.0]))
    with pytest.raises(ProfileError, match=r"^x: tone.colour must be 3 numbers in \[0, 3\]"):
        parse_profile(bad, source="x")
    grey = torch.full((1, 3, 32, 32), 0.2)
    assert colour_cast(grey) == pytest.approx((1.0, 1.0, 1.0))
    assert colour_cast(torch.zeros(1, 3, 32, 32)) is None


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_matched_colour_gives_the_reference_s_cast_and_keeps_the_brightness(seed: int) -> None:
    clean = torch.from_numpy(_scene(seed, 1.0)).permute(2, 0, 1).contiguous()
    darkening = Darkening(0.2, 0.6)
    found = matched_colour(clean, _orange_target(), darkening)
    assert found is not None
    scale, adjusted = found
    assert max(scale) == pytest.approx(1.0) and min(scale) > 0.0
    scaled = clean.to(torch.float32) / 255.0 * torch.tensor(scale)[:, None, None]
    output = darken(scaled, adjusted.alpha, adjusted.gamma)
    cast = colour_cast(output[None])
    assert cast is not None
    assert np.abs(np.subtract(cast, SODIUM)).max() < 0.03
    before = colour_cast(darken(clean.to(torch.float32) / 255.0, 0.2, 0.6)[None])
    assert before is not None and np.abs(np.subtract(before, SODIUM)).max() > 0.2
    # The brightness (mean of the channels) moves by a few percent at most.
    plain = darken(clean.to(torch.float32) / 255.0, 0.2, 0.6)
    assert float(output.mean()) == pytest.approx(float(plain.mean()), rel=0.1)


def test_apply_matches_the_colour_only_when_asked(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    Image.fromarray(_scene(2, 1.0)).save(folder / "a.png")
    profile = _profile(_orange_target())
    casts = {}
    for name, match in (("plain", False), ("orange", True)):
        report = apply(folder, tmp_path / name, ApplyOptions(recipe=ClipRecipe(profile, match_colour=match), seed=0))
        (record,) = report.records
        assert ("colour_scale" in record["parameters"]) is match
        pixels = np.array(Image.open(tmp_path / name / "a.png").convert("RGB"))
        casts[name] = colour_cast(_chw(pixels)[None])
    assert np.abs(np.subtract(casts["orange"], SODIUM)).max() < 0.06
    assert np.abs(np.subtract(casts["plain"], SODIUM)).max() > 0.2


# --- the match fitted on the output's luminance quantiles ----------------------------------------------------

NOISY = NoiseValues.from_values({"shot": 0.03, "read": 0.02, "quantization": 0.0, "banding": 0.0})
"""Noise strong enough against a dark output (about 5 8-bit levels at its median) that it widens the luminance
quantiles and clipping at black lifts the lowest."""


def _landscape() -> np.ndarray:
    """(192, 256, 3) uint8 smooth scene: random colours on a grid of 8 px, interpolated; its top and bottom halves
    are crops of one scene with similar, not equal, tones."""
    rng = np.random.default_rng(11)
    coarse = torch.from_numpy(rng.random((1, 3, 25, 33))).to(torch.float32)
    smooth = torch.nn.functional.interpolate(coarse, size=(192, 256), mode="bilinear", align_corners=True)[0]
    return (smooth * 255.0).round().clamp(0, 255).to(torch.uint8).permute(1, 2, 0).numpy()


def _noisy_profile(tone: ToneTarget | None) -> Profile:
    return Profile(noise=NOISY, darkening=Darkening(0.2, 0.6), tone=tone)


def _reference_target(reference: torch.Tensor) -> ToneTarget:
    """The tone target as ``estimate`` reads it from a reference (3, H, W) in [0, 1]."""
    return ToneTarget(
        tuple(float(q) for q in tone_quantiles(reference)),
        median_noise(reference),
        luminance=tuple(float(q) for q in luminance_quantiles(reference)),
    )


def _output(clean: np.ndarray, profile: Profile, darkening: Darkening | str = "profile") -> torch.Tensor:
    result = synthesize(
        torch.from_numpy(clean).permute(2, 0, 1).contiguous(),
        profile,
        darkening=darkening,
        generator=torch.Generator().manual_seed(3),
    )  # type: ignore[arg-type]
    return torch.as_tensor(result.image).to(torch.float32) / 255.0


def _luminance_gap(output: torch.Tensor, target: ToneTarget) -> float:
    """Mean absolute difference of the output's luminance quantiles from the target's, 4% to 96%."""
    assert target.luminance is not None
    middle = slice(1, -1)
    return float(np.abs(luminance_quantiles(output)[middle] - np.asarray(target.luminance)[middle]).mean())


@pytest.mark.parametrize(("alpha", "gamma"), [(0.12, 0.6), (0.25, 1.0), (0.15, 0.45), (0.3, 0.8)])
def test_a_noisy_reference_s_darkening_is_recovered_on_another_crop_of_its_scene(alpha: float, gamma: float) -> None:
    """A crop darkened with a known alpha and gamma and the profile's noise is the reference; the other crop of the
    same scene, matched to its tone target, gets the same tone curve, and its output the reference's luminance."""
    scene = _landscape()
    truth = Darkening(alpha, gamma)
    reference = _output(scene[:96], _noisy_profile(None), truth)
    target = _reference_target(reference)
    other = torch.from_numpy(np.ascontiguousarray(scene[96:])).permute(2, 0, 1)
    found = matched_darkening(other, target, noise=NOISY)
    assert found is not None
    # The tone curve at the crop's own tones, 10% to 90%: the two crops' tones differ a little, and the fit
    # answers for that (the same crop gets within 8%).
    levels = torch.from_numpy(np.quantile(scene[96:], np.linspace(0.1, 0.9, 9)) / 255.0).to(torch.float32)
    curve_error = (darken(levels, found.alpha, found.gamma) / darken(levels, alpha, gamma) - 1.0).abs()
    assert float(curve_error.max()) < 0.2
    output = _output(np.ascontiguousarray(scene[96:]), _noisy_profile(target))
    assert _luminance_gap(output, target) < 1.0 / 255.0


def test_the_output_fit_comes_closer_than_the_block_medians_where_noise_and_clipping_weigh() -> None:
    """On a dark, noisy reference the block medians leave out what the noise adds to the output's spread and what
    clipping at black adds to its low end; the output fit brings the luminance quantiles nearer the reference's."""
    scene = _landscape()
    reference = _output(scene[:96], _noisy_profile(None), Darkening(0.06, 0.5))
    target = _reference_target(reference)
    other = np.ascontiguousarray(scene[96:])
    block_only = dataclasses.replace(target, luminance=None)
    before = _luminance_gap(_output(other, _noisy_profile(block_only)), target)
    after = _luminance_gap(_output(other, _noisy_profile(target)), target)
    assert after < 0.7 * before


def test_a_profile_without_luminance_quantiles_loads_and_matches_on_the_block_medians() -> None:
    """Profiles written before the luminance quantiles keep working: the tone target reads without them and the
    match is the block-median one, noise or not."""
    target = _reference_target(_output(_landscape()[:96], _noisy_profile(None), Darkening(0.12, 0.6)))
    document = profile_to_dict(_noisy_profile(target))
    assert len(document["tone"]["luminance"]) == 49
    assert parse_profile(json.loads(json.dumps(document))).tone == target
    del document["tone"]["luminance"]
    old = parse_profile(json.loads(json.dumps(document))).tone
    assert old is not None and old.luminance is None and old.quantiles == target.quantiles
    other = torch.from_numpy(np.ascontiguousarray(_landscape()[96:])).permute(2, 0, 1)
    block = match_darkening(np.asarray(old.quantiles), old.noise, other.to(torch.float32) / 255.0).darkening
    assert matched_darkening(other, old, noise=NOISY) == block
    assert matched_darkening(other, target, noise=NOISY) != block
    falling = dict(document, tone=dict(document["tone"], luminance=list(reversed(target.luminance or ()))))
    with pytest.raises(ProfileError, match=r"^x: tone.luminance must be 49 non-decreasing numbers in \[0, 1\]"):
        parse_profile(falling, source="x")


def test_the_simulated_output_has_the_noise_std_and_the_quantiles_of_the_real_one() -> None:
    """The simulation's pieces against the composer: the std table against drawn noise at a flat level, and the
    simulated luminance quantiles against a synthesized output's."""
    flat = torch.full((1, 3, 128, 128), 0.05)
    drawn = noise_sum(flat, NOISY, generator=torch.Generator().manual_seed(0))
    std = channel_noise_std(NOISY, torch.tensor([0.05]))
    assert np.allclose(drawn.reshape(3, -1).std(dim=1).numpy(), std[0].numpy(), rtol=0.05)
    scene = _landscape()
    darkening = Darkening(0.1, 0.5)
    model = output_model(torch.from_numpy(scene).permute(2, 0, 1).to(torch.float32) / 255.0, NOISY)
    simulated = simulated_luminance_quantiles(model, darkening)
    real = luminance_quantiles(_output(scene, _noisy_profile(None), darkening))
    assert np.abs(simulated - real)[1:-1].mean() < 1.0 / 255.0
    noiseless = simulated_luminance_quantiles(
        dataclasses.replace(model, noise=output_model(flat[0], None).noise), darkening
    )
    # Without the noise the dark end is off by about a level: the noise the simulation adds is what brings it in.
    assert np.abs(noiseless - real)[:5].mean() > 3.0 * np.abs(simulated - real)[:5].mean()


def test_sorted_quantiles_are_numpy_s_and_the_compass_search_finds_a_stepped_minimum() -> None:
    values = np.sort(np.random.default_rng(0).random(1001))
    assert np.allclose(sorted_quantiles(values, PROBABILITIES), np.quantile(values, PROBABILITIES))

    def stepped(point: np.ndarray) -> float:
        # A bowl at (0.3, -0.7) seen through steps of 0.02, as 8-bit levels show a smooth curve.
        return float(np.round(((point[0] - 0.3) ** 2 + 4 * (point[1] + 0.7) ** 2) / 0.02) * 0.02)

    found = compass_search(stepped, np.zeros(2), 0.25, 0.005)
    assert stepped(found) == 0.0
    assert abs(found[0] - 0.3) < 0.11 and abs(found[1] + 0.7) < 0.06

    def along_a_bound(point: np.ndarray) -> float:
        # As alpha at 1 with a pivoted gamma: the first coordinate's effect is clamped at its bound, and the way
        # down needs both coordinates to move together (either alone does not lower it, at any step).
        clamped = min(point[0] - point[1], 0.0)
        return 10.0 * abs(clamped) + (point[1] - 1.0) ** 2

    found = compass_search(along_a_bound, np.zeros(2), 0.25, 0.005)
    assert abs(found[1] - 1.0) < 0.02 and along_a_bound(found) < 0.01


def test_the_output_fit_moves_along_the_alpha_bound() -> None:
    """A reference brighter than alpha 1 allows (alpha on its bound) and a dark input (median 0.12), where a step
    of gamma about the median moves alpha off the bound: the fit still finds the reference's curve."""
    clean = (torch.from_numpy(_landscape()).permute(2, 0, 1).to(torch.float32) / 255.0) ** 3
    model = output_model(clean, NOISY)
    target = simulated_luminance_quantiles(model, Darkening(1.0, 0.45))
    found = fit_output_darkening(target, model, Darkening(1.0, 0.35))
    assert found.gamma == pytest.approx(0.45, rel=0.05)
    gap = np.abs(simulated_luminance_quantiles(model, found) - target)[1:-1].mean()
    assert gap < 0.3 / 255.0
