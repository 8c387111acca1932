"""The fused per-pixel pass for 8-bit frames: darkening, heteroscedastic and quantization noise in one sweep.

An 8-bit input has only 256 values, so the darkened level and the standard deviation of the heteroscedastic
noise are read from two 256-entry tables instead of being computed per pixel. What remains per pixel, one
gather, a multiply-add, the quantization byte and the column pattern, rounding and clamping, is one
expression that ``torch.compile`` fuses into a single loop; without compilation the same expression runs as
a chain of eager operations and gives bit-identical output.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import torch

from darksynth.noise.heteroscedastic import heteroscedastic_std
from darksynth.noise.quantization import QUANTIZATION_LEVELS

logger = logging.getLogger(__name__)

FULL_SCALE = 255.0

PixelKernel = Callable[
    [torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor
]


def pixel_kernel_8bit(
    frame: torch.Tensor,
    standard_normal: torch.Tensor,
    uniform_levels: torch.Tensor,
    mean_table: torch.Tensor,
    std_table: torch.Tensor,
    level_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """One frame of darkening + f(v) on 8-bit values.

    Args:
        frame: clean frame (C, H, W) uint8.
        standard_normal: N(0, 1) draws, float32, shaped like ``frame``.
        uniform_levels: random bytes 0..255 shaped like ``frame`` (quantization noise).
        mean_table: (256,) float32, darkened level of each input value, in 8-bit units.
        std_table: (256,) float32, heteroscedastic standard deviation at each input value, in 8-bit units.
        level_step: 0-dim float32, quantization width q in 8-bit units divided by QUANTIZATION_LEVELS.
        column_pattern: (C, 1, W) float32, the sum of the column components, in 8-bit units.

    Returns:
        The low-light frame (C, H, W) uint8, rounded and clipped.
    """
    index = frame.to(torch.int32)
    level = (
        mean_table[index]
        + std_table[index] * standard_normal
        + (uniform_levels.to(torch.float32) + 0.5) * level_step
        + column_pattern
    )
    # Rounding before clamping equals clamping before rounding here because the bounds are integers.
    return level.round().clamp(0.0, FULL_SCALE).to(torch.uint8)


def lookup_tables(
    alpha: float | None, gamma: float | None, shot: float, read: float, *, device: torch.device
) -> tuple[torch.Tensor, torch.Tensor]:
    """The 256-entry tables of darkened level and noise standard deviation, in 8-bit units.

    Args:
        alpha, gamma: darkening x_d = alpha * x ** (1 / gamma); both None leaves the input level unchanged.
        shot, read: heteroscedastic parameters on the [0, 1] scale.
        device: device of the tables.
    """
    clean = torch.arange(256, dtype=torch.float64, device=device) / FULL_SCALE
    darkened = clean if alpha is None or gamma is None else alpha * clean.pow(1.0 / gamma)
    std = heteroscedastic_std(darkened, shot, read)
    return (darkened * FULL_SCALE).float(), (std * FULL_SCALE).float()


def quantization_level_step(quantization: float, *, device: torch.device) -> torch.Tensor:
    """q in 8-bit units per random byte, as a 0-dim tensor so that compiled code does not specialise on it."""
    return torch.tensor(quantization * FULL_SCALE / QUANTIZATION_LEVELS, dtype=torch.float32, device=device)


_compiled: PixelKernel | None = None


def compiled_pixel_kernel() -> PixelKernel:
    """The fused kernel through ``torch.compile``, or the eager one where compilation is unavailable.

    Compiling costs seconds once per process and frame size (less with the on-disk cache of later runs), so
    callers use it for streams of many same-sized frames and the eager kernel for a single image.
    """
    global _compiled
    if _compiled is None:
        try:
            _compiled = torch.compile(pixel_kernel_8bit, dynamic=False, fullgraph=True)
        except Exception as error:  # pragma: no cover - depends on the platform's compiler
            logger.info("torch.compile unavailable (%s); using the eager 8-bit kernel", error)
            _compiled = pixel_kernel_8bit
    return _compiled
