"""Quantization noise, uniform on [0, q)."""

from __future__ import annotations

import torch

from darksynth.tensors import per_clip

QUANTIZATION_LEVELS = 256
"""The uniform variate is drawn on this many equally spaced levels (one random byte per pixel).

A byte costs a third less to draw than a float32 uniform, and the grid of q/256 lies far below one output
level for any q a real camera shows, so the distribution is U(0, q) to within q/512."""


def uniform_levels_to_noise(levels: torch.Tensor, step: torch.Tensor | float) -> torch.Tensor:
    """Map random bytes (0..255) to the midpoints of QUANTIZATION_LEVELS equal bins of [0, step)."""
    return (levels.to(torch.float32) + 0.5) * (step / QUANTIZATION_LEVELS)


def quantization_noise(
    shape: torch.Size | tuple[int, ...],
    step: torch.Tensor | float,
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Draw u ~ U(0, q) independently at every pixel.

    The paper's model is one-sided, so this noise has mean q / 2 and variance q^2 / 12.

    Args:
        shape: clip shape (*batch, T, C, H, W).
        step: the interval width q (a number or one value per clip).
        generator: source of randomness; the global generator when None.
        device: device of the result.

    Returns:
        Float32 noise of the given shape, values in [0, q).
    """
    dev = torch.device(device) if device is not None else torch.device("cpu")
    levels = torch.empty(shape, dtype=torch.uint8, device=dev)
    levels.random_(generator=generator)
    return uniform_levels_to_noise(levels, per_clip(step, torch.Size(shape), device=dev))
