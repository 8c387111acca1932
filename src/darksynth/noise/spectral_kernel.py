"""The spectral model's compiled path for 8-bit streams: the frequency-domain draw and the per-pixel pass fused.

The eager spectral path (:mod:`darksynth.noise.spectral`, :mod:`darksynth.noise.spectral_8bit`) is bounded by
what it writes to memory: the white field of its FFT grid drawn from ``torch.Generator``'s serial stream (about
7 million normals a 1080p frame), nine frame-sized factor arrays read to mix it, and the quantization bytes.
Here two ``torch.compile`` kernels do the work in vectorised loops on every core:

* the **mixing kernel** computes each frequency bin's white values from a counter-based hash of the bin's index
  (:mod:`darksynth.noise.counter_rng`, nothing written to memory), carries them forward in time (AR(1), the
  clip's state), and mixes them into the channels with the factor of the bin's radial frequency, gathered from
  the small radial table (1024 entries) instead of read from frame-sized arrays;
* one inverse FFT (torch's own, not compiled);
* the **pixel kernel** reads the darkened level and the noise std of each 8-bit value from the clip's 256-entry
  tables, adds the unit noise times the std, a counter-based quantization draw and the column pattern, and
  rounds.

It draws the same law as the eager path (same spectrum, same colour covariance per octave, same AR(1) in time,
same level curve), not the same bits: the white values come from a hash, not from the generator, as the sRGB
model's compiled kernel already does (:func:`darksynth.noise.kernel8.srgb_pixel_kernel_8bit`). Eagerly these
functions give the compiled one's values (the tests run them both ways), only slower; they are used compiled.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

from darksynth.darkening import Darkening
from darksynth.noise.counter_rng import byte_from_word, first_word, flat_index, normal_from_word, random_key
from darksynth.noise.kernel8 import compiled_function
from darksynth.noise.quantization import QUANTIZATION_LEVELS
from darksynth.noise.spectral import MARGIN, grid_size, radial_correlation, radial_factor, radial_index
from darksynth.noise.spectral_8bit import level_tables

FULL_SCALE = 255.0

LEVELS = 256


@dataclass(frozen=True)
class KernelTables:
    """One clip's spectrum on one frame size's grid, in the form the mixing kernel reads.

    Attributes:
        grid_height, grid_width: the FFT grid (:func:`darksynth.noise.spectral.grid_size`).
        index: (rows, rfft columns) int32, each bin's entry of the radial tables.
        factors: (RADIAL_TABLE_SIZE, C, C) float32 factor of the unit spectral covariance at each radial entry,
            scaled for irfft2's 1/N and the split of a bin's variance between its real and imaginary parts.
        rho: (RADIAL_TABLE_SIZE,) float32 AR(1) coefficient, None without temporal correlation.
        innovation: sqrt(1 - rho^2), likewise.
    """

    grid_height: int
    grid_width: int
    index: torch.Tensor
    factors: torch.Tensor
    rho: torch.Tensor | None
    innovation: torch.Tensor | None


def kernel_tables(
    covariances: torch.Tensor, temporal: torch.Tensor, channels: int, height: int, width: int, *, device: torch.device
) -> KernelTables:
    """The tables of a spectrum (``covariances`` (OCTAVES, 3, 3), ``temporal`` (OCTAVES,)) for frames of
    (``height``, ``width``), as :func:`darksynth.noise.spectral.spectral_tables` builds them for the eager path."""
    grid_height, grid_width = grid_size(height, width)
    # A white field of unit variance has coefficients of mean square N (irfft2 divides by N), N / 2 in each of
    # the real and imaginary parts.
    scale = math.sqrt(grid_height * grid_width / 2.0)
    factors = (radial_factor(covariances.to(device), channels) * scale).to(torch.float32).contiguous()
    index = radial_index(grid_height, grid_width, device).to(torch.int32)
    rho = radial_correlation(temporal.to(device))
    if not bool((rho > 0).any()):
        return KernelTables(grid_height, grid_width, index, factors, None, None)
    innovation = (1.0 - rho.square()).sqrt()
    return KernelTables(grid_height, grid_width, index, factors, rho.to(torch.float32), innovation.to(torch.float32))


def _white(key: torch.Tensor, channels: int, rows: int, columns: int) -> torch.Tensor:
    """(C, rows, columns, 2) standard normals, the real and imaginary parts of each bin: value i (C order) is
    the normal of the counter-based word of index i under ``key``."""
    normal, _ = normal_from_word(first_word(flat_index((channels, rows, columns, 2), key.device), key))
    return normal


def _mix(white: torch.Tensor, index: torch.Tensor, factors: torch.Tensor) -> torch.Tensor:
    # Each bin's (target, source) factor, gathered from the radial table: (C_t, C_s, rows, columns, 1).
    factor = factors[index].permute(2, 3, 0, 1)[..., None]
    mixed: torch.Tensor = (factor * white[None]).sum(1)
    return mixed


def spectral_mix_kernel(key: torch.Tensor, index: torch.Tensor, factors: torch.Tensor) -> torch.Tensor:
    """One frame's spectrum without temporal correlation: (C, rows, rfft columns, 2), real and imaginary parts.

    Args:
        key: (2,) int32 key of the frame (:func:`darksynth.noise.counter_rng.random_key`).
        index: (rows, rfft columns) int32, :attr:`KernelTables.index`.
        factors: (entries, C, C) float32, :attr:`KernelTables.factors`.
    """
    rows, columns = index.shape
    return _mix(_white(key, factors.shape[-1], rows, columns), index, factors)


def spectral_ar_mix_kernel(
    key: torch.Tensor,
    index: torch.Tensor,
    factors: torch.Tensor,
    rho: torch.Tensor,
    innovation: torch.Tensor,
    state: torch.Tensor,
    started: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One frame's spectrum with AR(1) in time: (mixed, new state), both (C, rows, rfft columns, 2).

    The state is the white field behind the spectrum: ``w_t = rho w_{t-1} + sqrt(1 - rho^2) e_t`` per bin, with
    ``rho`` of the bin's radial frequency; the first frame (``started`` a 0-dim False) takes ``e_t`` itself.

    Args:
        key, index, factors: as :func:`spectral_mix_kernel`.
        rho, innovation: (entries,) float32, :attr:`KernelTables.rho` and :attr:`KernelTables.innovation`.
        state: the previous frame's white field (ignored at the first frame).
        started: 0-dim bool, whether ``state`` holds a previous frame.
    """
    rows, columns = index.shape
    fresh = _white(key, factors.shape[-1], rows, columns)
    carried = rho[index][..., None] * state + innovation[index][..., None] * fresh
    white = torch.where(started, carried, fresh)
    return _mix(white, index, factors), white


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
    channels = frame.shape[0]
    offsets = torch.arange(channels, dtype=torch.int32, device=frame.device).reshape(-1, 1, 1) * LEVELS
    index = frame.to(torch.int32) + offsets
    signal = signal_table.reshape(-1)[index]
    std = std_table.reshape(-1)[index]
    byte = byte_from_word(first_word(flat_index(frame.shape, frame.device), key))
    quantization = (byte.to(torch.float32) + 0.5) * quantization_step
    level = (signal + std * unit + quantization) * FULL_SCALE + column_pattern
    # Rounding before clamping equals clamping before rounding here because the bounds are integers.
    return level.round().clamp(0.0, FULL_SCALE).to(torch.uint8)


def crop_unit(field: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """The frame's part (C, height, width) of the inverse FFT's grid (C, grid rows, grid columns)."""
    return field[:, MARGIN : MARGIN + height, MARGIN : MARGIN + width]


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
    ) -> None:
        channels, self.height, self.width = shape
        self.tables = kernel_tables(covariances, temporal, channels, self.height, self.width, device=device)
        self.signal_table, self.std_table = level_tables(channels, darkening, curve, device=device)
        # As the eager path: the step a float32, its 1/256 exact.
        self.quantization_step = torch.tensor(quantization, dtype=torch.float32) / QUANTIZATION_LEVELS
        self.quantization_step = self.quantization_step.to(device)
        self.no_columns = torch.zeros((channels, 1, self.width), dtype=torch.float32, device=device)
        self._mix, self._ar_mix, self._pixel = mix, ar_mix, pixel
        self._state: torch.Tensor | None = None

    def __call__(
        self, frame: torch.Tensor, generator: torch.Generator | None, column_pattern: torch.Tensor | None
    ) -> torch.Tensor:
        """The noisy uint8 frame (C, H, W) of the clean uint8 ``frame``; ``column_pattern`` (C, 1, W) in 8-bit
        units, None when no column component is active."""
        tables = self.tables
        key = random_key(generator).to(frame.device)
        if tables.rho is None or tables.innovation is None:
            mixed = self._mix(key, tables.index, tables.factors)
        else:
            started = self._state is not None
            # The first frame's state is not read (the kernel takes the fresh draw), only its shape matters.
            state = (
                self._state
                if self._state is not None
                else torch.empty((frame.shape[0], *tables.index.shape, 2), device=frame.device)
            )
            mixed, self._state = self._ar_mix(
                key,
                tables.index,
                tables.factors,
                tables.rho,
                tables.innovation,
                state,
                torch.tensor(started, device=frame.device),
            )
        field = torch.fft.irfft2(torch.view_as_complex(mixed), s=(tables.grid_height, tables.grid_width))
        columns = self.no_columns if column_pattern is None else column_pattern
        return self._pixel(
            frame.contiguous(),
            random_key(generator).to(frame.device),
            self.signal_table,
            self.std_table,
            crop_unit(field, self.height, self.width),
            self.quantization_step,
            columns,
        )


def compiled_spectral_kernels() -> tuple[Kernel, Callable[..., tuple[torch.Tensor, torch.Tensor]], Kernel]:
    """(mix, ar_mix, pixel) through ``torch.compile``, once per process (each the eager function where
    compilation is unavailable)."""
    return (
        compiled_function(spectral_mix_kernel),
        compiled_function(spectral_ar_mix_kernel),
        compiled_function(spectral_pixel_kernel),
    )


__all__ = [
    "KernelTables",
    "SpectralKernelStream",
    "compiled_spectral_kernels",
    "crop_unit",
    "kernel_tables",
    "spectral_ar_mix_kernel",
    "spectral_mix_kernel",
    "spectral_pixel_kernel",
]
