"""Noise with a measured spectrum: per-octave colour covariances, a per-channel level curve, AR(1) in time.

Real sRGB noise is not one Gaussian blob per channel. Demosaicing, in-camera denoising, 4:2:0 chroma and JPEG
leave a fine brightness grain over coarse colour mottle (colour noise 8-75x white noise's power at 16-64 px on
the real pairs), channels that are far less alike at coarse scales than at fine ones, and in video a frame-to-
frame persistence (codecs, temporal denoisers). This module draws noise whose cross-spectrum between the colour
components is given per octave, so all of that is one set of numbers that can be measured on a reference.

The model (``u`` unit noise, ``x`` the darkened signal, ``c`` a channel, ``f`` radial frequency in cycles/px):

* colour basis: brightness ``(R + G + B) / sqrt 3`` and colour ``(R - B) / sqrt 2``, ``(R - 2G + B) / sqrt 6``
  (:data:`OPPONENT_BASIS`, orthonormal, so white RGB noise is white in it too);
* per octave ``k`` (node frequency :data:`OCTAVE_FREQUENCIES` ``[k]``, 0.35 cycles/px halving to 0.011), a
  3x3 covariance ``C_k`` of the three components' power spectral density, relative to white noise of unit
  variance: the diagonal is ``octave_power`` (1 = as white noise), the correlations ``octave_correlation``;
* between nodes the covariance is interpolated linearly in log2 f, held constant beyond the first and last;
* the RGB noise is ``B^T`` times the field of that spectrum (drawn on an FFT grid padded by a margin, so the
  frame does not wrap around), each channel divided by its std over the continuous frequency square (so ``u``
  has unit variance per channel whatever the frame size);
* noise = ``s_c(x_c) u_c``, ``s_c`` piecewise linear through ``level_curve``'s std at the intensities
  :data:`LEVEL_KNOTS`;
* time: the white field behind each frequency follows an AR(1) ``w_t = rho(f) w_{t-1} + sqrt(1 - rho(f)^2) e_t``,
  ``rho`` interpolated between the octaves' ``temporal_correlation`` like the covariances: each frame has the
  same spectrum, and its correlation with the next frame is ``rho`` octave by octave.

Every quantity is in pixels or cycles per pixel, so it does not depend on the image size.

References: Lebrun, Colom and Morel 2015, "The Noise Clinic" (noise per frequency and intensity in JPEG
images); Norkin and Birkbeck 2018, "Film grain synthesis for AV1 video codec" (grain with its own spatial
spectrum, intensity scaling curves, blind estimation from video).
"""

from __future__ import annotations

import functools
import math
import threading
from collections import OrderedDict
from collections.abc import MutableMapping
from dataclasses import dataclass

import torch

OCTAVES = 6
"""Octaves of the spectrum, finest first."""

OCTAVE_FREQUENCIES: tuple[float, ...] = tuple(2.0 ** (-1.5 - k) for k in range(OCTAVES))
"""Node frequency of each octave in cycles/px, finest first: 0.354, 0.177, ..., 0.011 (wavelengths 2.8-90 px),
the geometric centres of the bands [1/4, 1/2), [1/8, 1/4), ..., [1/128, 1/64)."""

LEVEL_KNOTS: tuple[float, ...] = tuple((j / 7.0) ** 2 for j in range(8))
"""Intensities of the level curve's knots: denser in the dark, where low-light pixels lie (0, 0.02, 0.08, ...)."""

OPPONENT_BASIS = torch.tensor(
    [
        [1.0 / math.sqrt(3.0), 1.0 / math.sqrt(3.0), 1.0 / math.sqrt(3.0)],
        [1.0 / math.sqrt(2.0), 0.0, -1.0 / math.sqrt(2.0)],
        [1.0 / math.sqrt(6.0), -2.0 / math.sqrt(6.0), 1.0 / math.sqrt(6.0)],
    ],
    dtype=torch.float64,
)
"""Rows: brightness, colour (red - blue), colour (magenta - green); orthonormal."""

CORRELATION_PAIRS = ((0, 1), (0, 2), (1, 2))
"""The component pairs of ``octave_correlation``: brightness-colour1, brightness-colour2, colour1-colour2."""

RADIAL_TABLE_SIZE = 1024
"""Entries of the radial tables over [0, sqrt 2 / 2] cycles/px: the spectrum is read from them by nearest entry."""

NORMALISATION_GRID = 512
"""Side of the frequency grid on which the unit variance is computed (independent of the frame's size)."""

MARGIN = 32
"""Pixels of padding on each side of the FFT grid, so that coarse noise does not wrap from one edge to the other."""

_MAX_FREQUENCY = math.sqrt(0.5)


def octave_weights(frequency: torch.Tensor) -> torch.Tensor:
    """Hat weights (..., OCTAVES) of each octave at radial frequencies ``frequency`` (cycles/px): linear in log2 f
    between neighbouring nodes, summing to 1, the end nodes held beyond the ends."""
    position = -torch.log2(frequency.clamp_min(1e-9)) - 1.5  # 0 at the first node, 1 at the next...
    position = position.clamp(0.0, OCTAVES - 1.0)
    nodes = torch.arange(OCTAVES, dtype=frequency.dtype, device=frequency.device)
    return (1.0 - (position[..., None] - nodes).abs()).clamp_min(0.0)


def octave_covariances(power: torch.Tensor, correlation: torch.Tensor) -> torch.Tensor:
    """The (..., OCTAVES, 3, 3) covariances in the colour basis from ``octave_power`` (..., OCTAVES * 3) and
    ``octave_correlation`` (..., OCTAVES * 3), octave-major; inconsistent correlations are repaired (eigenvalues
    raised to 1e-4 of the largest, the diagonal kept)."""
    power = power.reshape(*power.shape[:-1], OCTAVES, 3).to(torch.float64).clamp_min(0.0)
    rho = correlation.reshape(*correlation.shape[:-1], OCTAVES, 3).to(torch.float64)
    unit = torch.eye(3, dtype=torch.float64, device=power.device).expand(*rho.shape[:-1], 3, 3).clone()
    for index, (i, j) in enumerate(CORRELATION_PAIRS):
        unit[..., i, j] = unit[..., j, i] = rho[..., index]
    eigenvalues, eigenvectors = torch.linalg.eigh(unit)
    floor = 1e-4 * eigenvalues[..., -1:].clamp_min(1e-12)
    repaired = eigenvectors @ torch.diag_embed(torch.maximum(eigenvalues, floor)) @ eigenvectors.transpose(-1, -2)
    scale = repaired.diagonal(dim1=-2, dim2=-1).rsqrt()
    repaired = repaired * scale[..., :, None] * scale[..., None, :]
    std = power.sqrt()
    covariance: torch.Tensor = repaired * std[..., :, None] * std[..., None, :]
    return covariance


def covariance_parameters(covariances: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The inverse of :func:`octave_covariances`: (``octave_power``, ``octave_correlation``), each
    (..., OCTAVES * 3), from covariances (..., OCTAVES, 3, 3) in the colour basis."""
    power = covariances.diagonal(dim1=-2, dim2=-1).clamp_min(0.0)
    std = power.clamp_min(1e-30).sqrt()
    rho = torch.stack([covariances[..., i, j] / (std[..., i] * std[..., j]) for i, j in CORRELATION_PAIRS], dim=-1)
    return power.flatten(-2), rho.clamp(-0.99, 0.99).flatten(-2)


def _radial_frequencies(device: torch.device | str = "cpu") -> torch.Tensor:
    return torch.linspace(0.0, _MAX_FREQUENCY, RADIAL_TABLE_SIZE, dtype=torch.float64, device=device)


def grid_radius(height: int, width: int, device: torch.device | str) -> torch.Tensor:
    """Radial frequency (cycles/px) of each bin of an rfft2 grid of (height, width): (height, width // 2 + 1)."""
    fy = torch.fft.fftfreq(height, dtype=torch.float64, device=device)
    fx = torch.fft.rfftfreq(width, dtype=torch.float64, device=device)
    return torch.sqrt(fy[:, None] ** 2 + fx[None, :] ** 2)


@functools.lru_cache(maxsize=2)
def _octave_mass(device: str) -> torch.Tensor:
    """(1, OCTAVES) each octave's hat weight summed over the :data:`NORMALISATION_GRID` frequency square."""
    grid = grid_radius(NORMALISATION_GRID, NORMALISATION_GRID, device)
    # rfft grid: the columns other than 0 and Nyquist stand for two bins of the full square.
    weights = torch.full(grid.shape, 2.0, dtype=torch.float64, device=grid.device)
    weights[:, 0] = weights[:, -1] = 1.0
    return (octave_weights(grid.reshape(-1)) * weights.reshape(-1, 1)).sum(0, keepdim=True)


def _rgb_covariance(covariances: torch.Tensor, frequency: torch.Tensor, channels: int) -> torch.Tensor:
    """The (..., F, C, C) RGB (or grey) spectral covariance at ``frequency`` (F,) for one clip's (OCTAVES, 3, 3),
    or for octave weights (F, OCTAVES) given in place of the frequencies."""
    weights = octave_weights(frequency) if frequency.dim() == 1 else frequency
    opponent = torch.einsum("fk,kij->fij", weights, covariances)
    if channels == 1:
        return opponent[..., :1, :1]
    basis = OPPONENT_BASIS.to(covariances.device)
    return basis.T @ opponent @ basis


def radial_factor(covariances: torch.Tensor, channels: int) -> torch.Tensor:
    """(RADIAL_TABLE_SIZE, C, C) factor ``F(r)`` of the unit-variance spectral covariance, float64: the noise at a
    frequency of radius r is ``F(r) w`` for white ``w``. ``covariances`` (OCTAVES, 3, 3) in the colour basis.

    The unit variance is each channel's integral of its spectral density over the frequency square, evaluated on
    a fixed :data:`NORMALISATION_GRID` grid, so it is the same for every frame size."""
    # The spectral density is linear in the octaves' covariances, so its integral is the octaves' covariances
    # weighted by their hats' integrals: 6 numbers instead of a 512 x 257 grid of 3 x 3 matrices per spectrum.
    octave_mass = _octave_mass(str(covariances.device))
    variance = _rgb_covariance(covariances, octave_mass, channels).diagonal(dim1=-2, dim2=-1)[0]
    scale = (variance / float(NORMALISATION_GRID**2)).clamp_min(1e-30).rsqrt()
    table = _rgb_covariance(covariances, _radial_frequencies(covariances.device), channels)
    table = table * scale[:, None] * scale[None, :]
    # A covariance is factored by its eigen-decomposition, which, unlike Cholesky, takes singular ones (a channel
    # pair with correlation 1 at some octave).
    eigenvalues, eigenvectors = torch.linalg.eigh(table)
    factor: torch.Tensor = eigenvectors * eigenvalues.clamp_min(0.0).sqrt()[..., None, :]
    return factor


def radial_correlation(temporal: torch.Tensor) -> torch.Tensor:
    """(RADIAL_TABLE_SIZE,) AR(1) coefficient at each radial frequency from ``temporal_correlation`` (OCTAVES,)."""
    return octave_weights(_radial_frequencies(temporal.device)) @ temporal.to(torch.float64).clamp(0.0, 0.999)


def fft_size(size: int) -> int:
    """The smallest size >= ``size`` with no prime factor above 5, which FFT libraries transform fastest."""
    candidate = size
    while True:
        rest = candidate
        for prime in (2, 3, 5):
            while rest % prime == 0:
                rest //= prime
        if rest == 1:
            return candidate
        candidate += 1


@dataclass(frozen=True)
class SpectralTables:
    """What one spectrum needs on one FFT grid, the same for every frame and every clip of it (cached by
    :func:`spectral_tables`): the factor of each frequency bin and the AR(1) coefficients.

    Attributes:
        grid_height: rows of the FFT grid (the frame's height plus the margins, rounded up to a fast size).
        grid_width: columns of the FFT grid, of which the rfft grid keeps ``grid_width // 2 + 1``.
        terms: the (target, source) channel of each factor entry, in the order :meth:`SpectralGrid.frame` sums
            them: for each target channel, its sources in order.
        factors: (terms, rows, 2 * rfft columns) each entry's value at each bin, repeated for the bin's real
            and imaginary parts so that the mixing runs over contiguous memory; scaled for irfft2's 1/N.
        rho: (rows, 2 * rfft columns) AR(1) coefficient per bin, likewise repeated; None without temporal
            correlation.
        innovation: sqrt(1 - rho^2), likewise; None without temporal correlation.
    """

    grid_height: int
    grid_width: int
    terms: tuple[tuple[int, int], ...]
    factors: torch.Tensor
    rho: torch.Tensor | None
    innovation: torch.Tensor | None


def radial_index(grid_height: int, grid_width: int, device: torch.device | str) -> torch.Tensor:
    """(rows, rfft columns) int64 entry of the radial tables nearest to each bin's radial frequency."""
    radius = grid_radius(grid_height, grid_width, device)
    return (radius * ((RADIAL_TABLE_SIZE - 1) / _MAX_FREQUENCY)).round().long().clamp_max(RADIAL_TABLE_SIZE - 1)


def grid_size(height: int, width: int) -> tuple[int, int]:
    """The FFT grid of frames of (``height``, ``width``): the frame plus :data:`MARGIN` on each side, each side
    rounded up to a fast size."""
    return fft_size(height + 2 * MARGIN), fft_size(width + 2 * MARGIN)


def _mixing_terms(channels: int) -> tuple[tuple[int, int], ...]:
    return tuple((target, source) for target in range(channels) for source in range(channels))


def _repeat_for_real_and_imaginary(table: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """(rows, 2 * columns) of ``table`` (RADIAL_TABLE_SIZE,) read at ``index`` (rows, columns), each value twice."""
    values = table[index]
    return values[..., None].expand(*values.shape, 2).reshape(values.shape[0], -1)


def _build_tables(
    covariances: torch.Tensor,
    temporal: torch.Tensor,
    channels: int,
    grid_height: int,
    grid_width: int,
    device: torch.device | str,
    dtype: torch.dtype,
) -> SpectralTables:
    index = radial_index(grid_height, grid_width, device)
    # irfft2 divides by the bin count N; a white field of unit variance has coefficients of mean square N,
    # i.e. N / 2 in each of the real and imaginary parts drawn here.
    scale = math.sqrt(grid_height * grid_width / 2.0)
    factor = radial_factor(covariances.to(device), channels) * scale
    terms = _mixing_terms(channels)
    factors = torch.stack(
        [_repeat_for_real_and_imaginary(factor[:, target, source].to(dtype), index) for target, source in terms]
    )
    rho = radial_correlation(temporal.to(device))
    if not bool((rho > 0).any()):
        return SpectralTables(grid_height, grid_width, terms, factors, None, None)
    innovation = (1.0 - rho.square()).sqrt()
    return SpectralTables(
        grid_height,
        grid_width,
        terms,
        factors,
        _repeat_for_real_and_imaginary(rho.to(dtype), index),
        _repeat_for_real_and_imaginary(innovation.to(dtype), index),
    )


TABLE_CACHE_SIZE = 2
"""Spectra (with their grid size) whose tables are kept: a stream, or training on crops of one size, builds them
once instead of once per clip; each takes about 55 MB at 1080p, so only the last few are kept."""

_table_cache: OrderedDict[tuple[object, ...], SpectralTables] = OrderedDict()
_table_cache_lock = threading.Lock()


def spectral_tables(
    covariances: torch.Tensor,
    temporal: torch.Tensor,
    channels: int,
    height: int,
    width: int,
    *,
    device: torch.device | str,
    dtype: torch.dtype = torch.float32,
) -> SpectralTables:
    """The tables of a spectrum (``covariances`` (OCTAVES, 3, 3), ``temporal`` (OCTAVES,)) for frames of
    (``height``, ``width``), from a small cache of the last :data:`TABLE_CACHE_SIZE` ones (building them costs
    about as much as drawing a frame)."""
    grid_height, grid_width = grid_size(height, width)
    key = (
        covariances.detach().to("cpu", torch.float64).numpy().tobytes(),
        temporal.detach().to("cpu", torch.float64).numpy().tobytes(),
        channels,
        grid_height,
        grid_width,
        str(torch.device(device)),
        dtype,
    )
    with _table_cache_lock:
        found = _table_cache.get(key)
        if found is not None:
            _table_cache.move_to_end(key)
            return found
    tables = _build_tables(covariances, temporal, channels, grid_height, grid_width, device, dtype)
    with _table_cache_lock:
        _table_cache[key] = tables
        while len(_table_cache) > TABLE_CACHE_SIZE:
            _table_cache.popitem(last=False)
    return tables


ROW_BLOCK_VALUES = 1 << 15
"""Values per channel in one block of rows of the frequency grid. The white field of a block is drawn, carried
forward in time and mixed while it is in the processor's cache (whole-frame arrays would stream through memory
once per mixing term), and each operation on a block is below torch's grain for splitting work between threads
(32768 values), so it runs on the calling thread alone: with another process busy on a 2-core machine, 2-thread
operations on blocks of 2^17 values waited for each other far longer than they worked (800 against 65 ms a
1080p frame; 146 ms unblocked)."""


class SpectralGrid:
    """One clip's spectrum on one frame size's FFT grid, and the clip's state: the white field of the previous
    frame, for the temporal correlation.

    Built once per clip and size (a stream reuses it for every frame) on the ``tables`` of
    :func:`spectral_tables` for the same channels and frame size, on their device and in their dtype; its
    frame-sized work arrays are its own and reused from frame to frame."""

    def __init__(self, tables: SpectralTables, channels: int, height: int, width: int) -> None:
        self.channels, self.height, self.width = channels, height, width
        self.tables = tables
        self.grid_height, self.grid_width = tables.grid_height, tables.grid_width
        self.temporal = tables.rho is not None
        rows, values = tables.factors.shape[-2:]
        # The real and imaginary parts of each rfft bin, side by side: (C, rows, 2 * rfft columns).
        self._white = tables.factors.new_empty((channels, rows, values))
        self._mixed = torch.empty_like(self._white)
        # With temporal correlation the white field is the state carried to the next frame.
        self._state: torch.Tensor | None = torch.empty_like(self._white) if self.temporal else None
        self._started = False
        self._block_rows = max(1, ROW_BLOCK_VALUES // values)

    def frame(self, generator: torch.Generator) -> torch.Tensor:
        """The unit noise of the next frame, (C, height, width)."""
        tables = self.tables
        rows = self._white.shape[1]
        # One draw over the whole field, as the first version of this model drew it: the same numbers, on which
        # its estimates and their tests were made.
        self._white.normal_(generator=generator)
        for start in range(0, rows, self._block_rows):
            block = slice(start, start + self._block_rows)
            source, mixed = self._white[:, block], self._mixed[:, block]
            if self._state is not None and tables.rho is not None and tables.innovation is not None:
                state = self._state[:, block]
                if self._started:
                    # Two products and a sum, not addcmul, whose fused multiply-add rounds differently.
                    state.mul_(tables.rho[block]).add_(source.mul_(tables.innovation[block]))
                else:
                    state.copy_(source)
                source = state
            for factor, (target, term_source) in zip(tables.factors[:, block], tables.terms, strict=True):
                if term_source == 0:
                    torch.mul(factor, source[0], out=mixed[target])
                else:
                    mixed[target].addcmul_(factor, source[term_source])
        self._started = True
        spectrum = torch.view_as_complex(self._mixed.view(self.channels, rows, -1, 2))
        # Not into a kept array: irfft2's out= computes into a new one and copies it (15 ms more a 1080p frame).
        field = torch.fft.irfft2(spectrum, s=(self.grid_height, self.grid_width))
        return crop_unit(field, self.height, self.width)


def crop_unit(field: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """The frame's part (C, height, width) of an inverse FFT's grid (C, grid rows, grid columns): inside the
    :data:`MARGIN`."""
    unit: torch.Tensor = field[:, MARGIN : MARGIN + height, MARGIN : MARGIN + width]
    return unit


LEVEL_GRID_STEPS = 49
"""The knots (j / 7)^2 = j^2 / 49 all lie on the uniform grid of step 1/49, so the level curve is linear between
neighbouring points of that grid: a value's piece is floor(49 x), found by arithmetic instead of a search."""


def level_pieces(curve: torch.Tensor, channels: int, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """(C, LEVEL_GRID_STEPS, 2) intercept and slope of the level curve ``curve`` (24,) on each step of the uniform
    grid, in the variable u = 49 x: the std at x is ``intercept + slope * u`` of piece ``floor(u)``."""
    table = curve.reshape(3, len(LEVEL_KNOTS)).to(torch.float64)
    if channels == 1:
        table = table[1:2]
    steps = torch.arange(LEVEL_GRID_STEPS + 1, dtype=torch.float64, device=curve.device)
    # Grid point j = x * 49 lies in the knot segment k = floor(sqrt(j)) (knot k is at k^2 / 49).
    segment = steps.sqrt().floor().clamp_max(len(LEVEL_KNOTS) - 2).long()
    fraction = (steps - segment.square()) / (2 * segment + 1)
    values = table[:, segment] * (1.0 - fraction) + table[:, segment + 1] * fraction
    slope = values[:, 1:] - values[:, :-1]
    intercept = values[:, :-1] - slope * steps[:-1]
    return torch.stack([intercept, slope], dim=-1).to(dtype)


def level_std(signal: torch.Tensor, curve: torch.Tensor) -> torch.Tensor:
    """The noise std of each pixel of ``signal`` (..., C, H, W) from ``level_curve`` (3 * 8: red's, green's, then
    blue's std at :data:`LEVEL_KNOTS`), piecewise linear between knots, held beyond them; a grey signal takes
    green's curve."""
    channels = signal.shape[-3]
    pieces = level_pieces(curve, channels, signal.dtype).to(signal.device)
    position = signal.clamp(0.0, 1.0).mul_(float(LEVEL_GRID_STEPS))
    piece = position.to(torch.int32).clamp_max_(LEVEL_GRID_STEPS - 1)
    # Each channel reads its own rows of the flattened (C * steps) tables.
    offsets = torch.arange(channels, dtype=torch.int32, device=signal.device) * LEVEL_GRID_STEPS
    index = piece.add_(offsets.reshape(-1, 1, 1)).reshape(-1)
    intercept = pieces[..., 0].reshape(-1).index_select(0, index).view(position.shape)
    slope = pieces[..., 1].reshape(-1).index_select(0, index).view(position.shape)
    return intercept.addcmul_(slope, position)


def clip_grid(
    covariances: torch.Tensor,
    temporal: torch.Tensor,
    frame_shape: torch.Size | tuple[int, ...],
    *,
    device: torch.device | str,
    dtype: torch.dtype,
    state: MutableMapping[str, SpectralGrid] | None,
) -> SpectralGrid:
    """The grid of a clip with frames (C, H, W) ``frame_shape``: the one a stream holds in ``state`` under
    ``"spectral"`` (a new one, kept there, at the first frame or a new frame size), a new one without a state."""
    channels, height, width = frame_shape
    grid = None if state is None else state.get("spectral")
    if grid is None or (grid.channels, grid.height, grid.width) != (channels, height, width):
        tables = spectral_tables(covariances, temporal, channels, height, width, device=device, dtype=dtype)
        grid = SpectralGrid(tables, channels, height, width)
        if state is not None:
            state["spectral"] = grid
    return grid


def spectral_clip_noise(
    signal: torch.Tensor,
    curve: torch.Tensor,
    covariances: torch.Tensor,
    temporal: torch.Tensor,
    *,
    generator: torch.Generator,
    state: MutableMapping[str, SpectralGrid] | None = None,
) -> torch.Tensor:
    """The spectral noise of one clip ``signal`` (T, C, H, W) in [0, 1], frame after frame.

    Args:
        signal: the darkened clean clip.
        curve: ``level_curve`` (24,).
        covariances: (OCTAVES, 3, 3) from :func:`octave_covariances`.
        temporal: ``temporal_correlation`` (OCTAVES,).
        generator: source of randomness.
        state: a stream's held objects; the grid (and the previous frame's white field) is kept there under
            ``"spectral"`` so the next call continues the clip. None: a clip of its own.
    """
    grid = clip_grid(covariances, temporal, signal.shape[-3:], device=signal.device, dtype=signal.dtype, state=state)
    noise = level_std(signal, curve)
    for frame in noise:
        frame.mul_(grid.frame(generator))
    return noise
