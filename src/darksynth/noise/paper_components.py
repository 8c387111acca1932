"""The paper's components besides the heteroscedastic one: quantization and the column components (banding,
temporal banding, periodic), each declared next to the functions that draw it and give its variance.

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import torch

from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.component_types import ALL_8BIT_PATHS, DrawFunction, NoiseComponent, Parameter, VarianceFunction
from darksynth.noise.periodic import periodic_noise
from darksynth.noise.quantization import quantization_noise


def _draw_one_value(noise: Callable[..., torch.Tensor], name: str) -> DrawFunction:
    """The draw of a component whose one parameter ``name`` has one value: ``noise(shape, value, *, generator,
    device)`` for the signal's shape and device."""

    def draw(
        signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
    ) -> torch.Tensor:
        return noise(signal.shape, values[name][..., 0], generator=generator, device=signal.device)

    return draw


def _draw_periodic(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    return periodic_noise(signal.shape, values["periodic"], generator=generator, device=signal.device)


def _quantization_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # U(0, q) has variance q^2 / 12 (its mean q / 2 is a shift of the level, not noise).
    return (values["quantization"][:, :1].square() / 12.0).expand_as(channel_means)


def _column_variance(name: str) -> VarianceFunction:
    def variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
        # Each periodic mode has unit mean square over the columns, so its variance is its sigma^2 too.
        return values[name].square().sum(dim=-1, keepdim=True).expand_as(channel_means)

    return variance


QUANTIZATION = NoiseComponent(
    name="quantization",
    parameters=(
        Parameter(
            "quantization",
            1,
            "width of the uniform interval U(0, q)",
            1.0,
            (0.0, 0.02),
            log_floor=0.0002,
            fast_paths=ALL_8BIT_PATHS,
        ),
    ),
    structure="pixel",
    draw=_draw_one_value(quantization_noise, "quantization"),
    variance=_quantization_variance,
    reference="Lin, Morris et al. 2025, eq. of f(v); Monakhova et al. 2022",
)


BANDING = NoiseComponent(
    name="banding",
    parameters=(
        Parameter(
            "banding",
            1,
            "std of a per-frame column offset",
            1.0,
            (0.0, 0.03),
            log_floor=0.0003,
            fast_paths=ALL_8BIT_PATHS,
        ),
    ),
    structure="column",
    draw=_draw_one_value(banding_noise, "banding"),
    variance=_column_variance("banding"),
    reference="Monakhova et al. 2022, Dancing under the stars (row/column noise)",
)


TEMPORAL_BANDING = NoiseComponent(
    name="temporal_banding",
    parameters=(
        Parameter(
            "temporal_banding",
            1,
            "std of a per-clip column offset",
            1.0,
            (0.0, 0.03),
            log_floor=0.0003,
            fast_paths=ALL_8BIT_PATHS,
        ),
    ),
    structure="column",
    draw=_draw_one_value(temporal_banding_noise, "temporal_banding"),
    variance=_column_variance("temporal_banding"),
    reference="Monakhova et al. 2022, Dancing under the stars (fixed-pattern noise)",
    per_clip=True,
)


PERIODIC = NoiseComponent(
    name="periodic",
    parameters=(
        Parameter(
            "periodic",
            3,
            "std of the DC, cosine and sine column patterns",
            1.0,
            (0.0, 0.02),
            log_floor=0.0002,
            fast_paths=ALL_8BIT_PATHS,
        ),
    ),
    structure="column",
    draw=_draw_periodic,
    variance=_column_variance("periodic"),
    reference="Monakhova et al. 2022, Dancing under the stars (periodic noise)",
)
