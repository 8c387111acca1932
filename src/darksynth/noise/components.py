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
from darksynth.noise.heteroscedastic import heteroscedastic_noise
from darksynth.noise.periodic import periodic_noise
from darksynth.noise.quantization import quantization_noise

Structure = Literal["pixel", "column"]
"""How a component varies in the frame.

``pixel``: a new value at every pixel of every frame. ``column``: one value per channel and column, the same
down the whole column, so the component can be drawn as a (..., T or 1, C, 1, W) row and broadcast.
"""

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
    """

    name: str
    size: int
    unit: str
    maximum: float
    training_range: tuple[float, float]


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


def _draw_heteroscedastic(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return heteroscedastic_noise(signal, values["shot"][..., 0], values["read"][..., 0], generator=generator)


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
        parameters=(
            Parameter("shot", 1, "std per sqrt(intensity): variance shot^2 * x", 1.0, (0.0, 0.2)),
            Parameter("read", 1, "std, signal-independent", 1.0, (0.0, 0.1)),
        ),
        structure="pixel",
        draw=_draw_heteroscedastic,
        reference="Foi et al. 2008, Practical Poissonian-Gaussian noise modeling and fitting",
    ),
    NoiseComponent(
        name="quantization",
        parameters=(Parameter("quantization", 1, "width of the uniform interval U(0, q)", 1.0, (0.0, 0.02)),),
        structure="pixel",
        draw=_draw_quantization,
        reference="Lin, Morris et al. 2025, eq. of f(v); Monakhova et al. 2022",
    ),
    NoiseComponent(
        name="banding",
        parameters=(Parameter("banding", 1, "std of a per-frame column offset", 1.0, (0.0, 0.03)),),
        structure="column",
        draw=_draw_banding,
        reference="Monakhova et al. 2022, Dancing under the stars (row/column noise)",
    ),
    NoiseComponent(
        name="temporal_banding",
        parameters=(Parameter("temporal_banding", 1, "std of a per-clip column offset", 1.0, (0.0, 0.03)),),
        structure="column",
        draw=_draw_temporal_banding,
        reference="Monakhova et al. 2022, Dancing under the stars (fixed-pattern noise)",
        per_clip=True,
    ),
    NoiseComponent(
        name="periodic",
        parameters=(Parameter("periodic", 3, "std of the DC, cosine and sine column patterns", 1.0, (0.0, 0.02)),),
        structure="column",
        draw=_draw_periodic,
        reference="Monakhova et al. 2022, Dancing under the stars (periodic noise)",
    ),
)

NOISE_PARAMETERS: tuple[Parameter, ...] = tuple(p for c in NOISE_COMPONENTS for p in c.parameters)
"""The parameter vector v, in order: shot, read, quantization, banding, temporal_banding, periodic (3)."""

NOISE_PARAMETER_NAMES: tuple[str, ...] = tuple(p.name for p in NOISE_PARAMETERS)

NOISE_VECTOR_SIZE: int = sum(p.size for p in NOISE_PARAMETERS)
"""Length of the flat parameter vector v (8 for the paper's model)."""


def noise_parameter(name: str) -> Parameter:
    """The parameter called ``name``; raises KeyError naming the known ones."""
    for parameter in NOISE_PARAMETERS:
        if parameter.name == name:
            return parameter
    raise KeyError(f"unknown noise parameter {name!r}; known: {', '.join(NOISE_PARAMETER_NAMES)}")


def values_to_vector(values: Mapping[str, torch.Tensor]) -> torch.Tensor:
    """Concatenate named parameter tensors (*batch, size) into v (*batch, NOISE_VECTOR_SIZE)."""
    return torch.cat([values[p.name] for p in NOISE_PARAMETERS], dim=-1)


def vector_to_values(vector: torch.Tensor) -> dict[str, torch.Tensor]:
    """Split v (*batch, NOISE_VECTOR_SIZE) into named tensors (*batch, size), in the table's order."""
    if vector.shape[-1] != NOISE_VECTOR_SIZE:
        raise ValueError(f"noise vector must end in {NOISE_VECTOR_SIZE} values, got shape {tuple(vector.shape)}")
    parts = torch.split(vector, [p.size for p in NOISE_PARAMETERS], dim=-1)
    return {p.name: part for p, part in zip(NOISE_PARAMETERS, parts, strict=True)}
