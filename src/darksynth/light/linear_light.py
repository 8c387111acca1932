"""sRGB values and linear light, for integrating frames as a sensor sums photons (IEC 61966-2-1).

Frames are numpy arrays, uint8, uint16 or float in [0, 1]. An 8-bit frame goes through tables: each level to 16-bit
linear light and back (the round trip returns every level), so a blur of a 1080p frame needs no power function.
"""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np


def srgb_to_linear(values: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear light (IEC 61966-2-1), float32."""
    values = values.astype(np.float32, copy=False)
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(values: np.ndarray) -> np.ndarray:
    """Linear light in [0, 1] to sRGB-encoded values, float32."""
    values = np.clip(values, 0.0, 1.0).astype(np.float32, copy=False)
    encoded = np.where(values <= 0.0031308, values * 12.92, 1.055 * values ** (1 / 2.4) - 0.055)
    return encoded.astype(np.float32)


_LINEAR_OF_LEVEL = srgb_to_linear(np.arange(256, dtype=np.float32) / 255.0)
# Linear light on a 16-bit grid to the nearest 8-bit level: the encoding of a blurred pixel is one table read.
LINEAR16_OF_LEVEL = np.round(_LINEAR_OF_LEVEL * 65535.0).astype(np.uint16)
LEVEL_OF_LINEAR16 = np.round(linear_to_srgb(np.arange(65536, dtype=np.float32) / 65535.0) * 255.0).astype(np.uint8)


def unit_scale(frame: np.ndarray) -> np.ndarray:
    """A frame's values on the [0, 1] scale, float32."""
    if frame.dtype == np.uint16:
        return frame.astype(np.float32) / 65535.0
    if np.issubdtype(frame.dtype, np.floating):
        return frame.astype(np.float32, copy=False)
    raise ValueError(f"frames in linear light are uint8, uint16 or float frames, got {frame.dtype}")


def decode(frame: np.ndarray) -> np.ndarray:
    """A frame (H, W, C) of sRGB values (uint8, uint16 or float in [0, 1]) in linear light, float32 in [0, 1]."""
    if frame.dtype == np.uint8:
        return cv2.LUT(frame, _LINEAR_OF_LEVEL) if frame.shape[-1] <= 4 else _LINEAR_OF_LEVEL[frame]
    return srgb_to_linear(unit_scale(frame))


def encode(linear: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Linear light back to sRGB values of ``dtype`` (uint8 or uint16 rounded, float as it is)."""
    if dtype == np.uint8:
        # Rounded and saturated to 16 bits by OpenCV, on every core.
        index = cv2.multiply(np.ascontiguousarray(linear, dtype=np.float32), 65535.0, dtype=cv2.CV_16U)
        return levels_of_linear16(index)
    if dtype == np.uint16:
        return np.round(linear_to_srgb(linear) * 65535.0).astype(np.uint16)
    return linear_to_srgb(linear).astype(dtype)


_TABLE_PARTS = min(4, os.cpu_count() or 1)


@functools.lru_cache(maxsize=1)
def _table_threads() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=_TABLE_PARTS, thread_name_prefix="darksynth-srgb")


# A forked child (a DataLoader worker running the transforms) inherits the pool without its threads, and work sent
# to it would wait for ever: the child makes its own.
os.register_at_fork(after_in_child=_table_threads.cache_clear)


def levels_of_linear16(linear: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """8-bit sRGB levels of 16-bit linear light (one table read per value), into ``out`` if given (same shape).

    The table read is numpy's, which runs on one core but lets go of the interpreter: the rows are read in parallel
    blocks, one per core (a 1080p frame: 14 ms on one core, 7 on two)."""
    out = np.empty(linear.shape, np.uint8) if out is None else out
    parts = _TABLE_PARTS if linear.ndim and linear.shape[0] >= 64 else 1
    bounds = [linear.shape[0] * part // parts for part in range(parts + 1)]

    def read(part: int) -> None:
        rows = slice(bounds[part], bounds[part + 1])
        np.take(LEVEL_OF_LINEAR16, linear[rows], out=out[rows])

    if parts == 1:
        read(0)
    else:
        list(_table_threads().map(read, range(parts)))
    return out
