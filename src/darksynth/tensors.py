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


def full_scale(dtype: torch.dtype) -> float | None:
    """The value of full white in a pixel type (None for float, whose scale is [0, 1])."""
    if dtype == torch.uint8:
        return 255.0
    if dtype in (torch.uint16, torch.int32, torch.int64):
        return 65535.0
    if dtype.is_floating_point:
        return None
    raise ValueError(f"unsupported pixel type {dtype}")


def unit_float(image: torch.Tensor) -> torch.Tensor:
    """Pixels of any type as float32 values in [0, 1] (float pixels are already on that scale): the inverse of
    :func:`to_dtype`."""
    scale = full_scale(image.dtype)
    image = image.to(torch.float32)
    return image / scale if scale else image


def to_dtype(image: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """Values in [0, 1] as pixels of ``dtype`` (integers rounded)."""
    scale = full_scale(dtype)
    if scale is None:
        return image.to(dtype)
    rounded = (image * scale).round()
    # torch has few kernels for uint16; int32 holds every 16-bit value exactly.
    return rounded.to(torch.int32).to(dtype) if dtype == torch.uint16 else rounded.to(dtype)


def eight_bit_levels(frame: torch.Tensor) -> torch.Tensor | None:
    """The uint8 levels of a float frame whose every value is a level ``k / 255`` as float32 computes it, else
    None."""
    values = frame.to(torch.float32)
    # The first row first: a frame of other values is usually told from it at once.
    for part in (values[..., :1, :], values):
        levels = (part * 255.0).round_().clamp_(0.0, 255.0)
        if not torch.equal(levels / 255.0, part):
            return None
    return levels.to(torch.uint8)


def scale_channels(frame: torch.Tensor, factors: tuple[float, ...]) -> torch.Tensor:
    """A frame (C, H, W) with each channel times its factor, in its own dtype (integers rounded and clipped)."""
    scale = torch.tensor(factors, dtype=torch.float32, device=frame.device)[:, None, None]
    scaled = frame.to(torch.float32) * scale
    top = full_scale(frame.dtype)
    if top is None:
        return scaled.to(frame.dtype)
    return to_dtype(scaled.clamp_(0.0, top) / top, frame.dtype)


LUMINANCE_WEIGHTS: tuple[float, float, float] = (0.2126, 0.7152, 0.0722)
"""Rec. 709 weights of red, green and blue in the luminance a viewer judges brightness by (sRGB's primaries)."""


def luminance(frames: torch.Tensor) -> torch.Tensor:
    """The luminance (..., H, W) of frames (..., C, H, W): the weighted sum of red, green and blue
    (:data:`LUMINANCE_WEIGHTS`); a grey frame (C = 1) is its own luminance."""
    if frames.shape[-3] == 1:
        return frames[..., 0, :, :].to(torch.float32)
    weights = torch.tensor(LUMINANCE_WEIGHTS, dtype=torch.float32, device=frames.device)
    return torch.einsum("c,...chw->...hw", weights, frames[..., :3, :, :].to(torch.float32))
