"""Random draws of the parameters of the noise and darkening models (training, jitter, profile ranges)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import torch

from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE
from darksynth.noise.components import NoiseModel, model_parameters
from darksynth.noise.values import NoiseValues

Range = tuple[float, float]


def random_uniform(
    ranges: Sequence[Range],
    batch_shape: tuple[int, ...] = (),
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """Draw one value uniformly within each (low, high) interval, for each clip of a batch.

    Returns:
        Tensor (*batch_shape, len(ranges)), every value inside its closed interval.
    """
    low = torch.tensor([r[0] for r in ranges], dtype=dtype, device=device)
    high = torch.tensor([r[1] for r in ranges], dtype=dtype, device=device)
    unit = torch.rand((*batch_shape, len(ranges)), generator=generator, device=device, dtype=dtype)
    # The clamp keeps rounding of low + (high - low) * u from stepping past high.
    return torch.minimum(low + (high - low) * unit, high)


def random_noise_values(
    ranges: Mapping[str, Sequence[Range]] | None = None,
    batch_shape: tuple[int, ...] = (),
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
    noise_model: NoiseModel = "srgb",
    log_levels: bool = False,
) -> NoiseValues:
    """Draw every parameter of a noise model uniformly within its range (the training range where none is
    given); the parameters the model lacks get their neutral value, without a draw. With ``log_levels``, the
    levels that have a ``log_floor`` and no given range are drawn log-uniformly over [log_floor, high].

    Returns:
        Every parameter's values (*batch_shape, size), drawn in the order of the parameter table.
    """
    ranges = ranges or {}
    values: dict[str, torch.Tensor] = {}
    for p in model_parameters(noise_model):
        if log_levels and p.log_floor is not None and p.name not in ranges:
            logs = random_uniform(
                ((math.log(p.log_floor), math.log(p.training_range[1])),) * p.size,
                batch_shape,
                generator=generator,
                device=device,
                dtype=dtype,
            )
            values[p.name] = logs.exp().clamp(p.log_floor, p.training_range[1])
        else:
            values[p.name] = random_uniform(
                ranges.get(p.name, (p.training_range,) * p.size),
                batch_shape,
                generator=generator,
                device=device,
                dtype=dtype,
            )
    return NoiseValues.from_values(values, batch_shape=batch_shape, device=device, dtype=dtype)


def random_darkening_values(
    alpha_range: Range = ALPHA_RANGE,
    gamma_range: Range = GAMMA_RANGE,
    batch_shape: tuple[int, ...] = (),
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Draw alpha and gamma of the darkening, one pair per clip (paper's ranges by default).

    Returns:
        (alpha, gamma), each a tensor shaped batch_shape.
    """
    drawn = random_uniform((alpha_range, gamma_range), batch_shape, generator=generator, device=device)
    return drawn[..., 0], drawn[..., 1]
