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
from darksynth.noise.correlated import normalised_taps, unit_noise_factors
from darksynth.noise.counter_rng import (
    advance,
    byte_from_word,
    first_word,
    flat_index,
    normal_and_byte,
    normal_from_word,
)
from darksynth.noise.quantization import QUANTIZATION_LEVELS
from darksynth.noise.values import NoiseValues

logger = logging.getLogger(__name__)

FULL_SCALE = 255.0

FAST_PATH: FastPath = "fused_8bit"
"""The name under which the table declares what this kernel covers (:attr:`Parameter.fast_paths`): white
heteroscedastic and quantization noise per pixel; the column components come in as a precomputed pattern."""

STRUCTURED_PATH: FastPath = "structured_8bit"
"""The sRGB model's path: :func:`srgb_pixel_kernel_8bit`, which draws the structured unit noise (counter-based
normals, the spatial filter of each component, the channel mixing) and does the per-pixel pass in one compiled
function; the compression stage runs after it."""

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
    normal, byte = normal_and_byte(frame.shape, key)
    return pixel_pass_8bit(
        frame, normal, byte, alpha, inverse_gamma, shot_squared, read_squared, quantization_step, column_pattern
    )


def pixel_pass_8bit(
    frame: torch.Tensor,
    unit: torch.Tensor,
    byte: torch.Tensor,
    alpha: torch.Tensor,
    inverse_gamma: torch.Tensor,
    shot_squared: torch.Tensor,
    read_squared: torch.Tensor,
    quantization_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """The per-pixel pass of both kernels: darkening, std * ``unit`` (the heteroscedastic draw), the quantization
    draw from ``byte`` (C, H, W) int32 in 0..255 (:func:`darksynth.noise.quantization.quantization_noise`'s law), the
    column pattern, rounding and clamping. ``unit`` (C, H, W) float32 is white for :func:`pixel_kernel_8bit` and
    the structured unit noise for :func:`srgb_pixel_kernel_8bit`."""
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


def srgb_pixel_kernel_8bit(
    frame: torch.Tensor,
    key: torch.Tensor,
    taps: torch.Tensor,
    mixing: torch.Tensor,
    first_row: torch.Tensor,
    frame_rows: torch.Tensor,
    alpha: torch.Tensor,
    inverse_gamma: torch.Tensor,
    shot_squared: torch.Tensor,
    read_squared: torch.Tensor,
    quantization_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """Rows ``first_row ..`` of one frame of darkening + f(v) for the sRGB model on 8-bit values, the structured
    unit noise drawn inside: :func:`pixel_pass_8bit` fed with counter-based draws.

    The unit noise is the general path's law (:func:`darksynth.noise.correlated.structured_normal`): N white
    components on a grid padded by the kernel radius, each filtered along x and y by its row of ``taps`` (variance
    kept at 1), mixed into the channels by ``mixing``. Normal n at padded row y and column x is the draw of index
    (n * (frame_rows + K - 1) + y) * (W + K - 1) + x, the quantization byte of channel c at row y, column x the
    draw of index N * (frame_rows + K - 1) * (W + K - 1) + (c * frame_rows + y) * W + x, so a block of rows
    gets exactly its numbers in the whole frame: the eager kernel runs in blocks that stay in cache and the
    output does not depend on the blocking.

    Args:
        frame: rows of the clean frame (C, R, W) uint8.
        key: (2,) int32 key of the frame (:func:`darksynth.noise.counter_rng.random_key`).
        taps: (N, K) float32 normalised taps (:func:`darksynth.noise.correlated.normalised_taps`), K odd.
        mixing: (C, N) float32 mixing of the components into the channels.
        first_row, frame_rows: 0-dim int32, the block's first row in the frame and the frame's height.
        alpha ... column_pattern: as :func:`pixel_kernel_8bit`.
    """
    channels, rows, width = frame.shape
    count, size = taps.shape
    device = frame.device
    padded_width = width + size - 1
    padded_rows = frame_rows + (size - 1)
    component = torch.arange(count, dtype=torch.int32, device=device)[:, None, None]
    row = (torch.arange(rows + size - 1, dtype=torch.int32, device=device) + first_row)[None, :, None]
    column = torch.arange(padded_width, dtype=torch.int32, device=device)[None, None, :]
    white, _ = normal_from_word(first_word((component * padded_rows + row) * padded_width + column, key))
    along_x = taps[:, 0, None, None] * white[:, :, :width]
    for tap in range(1, size):
        along_x = along_x + taps[:, tap, None, None] * white[:, :, tap : tap + width]
    both = taps[:, 0, None, None] * along_x[:, :rows]
    for tap in range(1, size):
        both = both + taps[:, tap, None, None] * along_x[:, tap : tap + rows]
    unit = mixing[:, 0, None, None] * both[0]
    for component_index in range(1, count):
        unit = unit + mixing[:, component_index, None, None] * both[component_index]
    channel = torch.arange(channels, dtype=torch.int32, device=device)[:, None, None]
    frame_row = (torch.arange(rows, dtype=torch.int32, device=device) + first_row)[None, :, None]
    byte_index = (channel * frame_rows + frame_row) * width + flat_index((1, 1, width), device)
    byte = byte_from_word(first_word(byte_index + count * padded_rows * padded_width, key))
    return pixel_pass_8bit(
        frame, unit, byte, alpha, inverse_gamma, shot_squared, read_squared, quantization_step, column_pattern
    )


def srgb_kernel_factors(values: NoiseValues, channels: int, *, device: torch.device) -> tuple[torch.Tensor, ...]:
    """The (taps, mixing) arguments of :func:`srgb_pixel_kernel_8bit` for unbatched ``values`` and ``channels``:
    the general path's own factors (:func:`darksynth.noise.correlated.unit_noise_factors`)."""
    pairs = values["channel_correlation"].tolist()
    red, blue = values["channel_gain"].tolist()
    lengths, mixing = unit_noise_factors(
        channels, values.scalar("correlation_length"), values.scalar("chroma_length"), pairs, (red, blue)
    )
    return normalised_taps(lengths).to(device), mixing.to(device=device, dtype=torch.float32)


def srgb_kernel_in_pieces(
    kernel: PixelKernel,
    frame: torch.Tensor,
    key: torch.Tensor,
    factors: tuple[torch.Tensor, ...],
    scalars: tuple[torch.Tensor, ...],
    column_pattern: torch.Tensor,
    *,
    piece_values: int = EAGER_CHUNK_VALUES,
) -> torch.Tensor:
    """Run the sRGB kernel on blocks of rows (all channels, which the mixing needs); bit-identical to one call."""
    channels, height, width = frame.shape
    rows = max(1, piece_values // max(channels * width, 1))
    frame_rows = torch.tensor(height, dtype=torch.int32, device=frame.device)
    if rows >= height:
        first = torch.zeros((), dtype=torch.int32, device=frame.device)
        return kernel(frame, key, *factors, first, frame_rows, *scalars, column_pattern)
    out = torch.empty_like(frame)
    for top in range(0, height, rows):
        first = torch.tensor(top, dtype=torch.int32, device=frame.device)
        out[:, top : top + rows] = kernel(
            frame[:, top : top + rows], key, *factors, first, frame_rows, *scalars, column_pattern
        )
    return out


def kernel_scalars(
    alpha: float | None, gamma: float | None, values: NoiseValues, *, device: torch.device
) -> tuple[torch.Tensor, ...]:
    """The 0-dim arguments (alpha, inverse_gamma, shot_squared, read_squared, quantization_step) of the kernel.

    Args:
        alpha, gamma: darkening x_d = alpha * x ** (1 / gamma); both None leaves the input level unchanged.
        values: unbatched noise values that the kernel covers (``values.covered_by(FAST_PATH)``).
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


def compiled_srgb_kernel() -> PixelKernel:
    """:func:`srgb_pixel_kernel_8bit` through ``torch.compile`` (the eager one where that is unavailable)."""
    return compiled_function(srgb_pixel_kernel_8bit)
