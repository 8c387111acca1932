"""The heteroscedastic component: the paper's shot and read noise, and the sRGB structure that version-2 and
version-3 profiles (and the estimation network's vector) give it: channel gains, spatial, colour and chroma
correlation. Shot and read alone draw white noise; with a structure the noise is drawn as the spectral model
(:mod:`darksynth.noise.structure_translation`).

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch

from darksynth.noise.component_types import ALL_8BIT_PATHS, NoiseComponent, Parameter, shapes_neutral
from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_variance
from darksynth.noise.spectral_components import spectral_clips
from darksynth.noise.structure_translation import spectral_tensors

_HETEROSCEDASTIC_PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "shot",
        1,
        "std per sqrt(intensity): variance shot^2 * x",
        1.0,
        (0.0, 0.2),
        log_floor=0.002,
        fast_paths=ALL_8BIT_PATHS,
    ),
    Parameter(
        "read",
        1,
        "std, signal-independent",
        1.0,
        (0.0, 0.1),
        log_floor=0.001,
        fast_paths=ALL_8BIT_PATHS,
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
        since_version=2,
        statistics="multiscale",
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
        since_version=2,
        statistics="multiscale",
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
        since_version=2,
        statistics="multiscale",
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
        since_version=3,
        statistics="multiscale",
        role="shape",
        training_off_probability=0.3,
    ),
)


def _draw_heteroscedastic(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    if shapes_neutral(_HETEROSCEDASTIC_PARAMETERS, values):
        return heteroscedastic_noise(signal, values["shot"][..., 0], values["read"][..., 0], generator=generator)
    # Clip parameters come translated (darksynth.recipe, the training batches); values given to the composer
    # directly are translated here, so that no route draws the structure any other way.
    spectral = spectral_tensors(values)
    noise = spectral_clips(signal, spectral, generator, None)
    shot, read = spectral["shot"][..., 0], spectral["read"][..., 0]
    if bool((shot != 0.0).any() or (read != 0.0).any()):
        # A batch that mixes structured clips with white ones.
        noise = noise + heteroscedastic_noise(signal, shot, read, generator=generator)
    return noise


def _heteroscedastic_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # Spatial and channel correlation keep each pixel's variance; only the channel gains change it.
    per_channel = values["shot"][:, :1].square() * channel_means + values["read"][:, :1].square()
    if channel_means.shape[-1] != 3:
        return per_channel
    gains = values["channel_gain"]
    return per_channel * torch.stack([gains[:, 0], torch.ones_like(gains[:, 0]), gains[:, 1]], dim=1).square()


def _white_heteroscedastic_variance(values: Mapping[str, torch.Tensor], signal: torch.Tensor) -> torch.Tensor:
    # The white case, shot and read alone: what the fused kernel covers (the shape parameters declare no fast path).
    return heteroscedastic_variance(signal, values["shot"][..., 0], values["read"][..., 0])


HETEROSCEDASTIC = NoiseComponent(
    name="heteroscedastic",
    parameters=_HETEROSCEDASTIC_PARAMETERS,
    structure="pixel",
    draw=_draw_heteroscedastic,
    variance=_heteroscedastic_variance,
    white_variance=_white_heteroscedastic_variance,
    reference="Foi et al. 2008, Practical Poissonian-Gaussian noise modeling and fitting; "
    "structure: docs/srgb-noise.md (retired drawing), docs/spectral-noise.md",
)
