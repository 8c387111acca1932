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

from collections.abc import Mapping

import numpy as np
import torch

from darksynth.light.flicker import FlickerGains
from darksynth.light.shutter import ShutterStage
from darksynth.noise.component_types import ALL_PATHS, NoiseComponent, Parameter, Role

SHAKE_LENGTH_UNIT = "of the frame's longer side"


def scene_blur(
    clip: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    """The clean clips (*batch, T, C, H, W) as the shutter saw them: a clip of several frames blurred along its
    flow over its exposure fraction, a single frame by its camera shake. Deterministic (``generator`` unused: the
    shake's length and angle are values of their own, drawn within ranges like any other)."""
    flat = clip.reshape(-1, *clip.shape[-4:])
    fractions = values["exposure_fraction"].reshape(-1, 1).expand(flat.shape[0], 1)
    lengths = values["shake_length"].reshape(-1, 1).expand(flat.shape[0], 1)
    angles = values["shake_angle"].reshape(-1, 1).expand(flat.shape[0], 1)
    out = []
    for index, one in enumerate(flat):
        # The stage a stream runs (ClipSynthesizer), here on a whole clip.
        stage = ShutterStage(float(fractions[index, 0]), float(lengths[index, 0]), float(angles[index, 0]), one.device)
        frames = one.float() if one.dtype.is_floating_point else one
        if len(frames) > 1:
            blurred = [shot for frame in frames for shot in stage.push(frame)] + stage.finish()
        else:
            blurred = [stage.image(frames[0])]
        out.append(torch.stack(blurred).to(one.dtype))
    return torch.stack(out).reshape(clip.shape)


def flicker_gains(
    clip: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    """Per-frame gains (*batch, T, 1, 1, 1) on the darkened clips (*batch, T, C, H, W); 1 for single frames."""
    batch = clip.shape[:-4]
    frames = clip.shape[-4]
    stds = values["flicker"].reshape(-1).expand(int(np.prod(batch, dtype=np.int64)))
    correlations = values["flicker_correlation"].reshape(-1).expand(stds.shape[0])
    gains = torch.ones(stds.shape[0], frames, dtype=torch.float64)
    if frames > 1:
        for index in range(stds.shape[0]):
            gains[index] = FlickerGains(float(stds[index]), float(correlations[index])).sequence(frames, generator)
    return gains.reshape(*batch, frames, 1, 1, 1).to(device=clip.device, dtype=clip.dtype)


def _light_parameter(
    name: str, unit: str, maximum: float, training_range: tuple[float, float], role: Role = "amplitude"
) -> Parameter:
    # What every light parameter shares: it arrived with profile version 5, and every 8-bit path draws a frame's
    # noise whatever its value (the light stage runs before and around them).
    return Parameter(
        name, 1, unit, maximum, training_range, noise_model="spectral", since_version=5, fast_paths=ALL_PATHS, role=role
    )


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
    variance=None,
    reference="darksynth (issue 25): the shutter's integral along the scene's flow; Brooks & Barron 2019 for "
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
    variance=None,
    reference="darksynth (issue 25): mains flicker and auto-exposure hunting as an AR(1) gain",
)
