"""Conversion between numpy images (H, W, C) and torch frames (C, H, W), uint16 included."""

from __future__ import annotations

import numpy as np
import torch

from darksynth.tensors import full_scale


def numpy_to_tensor(array: np.ndarray) -> torch.Tensor:
    """A tensor sharing the array's memory where it can; uint16 goes through int32, as torch has few uint16 kernels."""
    if array.dtype == np.uint16:
        return torch.from_numpy(array.astype(np.int32)).to(torch.uint16)
    # torch warns about (and must not write through) read-only arrays, such as those of decoded images.
    return torch.from_numpy(np.require(array, requirements=("C", "W")))


def tensor_to_numpy(tensor: torch.Tensor) -> np.ndarray:
    """A contiguous numpy copy or view of a tensor (on any device), uint16 included."""
    tensor = tensor.cpu()
    if tensor.dtype == torch.uint16:
        # .to() keeps a permuted tensor's strides, so the int32 array can be a non-contiguous view: the copy to
        # uint16 is made contiguous here, as the encoders reinterpret its bytes.
        return np.ascontiguousarray(tensor.to(torch.int32).numpy(), dtype=np.uint16)
    return np.ascontiguousarray(tensor.numpy())


def hwc_to_chw(array: np.ndarray) -> torch.Tensor:
    """An (H, W, C) image array as a (C, H, W) tensor."""
    return numpy_to_tensor(array).permute(2, 0, 1)


def rgb_chw(array: np.ndarray) -> torch.Tensor:
    """An (H, W, 1 or 3) image array as a (3, H, W) tensor: a grey image's one channel stands for all three."""
    tensor = hwc_to_chw(array)
    return tensor.expand(3, -1, -1) if tensor.shape[0] == 1 else tensor


def unit_float_frames(frames: list[torch.Tensor]) -> torch.Tensor:
    """Integer frames (C, H, W), uint8 or uint16, stacked as float32 (T, C, H, W) on the [0, 1] scale."""
    # Stack the integer frames first and convert once: one pass over the clip instead of one per frame.
    stacked = torch.stack(frames)
    scale = full_scale(stacked.dtype)
    assert scale is not None, f"integer frames expected, got {stacked.dtype}"
    if stacked.dtype == torch.uint16:
        stacked = stacked.to(torch.int32)
    return stacked.to(torch.float32).div_(scale)


def chw_to_hwc(frame: torch.Tensor) -> np.ndarray:
    """A (C, H, W) frame tensor as a contiguous (H, W, C) array."""
    return tensor_to_numpy(frame.permute(1, 2, 0))


def clips_from_numpy(array: np.ndarray) -> tuple[torch.Tensor, str]:
    """A numpy image (H, W) grey, (H, W, C) or clip (T, H, W, C) as clips (1 or T, C, H, W), and its layout name."""
    if array.dtype not in (np.uint8, np.uint16) and not np.issubdtype(array.dtype, np.floating):
        raise ValueError(f"unsupported array dtype {array.dtype}; use uint8, uint16 or float in [0, 1]")
    tensor = numpy_to_tensor(array)
    if array.ndim == 2:
        return tensor[None, None], "grey"
    if array.ndim == 3:
        return tensor.permute(2, 0, 1)[None], "hwc"
    if array.ndim == 4:
        return tensor.permute(0, 3, 1, 2), "thwc"
    raise ValueError(f"expected a numpy array (H, W), (H, W, C) or (T, H, W, C), got shape {array.shape}")


def clips_to_numpy(clip: torch.Tensor, layout: str) -> np.ndarray:
    """Clips back in the numpy layout :func:`clips_from_numpy` named."""
    if layout == "grey":
        return tensor_to_numpy(clip[0, 0])
    if layout == "hwc":
        return tensor_to_numpy(clip[0].permute(1, 2, 0))
    return tensor_to_numpy(clip.permute(0, 2, 3, 1))
