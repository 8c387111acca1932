"""The noise components of f(v), declared as data.

Every quantity of the noise model lives in :data:`NOISE_COMPONENTS`: a component's parameters (name, number
of values, unit, valid bound, training range, the profile version it arrived in, the estimator statistics that
reveal it, the fast paths that can draw it) and the pure functions that draw it and give its term of the mean
noise variance. The profile schema, the carrier of values (:mod:`darksynth.noise.values`), the estimation
network's vector and statistics, the samplers, the composer and the fused kernel's choice all read this table
through the functions below (never a copy of it), so a new component is added here, next to its function, and
nowhere else; ``tests/noise/test_new_component.py`` declares one inside a test and runs it end to end.

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import torch

from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.correlated import jpeg_compress_clips, structured_normal
from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_std
from darksynth.noise.periodic import periodic_noise
from darksynth.noise.quantization import quantization_noise
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES, level_std, octave_covariances, spectral_clip_noise
from darksynth.noise.statistics import PAPER_STATISTICS, SRGB_STATISTICS, EstimatorStatistics

Structure = Literal["pixel", "column", "output"]
"""How a component varies in the frame.

``pixel``: a new value at every pixel of every frame. ``column``: one value per channel and column, the same
down the whole column, so the component can be drawn as a (..., T or 1, C, 1, W) row and broadcast.
``output``: not added but applied to the finished noisy image (after summing and clipping), like a camera's
compression; its ``draw`` returns the transformed image instead of noise.
"""

NoiseModel = Literal["paper", "srgb", "spectral"]
"""``paper``: the paper's five components (profile version 1, DEN model version 1). ``srgb``: those plus the
structure of real sRGB noise (per-channel gains, spatial and cross-channel correlation, JPEG), measured in
docs/srgb-noise.md (profile version 2, DEN model version 2). ``spectral``: those plus the measured spectrum
(per-octave colour covariances, level curves, temporal correlation; docs/spectral-noise.md, profile version 4),
estimated by measurement on the reference rather than by the network."""

Role = Literal["amplitude", "shape"]
"""``amplitude``: the component draws nothing when all its amplitude parameters are neutral. ``shape``: shapes
what the amplitudes draw (a correlation length, a channel gain) and draws nothing by itself."""

FastPath = Literal["fused_8bit", "structured_8bit", "spectral_8bit"]
"""A specialised implementation of part of f(v). ``fused_8bit``: :mod:`darksynth.noise.kernel8`, one pass over
an 8-bit frame that draws white heteroscedastic and quantization noise and adds the column components.
``structured_8bit``: the same pass fed with the sRGB model's structured unit noise (channel gains, spatial and
colour correlation, drawn by the composer's own function) instead of its counter-based normal, then the
compression stage: the compiled path of an sRGB profile. ``spectral_8bit``: :mod:`darksynth.noise.spectral_8bit`,
the spectral model's unit noise scaled by the level curve's std read from a table of the 256 input levels, then
the composer's quantization, column components and compression: the default path of a profile from ``estimate``."""

_FUSED: frozenset[FastPath] = frozenset({"fused_8bit", "structured_8bit"})
"""Both 8-bit kernels: the levels (shot, read), quantization, which they draw themselves, and the column components,
which the composer draws and they add."""

_STRUCTURED: frozenset[FastPath] = frozenset({"structured_8bit"})
"""The sRGB structure (gains, spatial and colour correlation): the structured path only."""

_SPECTRAL: frozenset[FastPath] = frozenset({"spectral_8bit"})
"""The spectrum and the level curve: the spectral path only."""

_ALL_8BIT: frozenset[FastPath] = _FUSED | _SPECTRAL
"""Quantization and the column components, which every 8-bit path draws as the composer does."""

_COMPRESSION: frozenset[FastPath] = _STRUCTURED | _SPECTRAL
"""The compression stage, which the structured and the spectral path run after their per-pixel pass."""

DrawFunction = Callable[[torch.Tensor, Mapping[str, torch.Tensor], torch.Generator | None], torch.Tensor]
"""``draw(signal, values, generator) -> noise``: ``signal`` is the darkened clean clip (..., T, C, H, W),
``values`` maps each of the component's parameter names to a tensor shaped (*batch, size), where *batch are
the clip's leading dimensions. The noise broadcasts against ``signal``."""

StreamDrawFunction = Callable[
    [torch.Tensor, Mapping[str, torch.Tensor], torch.Generator | None, dict[str, Any]], torch.Tensor
]
"""``draw_in_stream(signal, values, generator, held) -> noise`` for a component whose frames depend on the frames
before them (temporal correlation): ``held`` is the stream's dict of per-clip objects, the same for every frame
of a clip, where the component keeps its state."""

VarianceFunction = Callable[[Mapping[str, torch.Tensor], torch.Tensor], torch.Tensor]
"""``variance(values, channel_means) -> (B, C)``: the component's contribution to the mean noise variance of
clips whose channels have the mean levels ``channel_means`` (B, C), with ``values`` shaped (B, size)."""


@dataclass(frozen=True)
class Parameter:
    """One named entry of the noise parameter vector v.

    Attributes:
        name: key in the profile's ``noise`` object.
        size: number of values (1 is a JSON number, more is a JSON list of that length).
        unit: what the value measures, for documentation and error messages.
        maximum: largest valid value; every value must lie in [0, maximum].
        training_range: the range drawn from when training the estimator or jittering without a profile range.
        minimum: smallest valid value.
        neutral: the value that changes nothing (0 for most, 1 for a gain): what a profile of an older version
            or a model without the parameter means.
        noise_model: the first noise model that has the parameter (see :data:`NoiseModel`).
        since_version: the profile version the parameter arrived in. Parameters of version 1 are required in
            every profile; later ones are optional (neutral when absent) and refused in older documents.
        role: see :data:`Role`.
        training_off_probability: when set, training sets this parameter alone to its neutral value with this
            probability (shape parameters, so the estimator also sees white, uncompressed noise).
        log_floor: for a noise level spanning decades: with a log level prior, training draws it log-uniformly
            over [log_floor, training high] and the estimator predicts its logarithm (values below the floor
            read as the floor), so a level of 0.005 is estimated as precisely, relatively, as one of 0.05.
            This is also the scale of the estimator's output head for the parameter.
        statistics: the fixed statistics that reveal the parameter to the estimator; the head of a noise model
            reads those of all its parameters (:func:`model_statistics`).
        fast_paths: the fast paths that draw this parameter at any value; every other fast path is taken only
            while the parameter is neutral (:meth:`darksynth.noise.values.NoiseValues.covered_by`).
    """

    name: str
    size: int
    unit: str
    maximum: float
    training_range: tuple[float, float]
    minimum: float = 0.0
    neutral: float = 0.0
    noise_model: NoiseModel = "paper"
    since_version: int = 1
    role: Role = "amplitude"
    training_off_probability: float | None = None
    log_floor: float | None = None
    statistics: EstimatorStatistics = PAPER_STATISTICS
    fast_paths: frozenset[FastPath] = frozenset()


@dataclass(frozen=True)
class NoiseComponent:
    """One term of f(v) with the parameters it reads, the function that draws it and its variance."""

    name: str
    parameters: tuple[Parameter, ...]
    structure: Structure
    draw: DrawFunction
    reference: str
    variance: VarianceFunction | None
    """Its term of the mean noise variance (:func:`darksynth.noise.level.mean_noise_variance`); None for an
    output stage, which transforms the image instead of adding to it."""
    per_clip: bool = False
    """True when one draw is held over all frames of a clip: a frame-by-frame stream draws it once."""
    draw_in_stream: StreamDrawFunction | None = None
    """How a frame-by-frame stream draws it, for a component with memory from frame to frame; None: ``draw``."""


def shapes_neutral(parameters: tuple[Parameter, ...], values: Mapping[str, torch.Tensor]) -> bool:
    """Whether none of ``parameters``' shape parameters is set: what they shape is the paper's white noise."""
    return all(bool((values[p.name] == p.neutral).all()) for p in parameters if p.role == "shape")


_HETEROSCEDASTIC_PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "shot",
        1,
        "std per sqrt(intensity): variance shot^2 * x",
        1.0,
        (0.0, 0.2),
        log_floor=0.002,
        fast_paths=_FUSED,
    ),
    Parameter(
        "read",
        1,
        "std, signal-independent",
        1.0,
        (0.0, 0.1),
        log_floor=0.001,
        fast_paths=_FUSED,
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
        fast_paths=_STRUCTURED,
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
        fast_paths=_STRUCTURED,
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
        fast_paths=_STRUCTURED,
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
        fast_paths=_STRUCTURED,
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


def _draw_compression(
    noisy: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    if noisy.dim() < 4:
        return jpeg_compress_clips(noisy[None], values["compression"][..., 0])[0]
    return jpeg_compress_clips(noisy, values["compression"][..., 0])


def _draw_quantization(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return quantization_noise(signal.shape, values["quantization"][..., 0], generator=generator, device=signal.device)


def _draw_banding(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return banding_noise(signal.shape, values["banding"][..., 0], generator=generator, device=signal.device)


def _draw_temporal_banding(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return temporal_banding_noise(
        signal.shape, values["temporal_banding"][..., 0], generator=generator, device=signal.device
    )


def _draw_periodic(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return periodic_noise(signal.shape, values["periodic"], generator=generator, device=signal.device)


def _heteroscedastic_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # Spatial and channel correlation keep each pixel's variance; only the channel gains change it.
    per_channel = values["shot"][:, :1].square() * channel_means + values["read"][:, :1].square()
    if channel_means.shape[-1] != 3:
        return per_channel
    gains = values["channel_gain"]
    return per_channel * torch.stack([gains[:, 0], torch.ones_like(gains[:, 0]), gains[:, 1]], dim=1).square()


def _quantization_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # U(0, q) has variance q^2 / 12 (its mean q / 2 is a shift of the level, not noise).
    return (values["quantization"][:, :1].square() / 12.0).expand_as(channel_means)


def _column_variance(name: str) -> VarianceFunction:
    def variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
        # Each periodic mode has unit mean square over the columns, so its variance is its sigma^2 too.
        return values[name].square().sum(dim=-1, keepdim=True).expand_as(channel_means)

    return variance


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
        fast_paths=_SPECTRAL,
        since_version=4,
        statistics=SRGB_STATISTICS,
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
        fast_paths=_SPECTRAL,
        since_version=4,
        statistics=SRGB_STATISTICS,
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
        fast_paths=_SPECTRAL,
        since_version=4,
        statistics=SRGB_STATISTICS,
        role="shape",
    ),
    Parameter(
        "temporal_correlation",
        OCTAVES,
        "per octave the correlation of a frame's noise with the previous frame's (AR(1); 0 for independent frames)",
        0.99,
        (0.0, 0.9),
        noise_model="spectral",
        fast_paths=_SPECTRAL,
        since_version=4,
        statistics=SRGB_STATISTICS,
        role="shape",
        training_off_probability=0.5,
    ),
)


def _spectral_clips(
    signal: torch.Tensor,
    values: Mapping[str, torch.Tensor],
    generator: torch.Generator | None,
    held: dict[str, Any] | None,
) -> torch.Tensor:
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
    noise = []
    for index, clip in enumerate(flat):
        curve, power, correlation, temporal = (v[index] for v in flat_values)
        noise.append(
            spectral_clip_noise(
                clip,
                curve,
                octave_covariances(power, correlation),
                temporal,
                generator=generator,
                # A stream is one clip; a batch of clips never shares one clip's state.
                state=held if flat.shape[0] == 1 else None,
            )
        )
    return torch.stack(noise).reshape(signal.shape)


def _draw_spectral(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return _spectral_clips(signal, values, generator, None)


def _draw_spectral_in_stream(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None, held: dict[str, Any]
) -> torch.Tensor:
    return _spectral_clips(signal, values, generator, held)


def _spectral_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # The unit noise has unit variance per channel; the level curve at each channel's mean gives its std.
    rows = [
        level_std(means[:, None, None], curve)
        for means, curve in zip(channel_means, values["level_curve"], strict=True)
    ]
    return torch.stack(rows)[..., 0, 0].square()


# The training ranges cover real sRGB low-light noise: at mid-grey (x = 0.5) shot 0.2 alone gives a std of
# 0.14 of full scale, and read noise adds up to 0.1 at black.
NOISE_COMPONENTS: tuple[NoiseComponent, ...] = (
    NoiseComponent(
        name="heteroscedastic",
        parameters=_HETEROSCEDASTIC_PARAMETERS,
        structure="pixel",
        draw=_draw_heteroscedastic,
        variance=_heteroscedastic_variance,
        reference="Foi et al. 2008, Practical Poissonian-Gaussian noise modeling and fitting; "
        "structure: docs/srgb-noise.md",
    ),
    NoiseComponent(
        name="spectral",
        parameters=_SPECTRAL_PARAMETERS,
        structure="pixel",
        draw=_draw_spectral,
        draw_in_stream=_draw_spectral_in_stream,
        variance=_spectral_variance,
        reference="Lebrun, Colom and Morel 2015, The Noise Clinic; Norkin and Birkbeck 2018, AV1 film grain; "
        "docs/spectral-noise.md",
    ),
    NoiseComponent(
        name="quantization",
        parameters=(
            Parameter(
                "quantization",
                1,
                "width of the uniform interval U(0, q)",
                1.0,
                (0.0, 0.02),
                log_floor=0.0002,
                fast_paths=_ALL_8BIT,
            ),
        ),
        structure="pixel",
        draw=_draw_quantization,
        variance=_quantization_variance,
        reference="Lin, Morris et al. 2025, eq. of f(v); Monakhova et al. 2022",
    ),
    NoiseComponent(
        name="banding",
        parameters=(
            Parameter(
                "banding",
                1,
                "std of a per-frame column offset",
                1.0,
                (0.0, 0.03),
                log_floor=0.0003,
                fast_paths=_ALL_8BIT,
            ),
        ),
        structure="column",
        draw=_draw_banding,
        variance=_column_variance("banding"),
        reference="Monakhova et al. 2022, Dancing under the stars (row/column noise)",
    ),
    NoiseComponent(
        name="temporal_banding",
        parameters=(
            Parameter(
                "temporal_banding",
                1,
                "std of a per-clip column offset",
                1.0,
                (0.0, 0.03),
                log_floor=0.0003,
                fast_paths=_ALL_8BIT,
            ),
        ),
        structure="column",
        draw=_draw_temporal_banding,
        variance=_column_variance("temporal_banding"),
        reference="Monakhova et al. 2022, Dancing under the stars (fixed-pattern noise)",
        per_clip=True,
    ),
    NoiseComponent(
        name="periodic",
        parameters=(
            Parameter(
                "periodic",
                3,
                "std of the DC, cosine and sine column patterns",
                1.0,
                (0.0, 0.02),
                log_floor=0.0002,
                fast_paths=_ALL_8BIT,
            ),
        ),
        structure="column",
        draw=_draw_periodic,
        variance=_column_variance("periodic"),
        reference="Monakhova et al. 2022, Dancing under the stars (periodic noise)",
    ),
    NoiseComponent(
        name="compression",
        parameters=(
            Parameter(
                "compression",
                1,
                "JPEG compression strength c: quality round(100 (1 - c)), 0 for none",
                0.95,
                (0.0, 0.7),
                noise_model="srgb",
                fast_paths=_COMPRESSION,
                since_version=2,
                statistics=SRGB_STATISTICS,
                training_off_probability=0.4,
            ),
        ),
        structure="output",
        draw=_draw_compression,
        variance=None,
        reference="JPEG (ITU-T T.81) through Pillow, 4:2:0; docs/srgb-noise.md",
    ),
)
"""The table. Read it through the functions below, which look it up at each call, so that a component
declared here (or, in a test, added to it) is seen everywhere."""

NOISE_MODELS: tuple[NoiseModel, ...] = ("paper", "srgb", "spectral")


def noise_components() -> tuple[NoiseComponent, ...]:
    """Every component, in table order."""
    return NOISE_COMPONENTS


def noise_parameters() -> tuple[Parameter, ...]:
    """Every parameter, in table order: the full v of the ``spectral`` model."""
    return tuple(p for c in NOISE_COMPONENTS for p in c.parameters)


def noise_parameter_names() -> tuple[str, ...]:
    return tuple(p.name for p in noise_parameters())


def model_parameters(noise_model: NoiseModel = "srgb", version: int | None = None) -> tuple[Parameter, ...]:
    """The parameters of one noise model, in table order: ``paper`` is shot, read, quantization, banding,
    temporal_banding, periodic (3), the paper's v of 8 values; ``srgb`` is every parameter.

    ``version``: only the parameters that had arrived by that table (profile) version, as an estimator trained
    then predicts them (None: the table as it is now)."""
    if noise_model not in NOISE_MODELS:
        raise ValueError(f"unknown noise model {noise_model!r}; known: {', '.join(NOISE_MODELS)}")
    last = NOISE_MODELS.index(noise_model)
    return tuple(
        p
        for p in noise_parameters()
        if NOISE_MODELS.index(p.noise_model) <= last and (version is None or p.since_version <= version)
    )


def vector_size(noise_model: NoiseModel = "srgb", version: int | None = None) -> int:
    """Length of the flat v of one noise model (8 for ``paper``), at a table version (None: now)."""
    return sum(p.size for p in model_parameters(noise_model, version))


def model_statistics(noise_model: NoiseModel = "srgb", version: int | None = None) -> tuple[EstimatorStatistics, ...]:
    """The statistics the estimator of a noise model reads: those its parameters name, in table order."""
    found: list[EstimatorStatistics] = []
    for parameter in model_parameters(noise_model, version):
        if parameter.statistics not in found:
            found.append(parameter.statistics)
    return tuple(found)


def noise_component(name: str) -> NoiseComponent:
    """The component called ``name``; raises KeyError naming the known ones."""
    for component in NOISE_COMPONENTS:
        if component.name == name:
            return component
    raise KeyError(f"unknown noise component {name!r}; known: {', '.join(c.name for c in NOISE_COMPONENTS)}")


def noise_parameter(name: str) -> Parameter:
    """The parameter called ``name``; raises KeyError naming the known ones."""
    for parameter in noise_parameters():
        if parameter.name == name:
            return parameter
    raise KeyError(f"unknown noise parameter {name!r}; known: {', '.join(noise_parameter_names())}")


def profile_version() -> int:
    """The version profiles are written with: the newest a parameter of the table arrived in."""
    return max(p.since_version for p in noise_parameters())
