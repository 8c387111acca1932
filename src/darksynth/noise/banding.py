"""Column banding: one Gaussian offset per channel and column, constant down the column."""

from __future__ import annotations

import torch

from darksynth.tensors import check_clip_shape, per_clip


def banding_noise(
    shape: torch.Size | tuple[int, ...],
    sigma: torch.Tensor | float,
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Per-frame column banding: b[..., t, c, :, w] ~ N(0, sigma^2), redrawn for every frame.

    Args:
        shape: clip shape (*batch, T, C, H, W).
        sigma: standard deviation of a column's offset (a number or one value per clip).
        generator: source of randomness; the global generator when None.
        device: device of the result.

    Returns:
        A row pattern shaped (*batch, T, C, 1, W) that broadcasts down the columns of the clip.
    """
    check_clip_shape(shape)
    *frames, _height, width = shape
    return _column_offsets((*frames, 1, width), shape, sigma, generator, device)


def temporal_banding_noise(
    shape: torch.Size | tuple[int, ...],
    sigma: torch.Tensor | float,
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Fixed-pattern column banding: drawn once per clip and identical in each of its frames.

    The authors' public code redraws this pattern for every frame, which makes it the same thing as
    :func:`banding_noise`; the paper describes it as held over the clip, as here.

    Args:
        shape: clip shape (*batch, T, C, H, W).
        sigma: standard deviation of a column's offset (a number or one value per clip).
        generator: source of randomness; the global generator when None.
        device: device of the result.

    Returns:
        A row pattern shaped (*batch, 1, C, 1, W) that broadcasts over frames and down columns.
    """
    check_clip_shape(shape)
    *batch, _frames, channels, _height, width = shape
    return _column_offsets((*batch, 1, channels, 1, width), shape, sigma, generator, device)


def _column_offsets(
    pattern_shape: tuple[int, ...],
    clip_shape: torch.Size | tuple[int, ...],
    sigma: torch.Tensor | float,
    generator: torch.Generator | None,
    device: torch.device | str | None,
) -> torch.Tensor:
    """N(0, sigma^2) offsets of the given pattern shape, sigma broadcast per clip of ``clip_shape``."""
    dev = torch.device(device) if device is not None else torch.device("cpu")
    pattern = torch.randn(pattern_shape, generator=generator, device=dev)
    return per_clip(sigma, torch.Size(clip_shape), device=dev) * pattern
