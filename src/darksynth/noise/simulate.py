"""The one composer of the noise model: f(v) as the sum of its components, added to the darkened signal."""

from __future__ import annotations

from collections.abc import Mapping

import torch

from darksynth.noise.components import NOISE_COMPONENTS, NoiseComponent


def is_active(component: NoiseComponent, values: Mapping[str, torch.Tensor]) -> bool:
    """Whether any of the component's amplitude parameters differs from its neutral value; an inactive
    component draws nothing. Parameters missing from ``values`` (an older profile) count as neutral."""
    return any(
        p.name in values and bool((values[p.name] != p.neutral).any())
        for p in component.parameters
        if p.role == "amplitude"
    )


def drawing_order() -> tuple[NoiseComponent, ...]:
    """The additive components: column ones first, then per-pixel ones, each group in table order.

    Frame-by-frame streaming draws in the same order, so an image gives the same result either way.
    """
    columns = tuple(c for c in NOISE_COMPONENTS if c.structure == "column")
    return columns + tuple(c for c in NOISE_COMPONENTS if c.structure == "pixel")


def output_stages() -> tuple[NoiseComponent, ...]:
    """The components applied to the finished noisy image (compression), in table order."""
    return tuple(c for c in NOISE_COMPONENTS if c.structure == "output")


def apply_output_stages(
    noisy: torch.Tensor, values: Mapping[str, torch.Tensor], *, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Run the active output stages on a clipped noisy clip (*batch, T, C, H, W) in [0, 1]."""
    for stage in output_stages():
        if is_active(stage, values):
            noisy = stage.draw(noisy, values, generator)
    return noisy


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
    """The noisy low-light clip: signal + f(v), clipped to [0, 1], then the output stages (compression)."""
    noisy = (signal + noise_sum(signal, values, generator=generator)).clamp(0.0, 1.0)
    return apply_output_stages(noisy, values, generator=generator)
