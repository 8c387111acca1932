"""The fused per-pixel pass for 8-bit frames: darkening, heteroscedastic and quantization noise in one sweep.

Per pixel: the darkened level alpha * x ** (1 / gamma), its noise standard deviation
sqrt(shot^2 * x_d + read^2), a counter-based normal and byte (:mod:`darksynth.noise.counter_rng`), the column
pattern, rounding and clamping. It is one expression that ``torch.compile`` fuses into a single vectorised
loop over the frame, with no random numbers ever written to memory. Without compilation the same expression
runs as a chain of eager operations and gives bit-identical output, only slower, which suits a single image
better than the seconds a compilation costs.

Why lookup tables: 8-bit input has only 256 values, so the darkened level and its standard deviation are read
from two 256-entry tables (int32 indices, which the compiled loop gathers in vector registers). On AVX-512 that
is a little slower than computing exp(log(x) / gamma) and the square root per pixel (16.3 against 14.3 ms for
the white kernel, 1080p RGB, together with the inverse-CDF normal), but on AVX2, whose vector exp and log are
several times slower, it halves the kernel (18.7 against 34.4 ms): one code for both processor families, and
the worse of the two is what a user can count on (docs/performance.md).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import torch

from darksynth.noise.components import FastPath
from darksynth.noise.counter_rng import advance, normal_and_byte
from darksynth.noise.quantization import QUANTIZATION_LEVELS
from darksynth.noise.values import NoiseValues

logger = logging.getLogger(__name__)

FULL_SCALE = 255.0

FAST_PATH: FastPath = "fused_8bit"
"""The name under which the table declares what this kernel covers (:attr:`Parameter.fast_paths`): white
heteroscedastic and quantization noise per pixel; the column components come in as a precomputed pattern."""

PixelKernel = Callable[..., torch.Tensor]

EAGER_CHUNK_VALUES = 1 << 19
"""The eager kernel works through a frame in pieces of about this many values: its chain of operations
materialises some twenty frame-sized temporaries, over 1 GiB for a 1080p frame if done in one piece."""


def pixel_kernel_8bit(
    frame: torch.Tensor,
    key: torch.Tensor,
    alpha: torch.Tensor,
    inverse_gamma: torch.Tensor,
    shot_squared: torch.Tensor,
    read_squared: torch.Tensor,
    quantization_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """One frame of darkening + f(v) on 8-bit values.

    The scalar arguments are 0-dim float32 tensors (not Python numbers) so that compiled code does not
    specialise on their values and recompile for every clip.

    Args:
        frame: clean frame (C, H, W) uint8.
        key: (2,) int32, the frame's key for the counter-based normal and quantization byte.
        alpha: darkening scale (1 for no darkening).
        inverse_gamma: darkening exponent 1 / gamma (1 for no darkening).
        shot_squared: shot^2 of the heteroscedastic noise, on the [0, 1] scale.
        read_squared: read^2 of the heteroscedastic noise, on the [0, 1] scale.
        quantization_step: q / QUANTIZATION_LEVELS, the width of one level of the quantization byte.
        column_pattern: (C, 1, W) float32, the sum of the column components, in 8-bit units.

    Returns:
        The low-light frame (C, H, W) uint8, rounded and clipped.
    """
    unit, byte = normal_and_byte(frame.shape, key)
    # 8-bit input has 256 levels: the darkened level and its noise std are read from two 256-entry tables
    # computed here. exp(log(x) / gamma) is x ** (1 / gamma), with log(0) = -inf giving exactly 0 at black.
    levels = torch.arange(256, dtype=torch.float32, device=frame.device) * (1.0 / FULL_SCALE)
    darkened_table = alpha * torch.exp(inverse_gamma * torch.log(levels))
    std_table = torch.sqrt(shot_squared * darkened_table + read_squared)
    index = frame.to(torch.int32)
    darkened, std = darkened_table[index], std_table[index]
    quantization = (byte.to(torch.float32) + 0.5) * quantization_step
    level = (darkened + std * unit + quantization) * FULL_SCALE + column_pattern
    # Rounding before clamping equals clamping before rounding here because the bounds are integers.
    return level.round().clamp(0.0, FULL_SCALE).to(torch.uint8)


def kernel_scalars(
    alpha: float | None, gamma: float | None, values: NoiseValues, *, device: torch.device
) -> tuple[torch.Tensor, ...]:
    """The 0-dim arguments (alpha, inverse_gamma, shot_squared, read_squared, quantization_step) of the kernel.

    Args:
        alpha, gamma: darkening x_d = alpha * x ** (1 / gamma); both None leaves the input level unchanged.
        values: unbatched noise values that the kernel covers (``covered_by(values, FAST_PATH)``).
        device: device of the tensors.
    """
    shot, read, quantization = values.scalar("shot"), values.scalar("read"), values.scalar("quantization")
    scalars = (
        1.0 if alpha is None else alpha,
        1.0 if gamma is None else 1.0 / gamma,
        shot * shot,
        read * read,
        quantization / QUANTIZATION_LEVELS,
    )
    return tuple(torch.tensor(v, dtype=torch.float32, device=device) for v in scalars)


def pixel_kernel_in_pieces(
    kernel: PixelKernel,
    frame: torch.Tensor,
    key: torch.Tensor,
    scalars: tuple[torch.Tensor, ...],
    column_pattern: torch.Tensor,
    *,
    piece_values: int = EAGER_CHUNK_VALUES,
) -> torch.Tensor:
    """Run the kernel on blocks of rows of each channel; the result is bit-identical to one call on the frame.

    The counter-based draws depend only on a value's flat index plus the key's base, so a block starting at flat
    index ``offset`` gets exactly its own numbers when the key is advanced by ``offset``.
    """
    channels, height, width = frame.shape
    rows = max(1, piece_values // max(width, 1))
    if rows >= height and channels == 1:
        return kernel(frame, key, *scalars, column_pattern)
    out = torch.empty_like(frame)
    for channel in range(channels):
        for top in range(0, height, rows):
            offset = (channel * height + top) * width
            out[channel : channel + 1, top : top + rows] = kernel(
                frame[channel : channel + 1, top : top + rows],
                advance(key, offset),
                *scalars,
                column_pattern[channel : channel + 1],
            )
    return out


_compiled: dict[str, Callable[..., Any]] = {}


def compiled_function(kernel: Callable[..., Any]) -> Callable[..., Any]:
    """``kernel`` through ``torch.compile``, once per process, or ``kernel`` itself where compilation is
    unavailable (with one logged line)."""
    name = kernel.__name__
    if name not in _compiled:
        try:
            _compiled[name] = torch.compile(kernel, dynamic=False, fullgraph=True)
        except Exception as error:  # pragma: no cover - depends on the platform's compiler
            logger.warning("torch.compile unavailable (%s); using the eager %s", error, name)
            _compiled[name] = kernel
    return _compiled[name]


def compiled_pixel_kernel() -> PixelKernel:
    """The fused kernel through ``torch.compile``, or the eager one where compilation is unavailable.

    Compiling costs seconds once per process and frame size (less with the on-disk cache of later runs), so
    callers use it for streams of many same-sized frames and the eager kernel for a single image.
    """
    return compiled_function(pixel_kernel_8bit)
