"""The measured-spectrum model's component: noise with the reference's spectrum per octave, its level curve per
channel and its correlation from frame to frame (docs/spectral-noise.md).

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch

from darksynth.noise.component_types import ALL_8BIT_PATHS, SPECTRAL_PATHS, NoiseComponent, Parameter
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES, level_std, octave_covariances, spectral_clip_noise
from darksynth.noise.texture import texture_modulation

TEXTURE_SCALE_NEUTRAL = 0.01
"""``texture_scale`` where a profile has none: a detail level of 2.5 8-bit levels (it changes nothing while
``texture_gain`` is 0)."""

SPECTRUM_REPLACES = ("shot", "read", "channel_gain", "correlation_length", "channel_correlation", "chroma_length")
"""The heteroscedastic parameters the spectral model takes over: its level curve holds the level (shot, read, the
channel gains) and its octaves the structure (the correlation and colour lengths, the channel correlation), so a
clip given spectral values has these neutral. The column components are not among them."""

# The measured-spectrum model (docs/spectral-noise.md): real sRGB noise has a fine brightness grain over coarse
# colour mottle (colour 8-75x white noise's power at 16-64 px on the real pairs) and, in video, persists from
# frame to frame. Its structure is a covariance of brightness and colour per octave, its level a curve per channel.
_SPECTRAL_PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "level_curve",
        3 * len(LEVEL_KNOTS),
        "noise std of red, green and blue (8 values each) at the intensities "
        + ", ".join(f"{k:.3f}" for k in LEVEL_KNOTS)
        + ", linear between them",
        1.0,
        (0.0, 0.08),
        noise_model="spectral",
        fast_paths=SPECTRAL_PATHS,
        since_version=4,
    ),
    Parameter(
        "octave_power",
        3 * OCTAVES,
        "per octave (finest first: wavelengths 2.8, 5.7, 11, 23, 45, 90 px) the power of brightness, colour "
        "(red-blue) and colour (magenta-green) noise relative to white noise (1: white)",
        1.0e4,
        (0.2, 20.0),
        neutral=1.0,
        noise_model="spectral",
        fast_paths=SPECTRAL_PATHS,
        since_version=4,
        role="shape",
    ),
    Parameter(
        "octave_correlation",
        3 * OCTAVES,
        "per octave the correlation of brightness-colour1, brightness-colour2 and colour1-colour2 noise",
        0.99,
        (-0.3, 0.3),
        minimum=-0.99,
        noise_model="spectral",
        fast_paths=SPECTRAL_PATHS,
        since_version=4,
        role="shape",
    ),
    Parameter(
        "temporal_correlation",
        OCTAVES,
        "per octave the correlation of a frame's noise with the previous frame's (AR(1); 0 for independent frames)",
        0.99,
        (0.0, 0.9),
        noise_model="spectral",
        fast_paths=SPECTRAL_PATHS,
        since_version=4,
        role="shape",
        training_off_probability=0.5,
    ),
    # Noise that follows texture (noise/texture.py): in-camera denoising and JPEG flatten noise in flat regions and
    # keep it on texture. The level curve describes flat regions; the std is multiplied by (1 + d / scale) ** gain.
    # They are the spectral model's (noise_model "spectral"), so the shipped sRGB network neither reads nor predicts
    # them; the clean-aided fit sets both. The gain leaves the fused paths (the 8-bit spectral pass draws it); a scale
    # alone changes nothing.
    Parameter(
        "texture_gain",
        1,
        "exponent t of the factor (1 + d / texture_scale) ** t on the noise std at local detail d (0: no effect)",
        4.0,
        (0.0, 1.5),
        noise_model="spectral",
        fast_paths=SPECTRAL_PATHS,
        since_version=6,
        role="shape",
        training_off_probability=0.5,
    ),
    Parameter(
        "texture_scale",
        1,
        "local detail d0 on the [0, 1] scale at which the texture factor is 2 ** texture_gain (RMS of the luminance "
        "minus its 1.5-px blur, over a 3-px window)",
        1.0,
        (0.002, 0.05),
        minimum=1.0e-4,
        neutral=TEXTURE_SCALE_NEUTRAL,
        noise_model="spectral",
        since_version=6,
        role="shape",
        fast_paths=ALL_8BIT_PATHS,
    ),
)


def spectral_clips(
    signal: torch.Tensor,
    values: Mapping[str, torch.Tensor],
    generator: torch.Generator | None,
    held: dict[str, Any] | None = None,
) -> torch.Tensor:
    """The spectral noise of ``signal`` (*batch, T, C, H, W), or a single frame (C, H, W), with ``values`` batched
    like it; ``held``: a stream's state (see :func:`darksynth.noise.spectral.spectral_clip_noise`). The component's
    draw, and its draw in a stream with ``held``."""
    if generator is None:
        generator = torch.default_generator
    # A single frame (C, H, W), as streaming passes it, is a clip of one frame.
    clips = signal if signal.dim() >= 4 else signal[None]
    batch = tuple(clips.shape[:-4])
    flat = clips.reshape(-1, *clips.shape[-4:])
    names = ("level_curve", "octave_power", "octave_correlation", "temporal_correlation")
    flat_values = [
        values[name].expand(*batch, values[name].shape[-1]).reshape(-1, values[name].shape[-1]) for name in names
    ]
    gains, scales = (values[name].expand(*batch, 1).reshape(-1) for name in ("texture_gain", "texture_scale"))
    noise = []
    for index, clip in enumerate(flat):
        curve, power, correlation, temporal = (v[index] for v in flat_values)
        drawn = spectral_clip_noise(
            clip,
            curve,
            octave_covariances(power, correlation),
            temporal,
            generator=generator,
            # A stream is one clip; a batch of clips never shares one clip's state.
            state=held if flat.shape[0] == 1 else None,
        )
        gain = float(gains[index])
        # At gain 0 the factor is 1: not computed, so a profile without texture draws the same bits as before.
        if gain != 0.0:
            drawn = drawn * texture_modulation(clip, gain, float(scales[index]))
        noise.append(drawn)
    return torch.stack(noise).reshape(signal.shape)


def _spectral_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # The unit noise has unit variance per channel; the level curve at each channel's mean gives its std.
    rows = [
        level_std(means[:, None, None], curve)
        for means, curve in zip(channel_means, values["level_curve"], strict=True)
    ]
    return torch.stack(rows)[..., 0, 0].square()


SPECTRAL = NoiseComponent(
    name="spectral",
    parameters=_SPECTRAL_PARAMETERS,
    structure="pixel",
    draw=spectral_clips,
    draw_in_stream=spectral_clips,
    variance=_spectral_variance,
    reference="Lebrun, Colom and Morel 2015, The Noise Clinic; Norkin and Birkbeck 2018, AV1 film grain; "
    "docs/spectral-noise.md",
)
