"""The one composer of the noise model: f(v) as the sum of its components, added to the darkened signal."""

from __future__ import annotations

from collections.abc import Mapping

import torch

from darksynth.noise.components import NOISE_COMPONENTS, NoiseComponent


def is_active(component: NoiseComponent, values: Mapping[str, torch.Tensor]) -> bool:
    """Whether any of the component's parameters is non-zero; an inactive one draws nothing."""
    return any(bool((values[p.name] != 0).any()) for p in component.parameters)


def drawing_order() -> tuple[NoiseComponent, ...]:
    """Column components first, then per-pixel ones, each group in table order.

    Frame-by-frame streaming draws in the same order, so an image gives the same result either way.
    """
    columns = tuple(c for c in NOISE_COMPONENTS if c.structure == "column")
    return columns + tuple(c for c in NOISE_COMPONENTS if c.structure != "column")


def noise_sum(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], *, generator: torch.Generator | None = None
) -> torch.Tensor:
    """f(v): the sum of all active noise components for a darkened clip.

    Args:
        signal: darkened clean clip (*batch, T, C, H, W), values in [0, 1].
        values: every noise parameter by name, tensors (size,) or (*batch, size).
        generator: source of randomness; the global generator when None.

    Returns:
        The noise, shaped like ``signal`` (zeros when every parameter is zero).
    """
    total = torch.zeros_like(signal)
    for component in drawing_order():
        if is_active(component, values):
            total = total + component.draw(signal, values, generator)
    return total


def add_noise(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], *, generator: torch.Generator | None = None
) -> torch.Tensor:
    """The noisy low-light clip: signal + f(v), clipped to [0, 1]."""
    return (signal + noise_sum(signal, values, generator=generator)).clamp(0.0, 1.0)
