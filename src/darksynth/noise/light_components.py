"""Light beyond noise, declared in the one table: motion blur with the shutter's exposure fraction, camera shake
for single images (structure ``scene``: applied to the clean clip before darkening) and exposure flicker
(structure ``exposure``: a per-frame gain on the darkening).

They are not noise, and the estimation network neither reads nor predicts them (:func:`model_parameters` leaves
their structures out); they are in the table so that one carrier (:class:`~darksynth.noise.values.NoiseValues`)
takes them from ``estimate`` through the profile (its ``light`` section) and ``--jitter``'s draws to the pixel and
the manifest, and the one composer (:mod:`darksynth.noise.simulate`) runs them in their place: scene, darkening
times the gain, then f(v). Their functions are in :mod:`darksynth.light`. Lengths are fractions of the frame (the
flow gives the motion in pixels), so the values mean the same at any size.
"""

from __future__ import annotations

from typing import Any

import torch

from darksynth.light.flicker import FlickerGains, flicker_gains
from darksynth.light.shutter import ShutterStage, scene_blur
from darksynth.noise.component_types import ALL_PATHS, NoiseComponent, Parameter, Role

SHAKE_LENGTH_UNIT = "of the frame's longer side"


def _light_parameter(
    name: str, unit: str, maximum: float, training_range: tuple[float, float], role: Role = "amplitude"
) -> Parameter:
    # What every light parameter shares: it arrived with profile version 5, and every 8-bit path draws a frame's
    # noise whatever its value (the light stage runs before and around them).
    return Parameter(
        name, 1, unit, maximum, training_range, noise_model="spectral", since_version=5, fast_paths=ALL_PATHS, role=role
    )


def _shutter_stage(values: Any, device: torch.device) -> ShutterStage:
    return ShutterStage(
        values.scalar("exposure_fraction"), values.scalar("shake_length"), values.scalar("shake_angle"), device
    )


def _flicker_stage(values: Any, device: torch.device) -> FlickerGains:
    return FlickerGains(values.scalar("flicker"), values.scalar("flicker_correlation"))


SCENE = NoiseComponent(
    name="scene",
    parameters=(
        _light_parameter(
            "exposure_fraction",
            "share of the frame interval the shutter is open (0 instant, 1 a 360-degree shutter): a clip is blurred "
            "along its optical flow over it",
            1.0,
            (0.0, 1.0),
        ),
        _light_parameter(
            "shake_length",
            f"length of a single image's camera-shake path, {SHAKE_LENGTH_UNIT}",
            0.1,
            (0.0, 0.01),
        ),
        _light_parameter(
            "shake_angle",
            "direction of the camera-shake path in degrees, counter-clockwise from the x axis",
            180.0,
            (0.0, 180.0),
            role="shape",
        ),
    ),
    structure="scene",
    draw=scene_blur,
    stream_stage=_shutter_stage,
    variance=None,
    reference="darksynth, docs/motion-blur.md: the shutter's integral along the scene's flow; Brooks & Barron 2019 for "
    "averaging in linear light",
)

FLICKER = NoiseComponent(
    name="flicker",
    parameters=(
        _light_parameter(
            "flicker",
            "std of the per-frame gain on the darkened signal",
            0.5,
            (0.0, 0.1),
        ),
        _light_parameter(
            "flicker_correlation",
            "lag-1 correlation of the per-frame gain (AR(1))",
            0.99,
            (0.0, 0.9),
            role="shape",
        ),
    ),
    structure="exposure",
    draw=flicker_gains,
    stream_stage=_flicker_stage,
    variance=None,
    reference="darksynth, docs/motion-blur.md: mains flicker and auto-exposure hunting as an AR(1) gain",
)
