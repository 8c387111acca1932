"""Version-2 and version-3 profiles drawn as the spectral model: against the figures their own drawing left
(tests/noise/retired_srgb_drawing.json), and against the translation's own equations."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
import torch

from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES
from darksynth.noise.structure_translation import (
    _band_geometry,
    _band_powers,
    octave_densities,
    spectral_tensors,
    valid_channel_correlation,
)
from darksynth.noise.values import NoiseValues, stacked_values
from darksynth.profile import Profile, parse_profile
from darksynth.recipe import draw_clip_parameters
from darksynth.synthesize import synthesize
from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[2]

TOLERANCE = 0.10
"""What the translated drawing is held to: 10 % of each recorded figure."""

JPEG_FINEST_BRIGHTNESS = 0.20
"""Beyond :data:`TOLERANCE`, what the finest brightness band (1.4-4 px) of a JPEG-compressed profile may lose: the
spectral model holds its finest node's density up to the frequency square's corners, where a Gaussian kernel keeps
falling, so more of the translated noise lies where JPEG quantises hardest (23 % less power there after quality 80
for a 0.6 px kernel; within 2 % without JPEG)."""


def _check_script() -> ModuleType:
    return load_script(ROOT / "scripts" / "noise" / "translated_profile_check.py")


def band_bound(values: dict[str, object]) -> float:
    """The largest relative band error that the spectral model's node spacing leaves for a profile's kernels (its
    correlation length and, with a colour length, sqrt(l^2 + e^2)): the translation's own residual."""
    length = float(values.get("correlation_length", 0.0))  # type: ignore[arg-type]
    lengths = [length, math.hypot(length, float(values.get("chroma_length", 0.0)))]  # type: ignore[arg-type]
    _, hats = _band_geometry()
    return max(
        float(np.abs(hats @ np.asarray(octave_densities(px)) / _band_powers(px) - 1.0).max()) if px > 0 else 0.0
        for px in lengths
    )


def test_the_translated_drawing_matches_the_recorded_version_3_figures() -> None:
    """Per-channel std within 10 % everywhere. Bands within 10 % where the spectral model can hold the kernel's
    spectrum (kernels under 0.8 px); where it cannot, within 10 % plus the bound its node spacing sets, which
    :func:`band_bound` computes from the translation (up to 27 % for kernels of 1-3 px: a Gaussian spectrum falls
    faster within an octave than the model's density, linear in log frequency between nodes an octave apart); and
    the finest brightness band of a JPEG profile within :data:`JPEG_FINEST_BRIGHTNESS` more."""
    check = _check_script()
    record = json.loads((ROOT / "tests" / "noise" / "retired_srgb_drawing.json").read_text())
    assert record["profiles"] == check.PROFILES
    bounded = []
    for index, (name, values) in enumerate(check.PROFILES.items()):
        ratios = check.ratios(check.measure(values, 5000 + 1000 * index), record["figures"][name])
        assert np.all(np.abs(np.asarray(ratios["channel_std"]) - 1.0) < TOLERANCE), (name, ratios)
        bound = band_bound(values)
        bounded.append(bound > 0.01)
        for key in ("brightness_bands", "colour_bands"):
            allowed = np.full(5, TOLERANCE + bound)
            if key == "brightness_bands" and values.get("compression", 0.0):
                allowed[0] += JPEG_FINEST_BRIGHTNESS
            assert np.all(np.abs(np.asarray(ratios[key]) - 1.0) < allowed), (name, key, bound, ratios)
    # The exception is the kernels' spectra, not the whole record: the plain and short-kernel profiles hold 10 %.
    assert not all(bounded)


def test_the_level_curve_is_the_channel_gains_times_the_heteroscedastic_std_at_every_knot() -> None:
    values = NoiseValues.from_values({"shot": 0.08, "read": 0.01, "channel_gain": [1.5, 0.7]})
    curve = spectral_tensors(values)["level_curve"].reshape(3, len(LEVEL_KNOTS))
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64)
    std = (0.08**2 * knots + 0.01**2).sqrt()
    assert torch.allclose(curve, torch.stack([1.5 * std, std, 0.7 * std]))


def test_white_noise_and_short_kernels_keep_their_band_powers() -> None:
    assert octave_densities(0.0) == (1.0,) * OCTAVES
    _, hats = _band_geometry()
    for length in (0.2, 0.5, 0.75):
        model = hats @ np.asarray(octave_densities(length))
        assert np.allclose(model, _band_powers(length), rtol=1e-3), length


def test_the_translation_moves_the_structure_into_the_spectral_values_and_leaves_white_clips_alone() -> None:
    white = {"shot": 0.05, "read": 0.01, "quantization": 0.004, "compression": 0.3}
    structured = white | {"correlation_length": 1.2, "chroma_length": 2.0, "channel_correlation": [0.5, 0.4, 0.3]}
    batch = stacked_values([NoiseValues.from_values(white), NoiseValues.from_values(structured)])
    translated = NoiseValues(spectral_tensors(batch))
    assert translated.clip(0) == batch.clip(0)
    clip = translated.clip(1)
    assert clip.scalar("shot") == 0.0 and clip.scalar("read") == 0.0
    assert clip.scalar("correlation_length") == 0.0 and clip.scalar("chroma_length") == 0.0
    assert clip.scalar("quantization") == 0.004 and clip.scalar("compression") == 0.3
    power = clip["octave_power"].reshape(OCTAVES, 3)
    # Coarse colour blotches over a finer brightness grain: the colour part's power peaks at a coarser octave.
    assert int(power[:, 1].argmax()) > int(power[:, 0].argmax()) or float(power[-1, 1]) > float(power[-1, 0])


def test_a_structure_beside_a_spectral_curve_is_refused() -> None:
    values = NoiseValues.from_values({"correlation_length": 1.0, "level_curve": [0.01] * 24})
    with pytest.raises(ValueError, match="both an sRGB structure"):
        spectral_tensors(values)


def test_inconsistent_channel_correlations_are_made_valid() -> None:
    consistent = valid_channel_correlation([0.5, 0.3, 0.6])
    assert consistent[0, 1] == 0.5 and consistent[1, 2] == 0.3 and consistent[0, 2] == 0.6
    repaired = valid_channel_correlation([0.9, 0.9, -0.45])
    assert torch.allclose(repaired.diagonal(), torch.ones(3, dtype=torch.float64))
    assert float(torch.linalg.eigvalsh(repaired).min()) > 0


VERSION_3 = {
    "format": "darksynth-profile",
    "version": 3,
    "noise": {
        "shot": 0.06,
        "read": 0.01,
        "quantization": 0.0,
        "banding": 0.0,
        "temporal_banding": 0.0,
        "periodic": [0.0, 0.0, 0.0],
        "channel_gain": [1.3, 1.1],
        "correlation_length": 0.9,
        "channel_correlation": [0.5, 0.4, 0.3],
        "chroma_length": 2.0,
        "compression": 0.2,
    },
    "darkening": {"alpha": 0.3, "gamma": 0.8},
    "ranges": {"correlation_length": [0.2, 1.8]},
}


def test_a_version_3_profile_loads_draws_and_records_its_spectral_values_with_jitter() -> None:
    profile = parse_profile(VERSION_3)
    generator = torch.Generator().manual_seed(0)
    drawn = [draw_clip_parameters(profile, generator=generator) for _ in range(2)]
    # The length is drawn within its range first, then translated: two clips, two spectra.
    assert not torch.equal(drawn[0].noise["octave_power"], drawn[1].noise["octave_power"])
    record = drawn[0].to_json()["noise"]
    assert record["correlation_length"] == 0.0 and record["shot"] == 0.0
    assert record["compression"] == 0.2 and max(record["level_curve"]) > 0.0  # type: ignore[arg-type]
    clean = torch.full((3, 64, 64), 0.5)
    result = synthesize(clean, profile, generator=torch.Generator().manual_seed(1))
    assert isinstance(result.image, torch.Tensor) and result.image.shape == clean.shape
    assert float((result.image - 0.3 * 0.5 ** (1 / 0.8)).std()) > 0.01


def test_the_composer_draws_untranslated_values_as_their_translation() -> None:
    values = NoiseValues.from_values({"shot": 0.05, "read": 0.01, "correlation_length": 1.0, "channel_gain": [1.2, 1]})
    signal = torch.full((1, 1, 3, 48, 64), 0.2, dtype=torch.float64)
    direct = add_noise(signal, values, generator=torch.Generator().manual_seed(3))
    translated = add_noise(signal, NoiseValues(spectral_tensors(values)), generator=torch.Generator().manual_seed(3))
    assert torch.equal(direct, translated)


def test_a_profile_without_structure_draws_exactly_the_papers_white_noise() -> None:
    profile = Profile(noise=NoiseValues.from_values({"shot": 0.06, "read": 0.012}))
    parameters = draw_clip_parameters(profile, darkening=None)
    assert parameters.noise == profile.noise


def test_the_structures_neutral_values_are_the_tables() -> None:
    from darksynth.noise.components import noise_parameter
    from darksynth.noise.structure_translation import STRUCTURE_NEUTRAL

    assert {name: noise_parameter(name).neutral for name in STRUCTURE_NEUTRAL} == STRUCTURE_NEUTRAL
