"""The fused per-pixel pass for 8-bit frames: darkening, the white Gaussian and quantization noise in one sweep.

Per pixel: the darkened level, its noise standard deviation, a counter-based normal and byte
(:mod:`darksynth.noise.counter_rng`), the column pattern, rounding and clamping. It is one expression that
``torch.compile`` fuses into a single vectorised loop over the frame, with no random numbers ever written to memory.
Without compilation the same expression runs as a chain of eager operations and gives bit-identical output, only
slower, which suits a single image better than the seconds a compilation costs.

Why lookup tables: 8-bit input has only 256 values, so the darkened level and its standard deviation are read
from two 256-entry tables (int32 indices, which the compiled loop gathers in vector registers). The tables are the
composer's own: the level is :func:`darksynth.light.darkening.darken` of the 256 levels and the std the active
components' ``white_variance`` laws summed there (:func:`darksynth.noise.simulate.white_pixel_std`), so a white
Gaussian component declared in the table is drawn here without a line of this module. Reading tables is a little
slower than computing exp(log(x) / gamma) and the square root per pixel on AVX-512 (16.3 against 14.3 ms for the
white kernel, 1080p RGB, together with the inverse-CDF normal), but on AVX2, whose vector exp and log are several
times slower, it halves the kernel (18.7 against 34.4 ms): one code for both processor families, and the worse of
the two is what a user can count on (docs/performance.md).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import torch

from darksynth.light.darkening import Darkening, darken
from darksynth.noise.components import FastPath
from darksynth.noise.counter_rng import advance, normal_and_byte
from darksynth.noise.paper_components import QUANTIZATION
from darksynth.noise.quantization import QUANTIZATION_LEVELS
from darksynth.noise.simulate import active_components, white_pixel_std
from darksynth.noise.values import NoiseValues, covered_by

logger = logging.getLogger(__name__)

FULL_SCALE = 255.0

FAST_PATH: FastPath = "fused_8bit"
"""The name under which the table declares what this kernel covers (:attr:`Parameter.fast_paths`): the white
Gaussian components (by their laws) and quantization noise per pixel; the column components come in as a
precomputed pattern."""

PixelKernel = Callable[..., torch.Tensor]

EAGER_CHUNK_VALUES = 1 << 19
"""The eager kernel works through a frame in pieces of about this many values: its chain of operations
materialises some twenty frame-sized temporaries, over 1 GiB for a 1080p frame if done in one piece."""


def draws(values: NoiseValues) -> bool:
    """Whether the kernel draws ``values`` with the composer's law: every set parameter declares it
    (:attr:`Parameter.fast_paths`), and every active pixel component is white Gaussian noise with its law
    (``white_variance``) or the quantization the kernel draws by its byte."""
    return covered_by(values, FAST_PATH) and all(
        component.white_variance is not None or component is QUANTIZATION
        for component in active_components(values, "pixel")
    )


def pixel_kernel_8bit(
    frame: torch.Tensor,
    key: torch.Tensor,
    darkened_table: torch.Tensor,
    std_table: torch.Tensor,
    quantization_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """One frame of darkening + f(v) on 8-bit values.

    The tables and the step are tensors (not Python numbers) so that compiled code does not specialise on their
    values and recompile for every clip.

    Args:
        frame: clean frame (C, H, W) uint8.
        key: (2,) int32, the frame's key for the counter-based normal and quantization byte.
        darkened_table: (256,) float32, the darkened level of each 8-bit value on the [0, 1] scale.
        std_table: (256,) float32, the std of the white Gaussian noise at each of those levels.
        quantization_step: 0-dim float32, q / QUANTIZATION_LEVELS, the width of one level of the quantization byte.
        column_pattern: (C, 1, W) float32, the sum of the column components, in 8-bit units.

    Returns:
        The low-light frame (C, H, W) uint8, rounded and clipped.
    """
    unit, byte = normal_and_byte(frame.shape, key)
    index = frame.to(torch.int32)
    # Gathered from tables the graph computes (the inputs times 1, exactly themselves), not from the inputs: compiled
    # for AVX2, gathers from an input cost 46 ms a 1080p frame against 34 (AVX-512: 27 against 25).
    darkened, std = (darkened_table * 1.0)[index], (std_table * 1.0)[index]
    quantization = (byte.to(torch.float32) + 0.5) * quantization_step
    return rounded_frame(darkened + std * unit + quantization, column_pattern)


def rounded_frame(level: torch.Tensor, column_pattern: torch.Tensor) -> torch.Tensor:
    """The 8-bit frame of ``level`` (on the [0, 1] scale) plus ``column_pattern`` (in 8-bit units), the last step
    of every 8-bit kernel."""
    # Rounding before clamping equals clamping before rounding here because the bounds are integers.
    return (level * FULL_SCALE + column_pattern).round().clamp(0.0, FULL_SCALE).to(torch.uint8)


def kernel_tables(
    darkening: Darkening | None, values: NoiseValues, *, device: torch.device
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The kernel's (darkened_table, std_table, quantization_step) for a clip: the composer's darkening of the 256
    levels, the std of the white Gaussian components there, and the quantization byte's step.

    Args:
        darkening: x_d = alpha * x ** (1 / gamma); None leaves the input level unchanged.
        values: unbatched float32 noise values on ``device`` that the kernel covers
            (``covered_by(values, FAST_PATH)``), as the composer reads them.
        device: device of the tensors.
    """
    levels = (torch.arange(256, dtype=torch.float32, device=device) / FULL_SCALE).reshape(1, 1, 1, 256)
    darkened = levels if darkening is None else darken(levels, darkening.alpha, darkening.gamma)
    std = white_pixel_std(darkened, values)
    # As the composer: the step a float32, its 1/256 exact.
    step = values["quantization"][0].to(device=device, dtype=torch.float32) / QUANTIZATION_LEVELS
    return darkened.reshape(256).contiguous(), std.reshape(256).contiguous(), step


def pixel_kernel_in_pieces(
    kernel: PixelKernel,
    frame: torch.Tensor,
    key: torch.Tensor,
    tables: tuple[torch.Tensor, ...],
    column_pattern: torch.Tensor,
    *,
    piece_values: int = EAGER_CHUNK_VALUES,
) -> torch.Tensor:
    """Run the kernel on blocks of rows of each channel; the result is bit-identical to one call on the frame
    (``tables``: :func:`kernel_tables`).

    The counter-based draws depend only on a value's flat index plus the key's base, so a block starting at flat
    index ``offset`` gets exactly its own numbers when the key is advanced by ``offset``.
    """
    channels, height, width = frame.shape
    rows = max(1, piece_values // max(width, 1))
    if rows >= height and channels == 1:
        return kernel(frame, key, *tables, column_pattern)
    out = torch.empty_like(frame)
    for channel in range(channels):
        for top in range(0, height, rows):
            offset = (channel * height + top) * width
            out[channel : channel + 1, top : top + rows] = kernel(
                frame[channel : channel + 1, top : top + rows],
                advance(key, offset),
                *tables,
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
