"""Tensor conventions shared by every layer: clips shaped (*batch, T, C, H, W), per-clip parameters broadcast
against them, and the 8-bit levels a stored image has. Imports nothing of darksynth, so the pure core
(darkening, noise) and the edges (io, training, evaluation) can all use it."""

from __future__ import annotations

import torch

CLIP_DIMS = 4
"""The trailing (T, C, H, W) dimensions of every clip tensor; the dimensions before them are the batch."""


def per_clip(value: torch.Tensor | float, like: torch.Tensor | torch.Size, *, device: torch.device) -> torch.Tensor:
    """Shape a parameter so that it broadcasts against a clip.

    Args:
        value: a number, or a tensor shaped like the clip's batch dimensions (one value per clip).
        like: the clip, or its shape (*batch, T, C, H, W).
        device: device of the result.

    Returns:
        A float tensor shaped (*batch, 1, 1, 1, 1), or 0-dimensional for a plain number.
    """
    if not isinstance(value, torch.Tensor):
        return torch.tensor(float(value), device=device)
    shape = like.shape if isinstance(like, torch.Tensor) else like
    batch = tuple(shape[: len(shape) - CLIP_DIMS])
    if value.dim() == 0:
        return value.to(device=device, dtype=torch.float32)
    if tuple(value.shape) != batch:
        raise ValueError(f"a per-clip parameter must have the batch shape {batch}, got {tuple(value.shape)}")
    return value.to(device=device, dtype=torch.float32).reshape(*batch, 1, 1, 1, 1)


def check_clip_shape(shape: torch.Size | tuple[int, ...]) -> None:
    """Reject shapes that are not (*batch, T, C, H, W)."""
    if len(shape) < CLIP_DIMS:
        raise ValueError(f"expected a clip shaped (..., T, C, H, W), got shape {tuple(shape)}")


def to_8bit_levels(image: torch.Tensor) -> torch.Tensor:
    """Clip to [0, 1] and round to the 256 levels an 8-bit file stores, as a real sRGB reference arrives."""
    return (image.clamp(0.0, 1.0) * 255.0).round() / 255.0
