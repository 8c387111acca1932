"""The heteroscedastic component (the paper's shot and read noise, shaped by the structure of real sRGB noise:
channel gains, spatial, colour and chroma correlation) and the sRGB model's compression stage.

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch

from darksynth.noise.component_types import (
    COMPRESSION_PATHS,
    FUSED_PATHS,
    STRUCTURED_PATHS,
    NoiseComponent,
    Parameter,
    shapes_neutral,
)
from darksynth.noise.correlated import jpeg_compress_clips, structured_normal
from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_std
from darksynth.noise.statistics import SRGB_STATISTICS

_HETEROSCEDASTIC_PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "shot",
        1,
        "std per sqrt(intensity): variance shot^2 * x",
        1.0,
        (0.0, 0.2),
        log_floor=0.002,
        fast_paths=FUSED_PATHS,
    ),
    Parameter(
        "read",
        1,
        "std, signal-independent",
        1.0,
        (0.0, 0.1),
        log_floor=0.001,
        fast_paths=FUSED_PATHS,
    ),
    # Measured on the real pairs (docs/srgb-noise.md): red and blue noise 1.1-1.5x green's std, Gaussian
    # lengths 0.6-0.9 px, channel correlations 0.2-0.7, different per pair of channels.
    Parameter(
        "channel_gain",
        2,
        "std of red and of blue noise relative to green (shot and read are green's)",
        4.0,
        (0.7, 2.0),
        minimum=0.25,
        neutral=1.0,
        noise_model="srgb",
        fast_paths=STRUCTURED_PATHS,
        since_version=2,
        statistics=SRGB_STATISTICS,
        role="shape",
        training_off_probability=0.2,
    ),
    Parameter(
        "correlation_length",
        1,
        "std in pixels of the Gaussian kernel that correlates the noise spatially (variance kept)",
        8.0,
        (0.0, 2.0),
        noise_model="srgb",
        fast_paths=STRUCTURED_PATHS,
        since_version=2,
        statistics=SRGB_STATISTICS,
        role="shape",
        training_off_probability=0.2,
    ),
    Parameter(
        "channel_correlation",
        3,
        "correlation coefficient of the noise of red-green, green-blue and red-blue",
        0.95,
        (0.0, 0.7),
        minimum=-0.45,
        noise_model="srgb",
        fast_paths=STRUCTURED_PATHS,
        since_version=2,
        statistics=SRGB_STATISTICS,
        role="shape",
        training_off_probability=0.2,
    ),
    # In-camera chroma denoising and 4:2:0 subsampling make colour noise coarser than brightness noise
    # (docs/srgb-noise.md): blotches of colour over a finer grain.
    Parameter(
        "chroma_length",
        1,
        "extra std in pixels of the kernel of the colour part of the noise: sqrt(l^2 + e^2) (0: as the brightness)",
        8.0,
        (0.0, 3.0),
        noise_model="srgb",
        fast_paths=STRUCTURED_PATHS,
        since_version=3,
        statistics=SRGB_STATISTICS,
        role="shape",
        training_off_probability=0.3,
    ),
)


def _draw_heteroscedastic(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    shot, read = values["shot"][..., 0], values["read"][..., 0]
    if shapes_neutral(_HETEROSCEDASTIC_PARAMETERS, values):
        return heteroscedastic_noise(signal, shot, read, generator=generator)
    # A single frame (C, H, W), as streaming passes it, is a clip of one frame.
    shape = signal.shape if signal.dim() >= 4 else (1, *signal.shape)
    unit = structured_unit_noise(shape, values, generator=generator, dtype=signal.dtype).reshape(signal.shape)
    return heteroscedastic_std(signal, shot, read) * unit


def structured_unit_noise(
    shape: Sequence[int],
    values: Mapping[str, torch.Tensor],
    *,
    generator: torch.Generator | None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """The heteroscedastic component's unit noise for clips ``shape`` (*batch, T, C, H, W): channel gains,
    spatial and colour correlation of ``values`` (batched like the clips, or unbatched), before the per-pixel
    std; the compiled sRGB kernel draws the same law from the same factors (:mod:`darksynth.noise.kernel8`)."""
    batch = tuple(shape[: len(shape) - 4])
    return structured_normal(
        shape,
        values["correlation_length"].expand(*batch, 1)[..., 0],
        values["channel_correlation"].expand(*batch, 3),
        values["channel_gain"].expand(*batch, 2),
        generator=generator,
        dtype=dtype,
        chroma_lengths=values["chroma_length"].expand(*batch, 1)[..., 0],
    )


def _heteroscedastic_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # Spatial and channel correlation keep each pixel's variance; only the channel gains change it.
    per_channel = values["shot"][:, :1].square() * channel_means + values["read"][:, :1].square()
    if channel_means.shape[-1] != 3:
        return per_channel
    gains = values["channel_gain"]
    return per_channel * torch.stack([gains[:, 0], torch.ones_like(gains[:, 0]), gains[:, 1]], dim=1).square()


HETEROSCEDASTIC = NoiseComponent(
    name="heteroscedastic",
    parameters=_HETEROSCEDASTIC_PARAMETERS,
    structure="pixel",
    draw=_draw_heteroscedastic,
    variance=_heteroscedastic_variance,
    reference="Foi et al. 2008, Practical Poissonian-Gaussian noise modeling and fitting; "
    "structure: docs/srgb-noise.md",
)


def _draw_compression(
    noisy: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    if noisy.dim() < 4:
        return jpeg_compress_clips(noisy[None], values["compression"][..., 0])[0]
    return jpeg_compress_clips(noisy, values["compression"][..., 0])


COMPRESSION = NoiseComponent(
    name="compression",
    parameters=(
        Parameter(
            "compression",
            1,
            "JPEG compression strength c: quality round(100 (1 - c)), 0 for none",
            0.95,
            (0.0, 0.7),
            noise_model="srgb",
            fast_paths=COMPRESSION_PATHS,
            since_version=2,
            statistics=SRGB_STATISTICS,
            training_off_probability=0.4,
        ),
    ),
    structure="output",
    draw=_draw_compression,
    variance=None,
    reference="JPEG (ITU-T T.81) through Pillow, 4:2:0; docs/srgb-noise.md",
)
