"""The noise components of f(v), declared as data.

Every quantity of the noise model lives in :data:`NOISE_COMPONENTS`: a component's parameters (name, number
of values, unit, valid bound, training range) and the pure function that draws it. The profile schema, the
parameter vector of the estimation network, the samplers and the command line all iterate over this table,
so a new component is added here, next to its function, and nowhere else.

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal

import torch

from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.correlated import jpeg_compress_clips, structured_normal
from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_std
from darksynth.noise.periodic import periodic_noise
from darksynth.noise.quantization import quantization_noise

Structure = Literal["pixel", "column", "output"]
"""How a component varies in the frame.

``pixel``: a new value at every pixel of every frame. ``column``: one value per channel and column, the same
down the whole column, so the component can be drawn as a (..., T or 1, C, 1, W) row and broadcast.
``output``: not added but applied to the finished noisy image (after summing and clipping), like a camera's
compression; its ``draw`` returns the transformed image instead of noise.
"""

NoiseModel = Literal["paper", "srgb"]
"""``paper``: the paper's five components (profile version 1, DEN model version 1). ``srgb``: those plus the
structure of real sRGB noise (per-channel gains, spatial and cross-channel correlation, JPEG), measured in
docs/srgb-noise.md (profile version 2, DEN model version 2)."""

Role = Literal["amplitude", "shape"]
"""``amplitude``: the component draws nothing when all its amplitude parameters are neutral. ``shape``: shapes
what the amplitudes draw (a correlation length, a channel gain) and draws nothing by itself."""

DrawFunction = Callable[[torch.Tensor, Mapping[str, torch.Tensor], torch.Generator | None], torch.Tensor]
"""``draw(signal, values, generator) -> noise``: ``signal`` is the darkened clean clip (..., T, C, H, W),
``values`` maps each of the component's parameter names to a tensor shaped (*batch, size), where *batch are
the clip's leading dimensions. The noise broadcasts against ``signal``."""


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
        model: the first noise model that has the parameter (see :data:`NoiseModel`).
        role: see :data:`Role`.
        training_off_probability: when set, training sets this parameter alone to its neutral value with this
            probability (shape parameters, so the estimator also sees white, uncompressed noise).
        log_floor: for a noise level spanning decades: with a log level prior, training draws it log-uniformly
            over [log_floor, training high] and the estimator predicts its logarithm (values below the floor
            read as the floor), so a level of 0.005 is estimated as precisely, relatively, as one of 0.05.
    """

    name: str
    size: int
    unit: str
    maximum: float
    training_range: tuple[float, float]
    minimum: float = 0.0
    neutral: float = 0.0
    model: NoiseModel = "paper"
    role: Role = "amplitude"
    training_off_probability: float | None = None
    log_floor: float | None = None


@dataclass(frozen=True)
class NoiseComponent:
    """One additive term of f(v) with the parameters it reads and the function that draws it."""

    name: str
    parameters: tuple[Parameter, ...]
    structure: Structure
    draw: DrawFunction
    reference: str
    per_clip: bool = False
    """True when one draw is held over all frames of a clip: a frame-by-frame stream draws it once."""


def shapes_neutral(parameters: tuple[Parameter, ...], values: Mapping[str, torch.Tensor]) -> bool:
    """True when none of ``parameters``' shape parameters is set (missing ones count as neutral): the noise
    they shape is the paper's white noise, drawn exactly as before them."""
    return all(
        p.name not in values or bool((values[p.name] == p.neutral).all()) for p in parameters if p.role == "shape"
    )


_HETEROSCEDASTIC_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("shot", 1, "std per sqrt(intensity): variance shot^2 * x", 1.0, (0.0, 0.2), log_floor=0.002),
    Parameter("read", 1, "std, signal-independent", 1.0, (0.0, 0.1), log_floor=0.001),
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
        model="srgb",
        role="shape",
        training_off_probability=0.2,
    ),
    Parameter(
        "correlation_length",
        1,
        "std in pixels of the Gaussian kernel that correlates the noise spatially (variance kept)",
        8.0,
        (0.0, 2.0),
        model="srgb",
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
        model="srgb",
        role="shape",
        training_off_probability=0.2,
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
    batch = shape[: len(shape) - 4]
    unit = structured_normal(
        shape,
        values["correlation_length"].expand(*batch, 1)[..., 0],
        values["channel_correlation"].expand(*batch, 3),
        values["channel_gain"].expand(*batch, 2),
        generator=generator,
        dtype=signal.dtype,
    ).reshape(signal.shape)
    return heteroscedastic_std(signal, shot, read) * unit


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


# The training ranges cover real sRGB low-light noise: at mid-grey (x = 0.5) shot 0.2 alone gives a std of
# 0.14 of full scale, and read noise adds up to 0.1 at black.
NOISE_COMPONENTS: tuple[NoiseComponent, ...] = (
    NoiseComponent(
        name="heteroscedastic",
        parameters=_HETEROSCEDASTIC_PARAMETERS,
        structure="pixel",
        draw=_draw_heteroscedastic,
        reference="Foi et al. 2008, Practical Poissonian-Gaussian noise modeling and fitting; "
        "structure: docs/srgb-noise.md",
    ),
    NoiseComponent(
        name="quantization",
        parameters=(
            Parameter("quantization", 1, "width of the uniform interval U(0, q)", 1.0, (0.0, 0.02), log_floor=0.0002),
        ),
        structure="pixel",
        draw=_draw_quantization,
        reference="Lin, Morris et al. 2025, eq. of f(v); Monakhova et al. 2022",
    ),
    NoiseComponent(
        name="banding",
        parameters=(Parameter("banding", 1, "std of a per-frame column offset", 1.0, (0.0, 0.03), log_floor=0.0003),),
        structure="column",
        draw=_draw_banding,
        reference="Monakhova et al. 2022, Dancing under the stars (row/column noise)",
    ),
    NoiseComponent(
        name="temporal_banding",
        parameters=(
            Parameter("temporal_banding", 1, "std of a per-clip column offset", 1.0, (0.0, 0.03), log_floor=0.0003),
        ),
        structure="column",
        draw=_draw_temporal_banding,
        reference="Monakhova et al. 2022, Dancing under the stars (fixed-pattern noise)",
        per_clip=True,
    ),
    NoiseComponent(
        name="periodic",
        parameters=(
            Parameter(
                "periodic", 3, "std of the DC, cosine and sine column patterns", 1.0, (0.0, 0.02), log_floor=0.0002
            ),
        ),
        structure="column",
        draw=_draw_periodic,
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
                model="srgb",
                training_off_probability=0.4,
            ),
        ),
        structure="output",
        draw=_draw_compression,
        reference="JPEG (ITU-T T.81) through Pillow, 4:2:0; docs/srgb-noise.md",
    ),
)

NOISE_PARAMETERS: tuple[Parameter, ...] = tuple(p for c in NOISE_COMPONENTS for p in c.parameters)
"""Every parameter, in table order: the full v of the ``srgb`` model."""

NOISE_PARAMETER_NAMES: tuple[str, ...] = tuple(p.name for p in NOISE_PARAMETERS)

NOISE_VECTOR_SIZE: int = sum(p.size for p in NOISE_PARAMETERS)
"""Length of the flat parameter vector v of the full (``srgb``) model."""

NOISE_MODELS: tuple[NoiseModel, ...] = ("paper", "srgb")


def model_parameters(model: NoiseModel = "srgb") -> tuple[Parameter, ...]:
    """The parameters of one noise model, in table order: ``paper`` is shot, read, quantization, banding,
    temporal_banding, periodic (3), the paper's v of 8 values; ``srgb`` is every parameter."""
    if model not in NOISE_MODELS:
        raise ValueError(f"unknown noise model {model!r}; known: {', '.join(NOISE_MODELS)}")
    last = NOISE_MODELS.index(model)
    return tuple(p for p in NOISE_PARAMETERS if NOISE_MODELS.index(p.model) <= last)


def vector_size(model: NoiseModel = "srgb") -> int:
    """Length of the flat v of one noise model (8 for ``paper``)."""
    return sum(p.size for p in model_parameters(model))


def noise_parameter(name: str) -> Parameter:
    """The parameter called ``name``; raises KeyError naming the known ones."""
    for parameter in NOISE_PARAMETERS:
        if parameter.name == name:
            return parameter
    raise KeyError(f"unknown noise parameter {name!r}; known: {', '.join(NOISE_PARAMETER_NAMES)}")


def values_to_vector(values: Mapping[str, torch.Tensor], model: NoiseModel = "srgb") -> torch.Tensor:
    """Concatenate a model's named parameter tensors (*batch, size) into its v (*batch, vector_size(model))."""
    return torch.cat([values[p.name] for p in model_parameters(model)], dim=-1)


def vector_to_values(vector: torch.Tensor, model: NoiseModel = "srgb") -> dict[str, torch.Tensor]:
    """Split a model's v (*batch, vector_size(model)) into named tensors (*batch, size), in the table's order."""
    parameters = model_parameters(model)
    size = sum(p.size for p in parameters)
    if vector.shape[-1] != size:
        raise ValueError(f"noise vector must end in {size} values, got shape {tuple(vector.shape)}")
    parts = torch.split(vector, [p.size for p in parameters], dim=-1)
    return {p.name: part for p, part in zip(parameters, parts, strict=True)}
