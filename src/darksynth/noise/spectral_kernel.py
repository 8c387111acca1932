"""The spectral model's compiled path for 8-bit streams: the frequency-domain draw and the per-pixel pass fused.

The eager spectral path (:mod:`darksynth.noise.spectral`, :mod:`darksynth.noise.spectral_8bit`) is bounded by
what it writes to memory: the white field of its FFT grid drawn from ``torch.Generator``'s serial stream (about
7 million normals a 1080p frame), and the mixing and the per-pixel pass in many small eager operations.
Here two ``torch.compile`` kernels do the work in vectorised loops on every core:

* the **mixing kernel** computes each frequency bin's white values from a counter-based hash of the bin's index
  (:mod:`darksynth.noise.counter_rng`, nothing written to memory; triangular draws of unit variance, which the
  inverse FFT sums into a normal field, at a fifth of the inverse normal CDF's cost), carries them forward in
  time (AR(1), the clip's state), and mixes them into the channels with each bin's factor (the eager path's
  cached tables);
* one inverse FFT (torch's own, not compiled);
* the **pixel kernel** reads the darkened level and the noise std of each 8-bit value from the clip's 256-entry
  tables, adds the unit noise times the std, a counter-based quantization draw and the column pattern, and
  rounds.

It draws the same law as the eager path (same spectrum, same colour covariance per octave, same AR(1) in time,
same level curve, normal values), not the same bits: the white values come from a hash, not from the
generator, as the white model's kernel does (:func:`darksynth.noise.fused_8bit.pixel_kernel_8bit`).
Eagerly these functions give the compiled ones' values (the tests run them both ways), only slower; they are
used compiled.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from darksynth.light.darkening import Darkening
from darksynth.noise.counter_rng import (
    byte_from_word,
    first_word,
    flat_index,
    normal_from_word,
    random_key,
    triangular_from_word,
)
from darksynth.noise.fused_8bit import compiled_function, rounded_frame
from darksynth.noise.quantization import QUANTIZATION_LEVELS
from darksynth.noise.simulate import white_pixel_std
from darksynth.noise.spectral import crop_unit, spectral_tables
from darksynth.noise.spectral_8bit import LEVELS, level_tables, read_levels
from darksynth.noise.texture import texture_modulation
from darksynth.noise.values import NoiseValues


def _white(key: torch.Tensor, channels: int, rows: int, values: int) -> torch.Tensor:
    """(C, rows, values) zero-mean unit-variance draws, the real and imaginary parts of each bin side by side:
    value i (C order) is the triangular draw of the counter-based word of index i under ``key``
    (:func:`darksynth.noise.counter_rng.triangular_from_word`: the inverse FFT sums them into a normal field)."""
    return triangular_from_word(first_word(flat_index((channels, rows, values), key.device), key))


def _mix(white: torch.Tensor, factors: torch.Tensor) -> torch.Tensor:
    channels = white.shape[0]
    # factors (C_t * C_s, rows, values), target-major, as SpectralTables keeps them.
    mixed: torch.Tensor = (factors.view(channels, channels, *factors.shape[1:]) * white[None]).sum(1)
    return mixed


def spectral_mix_kernel(key: torch.Tensor, factors: torch.Tensor) -> torch.Tensor:
    """One frame's spectrum without temporal correlation: (C, rows, 2 * rfft columns), the real and imaginary
    part of each bin side by side.

    Args:
        key: (2,) int32 key of the frame (:func:`darksynth.noise.counter_rng.random_key`).
        factors: (C * C, rows, 2 * rfft columns) float32 mixing factor of each bin,
            :attr:`darksynth.noise.spectral.SpectralTables.factors` (read per value, not gathered from the radial
            table: the compiled gathers cost 9 ms a 1080p frame, the reads of the cached array 3).
    """
    channels = math.isqrt(factors.shape[0])
    return _mix(_white(key, channels, *factors.shape[1:]), factors)


def spectral_ar_mix_kernel(
    key: torch.Tensor,
    factors: torch.Tensor,
    rho: torch.Tensor,
    innovation: torch.Tensor,
    state: torch.Tensor,
    started: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One frame's spectrum with AR(1) in time: (mixed, new state), both (C, rows, 2 * rfft columns).

    The state is the white field behind the spectrum: ``w_t = rho w_{t-1} + sqrt(1 - rho^2) e_t`` per bin, with
    ``rho`` of the bin's radial frequency; the first frame (``started`` a 0-dim False) takes ``e_t`` itself.

    Args:
        key, factors: as :func:`spectral_mix_kernel`.
        rho, innovation: (rows, 2 * rfft columns) float32, :attr:`darksynth.noise.spectral.SpectralTables.rho`
            and ``innovation``.
        state: the previous frame's white field (not read at the first frame).
        started: 0-dim bool, whether ``state`` holds a previous frame.
    """
    channels = math.isqrt(factors.shape[0])
    fresh = _white(key, channels, *factors.shape[1:])
    white = torch.where(started, rho * state + innovation * fresh, fresh)
    return _mix(white, factors), white


def spectral_pixel_kernel(
    frame: torch.Tensor,
    key: torch.Tensor,
    signal_table: torch.Tensor,
    std_table: torch.Tensor,
    unit: torch.Tensor,
    quantization_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """One 8-bit frame's darkened level + std * unit noise + quantization + columns, rounded: (C, H, W) uint8.

    Args:
        frame: the clean frame (C, H, W) uint8.
        key: (2,) int32 key of the quantization bytes (another than the mixing kernel's).
        signal_table, std_table: (C, 256) float32 darkened level and noise std of each 8-bit level
            (:func:`darksynth.noise.spectral_8bit.level_tables`).
        unit: the frame's spectral unit noise (C, H, W) float32.
        quantization_step: 0-dim float32, q / 256 (:data:`darksynth.noise.quantization.QUANTIZATION_LEVELS`).
        column_pattern: (C, 1, W) float32 column components in 8-bit units (zeros when none is active).
    """
    index = _table_index(frame)
    signal, std = _read(signal_table, index), _read(std_table, index)
    byte = byte_from_word(first_word(flat_index(frame.shape, frame.device), key))
    quantization = (byte.to(torch.float32) + 0.5) * quantization_step
    return rounded_frame(signal + std * unit + quantization, column_pattern)


def _table_index(frame: torch.Tensor) -> torch.Tensor:
    """(C, H, W) int32: each value's place in a (C, 256) table read flat (its channel's row, its level's column)."""
    offsets = torch.arange(frame.shape[0], dtype=torch.int32, device=frame.device).reshape(-1, 1, 1) * LEVELS
    return frame.to(torch.int32) + offsets


def _read(table: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    return table.reshape(-1)[index]


def spectral_white_pixel_kernel(
    frame: torch.Tensor,
    key: torch.Tensor,
    signal_table: torch.Tensor,
    std_table: torch.Tensor,
    white_std_table: torch.Tensor,
    unit: torch.Tensor,
    quantization_step: torch.Tensor,
    column_pattern: torch.Tensor,
) -> torch.Tensor:
    """:func:`spectral_pixel_kernel` with white Gaussian noise besides: ``white_std_table`` (C, 256) float32, the
    std of the white components together at each 8-bit level, times a counter-based normal of the same word as
    the quantization byte (the normal takes its top 24 bits, the byte its low 8: independent)."""
    index = _table_index(frame)
    signal, std, white_std = _read(signal_table, index), _read(std_table, index), _read(white_std_table, index)
    normal, byte = normal_from_word(first_word(flat_index(frame.shape, frame.device), key))
    quantization = (byte.to(torch.float32) + 0.5) * quantization_step
    return rounded_frame(signal + std * unit + white_std * normal + quantization, column_pattern)


Kernel = Callable[..., torch.Tensor]


class SpectralKernelStream:
    """One 8-bit clip through the compiled spectral path, frame after frame: its tables, its level tables and
    its state (the white field of the previous frame, with temporal correlation).

    Args:
        shape: the frames' (C, H, W).
        covariances, temporal: the clip's spectrum (:func:`darksynth.noise.spectral.octave_covariances`) and
            ``temporal_correlation``.
        darkening: the clip's darkening, None for none.
        curve: ``level_curve`` (24,).
        quantization: the quantization value (0 for none).
        mix, ar_mix, pixel: :func:`spectral_mix_kernel`, :func:`spectral_ar_mix_kernel` and
            :func:`spectral_pixel_kernel`, compiled (or not, for tests).
        device: where the frames are.
        texture: (``texture_gain``, ``texture_scale``) when the noise follows texture, else None.
        white: the clip's values when white Gaussian components are active (their laws read them; ``pixel`` is
            then :func:`spectral_white_pixel_kernel`), else None.
    """

    def __init__(
        self,
        shape: tuple[int, int, int],
        covariances: torch.Tensor,
        temporal: torch.Tensor,
        darkening: Darkening | None,
        curve: torch.Tensor,
        quantization: float,
        *,
        mix: Kernel,
        ar_mix: Callable[..., tuple[torch.Tensor, torch.Tensor]],
        pixel: Kernel,
        device: torch.device,
        texture: tuple[float, float] | None = None,
        white: NoiseValues | None = None,
    ) -> None:
        channels, self.height, self.width = shape
        # The eager path's cached tables: a stream of either kind builds them once.
        self.tables = spectral_tables(covariances, temporal, channels, self.height, self.width, device=device)
        self.channels, self.device, self.curve, self.white = channels, device, curve, white
        self.set_darkening(darkening)
        # As the eager path: the step a float32, its 1/256 exact.
        self.quantization_step = torch.tensor(quantization, dtype=torch.float32) / QUANTIZATION_LEVELS
        self.quantization_step = self.quantization_step.to(device)
        self.no_columns = torch.zeros((channels, 1, self.width), dtype=torch.float32, device=device)
        self._mix, self._ar_mix, self._pixel = mix, ar_mix, pixel
        self._state: torch.Tensor | None = None
        self.texture = texture
        # The darkened frame the texture factor is read on (the eager pass's own signal array, reused).
        self._signal = torch.empty(shape, dtype=torch.float32, device=device) if texture is not None else None

    def set_darkening(self, darkening: Darkening | None) -> None:
        """The 8-bit tables of a darkening (the clip's, or a frame's under flicker)."""
        self.signal_table, self.std_table = level_tables(self.channels, darkening, self.curve, device=self.device)
        self.white_std_table = None
        if self.white is not None:
            levels = self.signal_table[None, :, None, :]
            self.white_std_table = white_pixel_std(levels, self.white)[0, :, 0].contiguous()

    def __call__(
        self, frame: torch.Tensor, generator: torch.Generator | None, column_pattern: torch.Tensor | None
    ) -> torch.Tensor:
        """The noisy uint8 frame (C, H, W) of the clean uint8 ``frame``; ``column_pattern`` (C, 1, W) in 8-bit
        units, None when no column component is active."""
        tables = self.tables
        key = random_key(generator).to(frame.device)
        if tables.rho is None or tables.innovation is None:
            mixed = self._mix(key, tables.factors)
        else:
            started = self._state is not None
            # The first frame's state is not read (the kernel takes the fresh draw), only its shape matters.
            state = self._state if self._state is not None else torch.empty_like(tables.factors[: frame.shape[0]])
            mixed, self._state = self._ar_mix(
                key, tables.factors, tables.rho, tables.innovation, state, torch.tensor(started, device=frame.device)
            )
        spectrum = torch.view_as_complex(mixed.view(*mixed.shape[:2], -1, 2))
        field = torch.fft.irfft2(spectrum, s=(tables.grid_height, tables.grid_width))
        columns = self.no_columns if column_pattern is None else column_pattern
        frame = frame.contiguous()
        unit = crop_unit(field, self.height, self.width)
        if self.texture is not None and self._signal is not None:
            # The std's texture factor, read as the composer reads it: on the darkened frame before the columns.
            # std * (unit * factor) is the kernel's std * unit with the factor on the std.
            darkened = read_levels(frame, self.signal_table, self._signal)
            unit = unit * texture_modulation(darkened, *self.texture)
        white = () if self.white_std_table is None else (self.white_std_table,)
        return self._pixel(
            frame,
            random_key(generator).to(frame.device),
            self.signal_table,
            self.std_table,
            *white,
            unit,
            self.quantization_step,
            columns,
        )


def spectral_kernels(white: bool = False) -> tuple[Kernel, Callable[..., tuple[torch.Tensor, torch.Tensor]], Kernel]:
    """(mix, ar_mix, pixel), eager: :func:`spectral_mix_kernel`, :func:`spectral_ar_mix_kernel` and
    :func:`spectral_pixel_kernel` (with ``white``, :func:`spectral_white_pixel_kernel`)."""
    return spectral_mix_kernel, spectral_ar_mix_kernel, spectral_white_pixel_kernel if white else spectral_pixel_kernel


def compiled_spectral_kernels(
    white: bool = False,
) -> tuple[Kernel, Callable[..., tuple[torch.Tensor, torch.Tensor]], Kernel]:
    """:func:`spectral_kernels` through ``torch.compile``, once per process (each the eager function where
    compilation is unavailable)."""
    mix, ar_mix, pixel = spectral_kernels(white)
    return compiled_function(mix), compiled_function(ar_mix), compiled_function(pixel)


__all__ = [
    "SpectralKernelStream",
    "compiled_spectral_kernels",
    "spectral_ar_mix_kernel",
    "spectral_kernels",
    "spectral_mix_kernel",
    "spectral_pixel_kernel",
    "spectral_white_pixel_kernel",
]
