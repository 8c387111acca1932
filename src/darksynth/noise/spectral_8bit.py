"""The spectral model's fast path for 8-bit frames: the darkened level and the noise std read from tables.

An 8-bit frame has 256 levels per channel, so its darkened signal and the level curve's std at that signal take
at most 256 values per channel. Computing both once per clip on the 256 levels, with the general composer's own
functions (:func:`darksynth.light.darkening.darken`, :func:`darksynth.noise.spectral.level_std`), and reading them per
pixel replaces a power, a clamp, the piece arithmetic and two gathers per value by two table reads (OpenCV's
``LUT`` on the CPU, 8-bit indices, no index array). Everything else is drawn as the composer draws it, in its
order (:mod:`darksynth.noise.simulate`): the column components, the spectral unit noise of the stream's held
:class:`~darksynth.noise.spectral.SpectralGrid`, the quantization bytes, then the compression stage, so for the
same generator state the output is the composer's (tests/noise/test_fast_paths.py).

The table declares what this path draws (:attr:`darksynth.noise.components.Parameter.fast_paths`): the spectrum,
quantization, the column components, compression, and the white Gaussian components by their laws
(``white_variance``: the std of each at the 256 darkened levels is read from a table of its own, and its normals
are drawn where the composer draws them, in table order).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch

from darksynth.light.darkening import Darkening, darken
from darksynth.noise.components import FastPath, NoiseComponent
from darksynth.noise.quantization import QUANTIZATION_LEVELS
from darksynth.noise.spectral import level_std
from darksynth.noise.texture import texture_modulation

SPECTRAL_PATH: FastPath = "spectral_8bit"
"""The name under which the table declares what this path draws."""

LEVELS = 256

_ROUNDING = float(1 << 23)

PIXEL_BLOCK_VALUES = 1 << 15
"""Values of one channel in one block of rows of the per-pixel pass: its operations run on cache-resident
blocks, each below torch's grain for splitting work between threads (see
:data:`darksynth.noise.spectral.ROW_BLOCK_VALUES`)."""


def level_tables(
    channels: int, darkening: Darkening | None, curve: torch.Tensor, *, device: torch.device | str
) -> tuple[torch.Tensor, torch.Tensor]:
    """(C, 256) darkened signal and (C, 256) noise std of each 8-bit level of each channel, float32: the general
    composer's darkening of ``level / 255`` and the level curve ``curve`` (24,) at that signal."""
    clean = (torch.arange(LEVELS, dtype=torch.float32, device=device) / 255.0).expand(1, channels, 1, LEVELS)
    signal = clean if darkening is None else darken(clean, darkening.alpha, darkening.gamma)
    std = level_std(signal, curve.to(device=device, dtype=torch.float32))
    return signal[0, :, 0].contiguous(), std[0, :, 0].contiguous()


DRAW_SPECTRUM = "spectrum"
DRAW_QUANTIZATION = "quantization"
DrawOrder = tuple[str | int, ...]
"""The per-pixel draws of a clip in the composer's (table) order: :data:`DRAW_SPECTRUM`, :data:`DRAW_QUANTIZATION`,
or the index of a white Gaussian component among the pass's ``white`` ones."""


def white_std_tables(
    signal_table: torch.Tensor, values: Mapping[str, torch.Tensor], white: Sequence[NoiseComponent]
) -> list[torch.Tensor]:
    """(C, 256) std of each ``white`` component at the darkened levels ``signal_table`` (C, 256): the square root
    of its ``white_variance`` law, as the composer's draw computes it per pixel."""
    levels = signal_table[None, :, None, :]  # a clip of one frame, one row of the 256 levels
    tables = []
    for component in white:
        assert component.white_variance is not None
        tables.append(component.white_variance(values, levels).sqrt()[0, :, 0].contiguous())
    return tables


def read_levels(frame: torch.Tensor, table: torch.Tensor, out: torch.Tensor) -> torch.Tensor:
    """``out`` (C, H, W) float32 = ``table`` (C, 256) at each value of the uint8 ``frame`` (C, H, W), channel by
    channel; ``frame`` and ``out`` contiguous."""
    if frame.device.type != "cpu":
        return read_levels_by_index(frame, table, out)
    import cv2  # only this path needs it; importing it costs start-up time

    # OpenCV reads 8-bit indices directly: torch's gathers need a 64- or 32-bit index array of the frame's size
    # first (three table reads of a 1080p frame: 8 ms against 35 ms with int32 indices).
    for channel in range(frame.shape[0]):
        cv2.LUT(frame[channel].numpy(), table[channel].numpy(), dst=out[channel].numpy())
    return out


def read_levels_by_index(frame: torch.Tensor, table: torch.Tensor, out: torch.Tensor) -> torch.Tensor:
    """:func:`read_levels` with torch's indexing, on any device."""
    offsets = torch.arange(frame.shape[0], device=frame.device).reshape(-1, 1, 1) * LEVELS
    out.copy_(table.reshape(-1)[frame.long() + offsets])
    return out


class SpectralPixelPass:
    """The per-pixel work of one 8-bit clip: frame-sized work arrays reused from frame to frame, the level tables
    of its darkening and curve, and the constants of its quantization."""

    def __init__(
        self,
        channels: int,
        height: int,
        width: int,
        darkening: Darkening | None,
        curve: torch.Tensor,
        quantization: float,
        *,
        device: torch.device | str,
        texture: tuple[float, float] | None = None,
        white: Sequence[NoiseComponent] = (),
        values: Mapping[str, torch.Tensor] | None = None,
        order: DrawOrder | None = None,
    ) -> None:
        self.shape, self.device = (channels, height, width), device
        # (texture_gain, texture_scale) when the noise follows texture: the std times the composer's factor, read
        # on the darkened signal before the column pattern is added, as the composer reads it.
        self.texture = texture
        # The white Gaussian components (their laws read ``values``), drawn and summed in ``order``.
        self.white, self.values = tuple(white), values
        self.order: DrawOrder = order if order is not None else (DRAW_SPECTRUM, DRAW_QUANTIZATION)
        self.set_darkening(darkening, curve)
        self.signal = torch.empty(self.shape, dtype=torch.float32, device=device)
        self.noise = torch.empty_like(self.signal)
        self.white_normals = [torch.empty_like(self.signal) for _ in self.white]
        self.white_std = [torch.empty_like(self.signal) for _ in self.white]
        self.quantization_levels = torch.empty(self.shape, dtype=torch.uint8, device=device)
        self.quantization_step: torch.Tensor | None = None
        if quantization > 0:
            # As the composer: the step a float32, its 1/256 exact.
            self.quantization_step = torch.tensor(quantization, dtype=torch.float32) / QUANTIZATION_LEVELS
        self.block_rows = max(1, PIXEL_BLOCK_VALUES // width)

    def set_darkening(self, darkening: Darkening | None, curve: torch.Tensor) -> None:
        """The tables of another darkening (a frame's flicker gain)."""
        self.signal_table, self.std_table = level_tables(self.shape[0], darkening, curve, device=self.device)
        self.white_tables = white_std_tables(self.signal_table, self.values or {}, self.white)

    def draw(self, item: str | int, generator: torch.Generator | None) -> None:
        """Draw the quantization bytes or a white component's normals (``item`` of :data:`DrawOrder`) of the next
        frame, as the composer draws them (one draw over the whole frame, in memory order)."""
        if item == DRAW_QUANTIZATION:
            if self.quantization_step is not None:
                self.quantization_levels.random_(generator=generator)
        elif isinstance(item, int):
            normals = self.white_normals[item]
            torch.randn(normals.shape, generator=generator, out=normals)

    def noisy(
        self,
        frame: torch.Tensor,
        unit: torch.Tensor,
        columns: torch.Tensor | None,
        *,
        rounded: bool,
    ) -> torch.Tensor:
        """signal + columns + the per-pixel terms summed in the composer's order (the white components' std times
        their normals, the spectrum's std times ``unit``, the quantization), clipped to [0, 1]: (C, H, W) float32,
        a view of this pass's own array valid until the next call; with ``rounded``, a new uint8 frame of it
        instead, rounded as :func:`to_8bit` rounds. The quantization bytes and the white normals are those of
        :meth:`draw`.

        Args:
            frame: the uint8 frame (C, H, W).
            unit: the spectral unit noise of the frame (C, H, W), already drawn.
            columns: the column components' pattern (C, 1, W), already drawn; None when none is active.
            rounded: return the 8-bit frame (when no output stage comes after).
        """
        frame = frame.contiguous()
        read_levels(frame, self.signal_table, self.signal)
        read_levels(frame, self.std_table, self.noise)
        for table, std in zip(self.white_tables, self.white_std, strict=True):
            read_levels(frame, table, std)
        factor = None if self.texture is None else texture_modulation(self.signal, *self.texture)[0]
        out = torch.empty(self.shape, dtype=torch.uint8, device=frame.device) if rounded else None
        for start in range(0, self.shape[1], self.block_rows):
            rows = slice(start, start + self.block_rows)
            for channel in range(self.shape[0]):
                signal, noise = self.signal[channel, rows], self.noise[channel, rows]
                noise.mul_(unit[channel, rows])
                if factor is not None:
                    noise.mul_(factor[rows])
                total = self._summed(noise, channel, rows)
                if columns is not None:
                    signal.add_(columns[channel])
                signal.add_(total).clamp_(0.0, 1.0)
                if out is not None:
                    # round() to nearest even by the float32 rounding of adding 2^23 (exact for 0 <= x < 2^22):
                    # the same bits as torch's round_, which on blocks this small still waits for a second
                    # thread (6 ms a block on a busy machine, against 20 us for an addition).
                    out[channel, rows].copy_(signal.mul_(255.0).add_(_ROUNDING).sub_(_ROUNDING))
        return self.signal if out is None else out

    def _summed(self, spectral: torch.Tensor, channel: int, rows: slice) -> torch.Tensor:
        """The block's per-pixel terms summed in :attr:`order`, as the composer sums its components (``spectral``,
        the spectrum's term, is overwritten)."""
        step = self.quantization_step
        if self.order == (DRAW_SPECTRUM, DRAW_QUANTIZATION) or self.order == (DRAW_SPECTRUM,):
            if step is not None:
                # (level + 0.5) * step / 256, the composer's uniform_levels_to_noise, added to the spectral
                # noise before the signal as the composer sums its per-pixel components.
                spectral.add_(torch.add(self.quantization_levels[channel, rows], 0.5).mul_(step))
            return spectral
        total: torch.Tensor | None = None
        for item in self.order:
            if item == DRAW_SPECTRUM:
                term = spectral
            elif item == DRAW_QUANTIZATION:
                if step is None:
                    continue
                term = torch.add(self.quantization_levels[channel, rows], 0.5).mul_(step)
            else:
                assert isinstance(item, int)
                term = self.white_std[item][channel, rows] * self.white_normals[item][channel, rows]
            total = term if total is None else total + term
        assert total is not None
        return total


def to_8bit(noisy: torch.Tensor) -> torch.Tensor:
    """The [0, 1] image as uint8, rounded as :func:`darksynth.synthesize` rounds every float result (``noisy``
    is overwritten)."""
    return noisy.mul_(255.0).round_().to(torch.uint8)


__all__ = [
    "DRAW_QUANTIZATION",
    "DRAW_SPECTRUM",
    "SPECTRAL_PATH",
    "DrawOrder",
    "SpectralPixelPass",
    "level_tables",
    "read_levels",
    "read_levels_by_index",
    "to_8bit",
    "white_std_tables",
]
