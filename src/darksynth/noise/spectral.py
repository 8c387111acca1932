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

import math
from collections.abc import MutableMapping

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


def _grid_radius(height: int, width: int, device: torch.device | str) -> torch.Tensor:
    """Radial frequency (cycles/px) of each bin of an rfft2 grid of (height, width): (height, width // 2 + 1)."""
    fy = torch.fft.fftfreq(height, dtype=torch.float64, device=device)
    fx = torch.fft.rfftfreq(width, dtype=torch.float64, device=device)
    return torch.sqrt(fy[:, None] ** 2 + fx[None, :] ** 2)


def _rgb_covariance(covariances: torch.Tensor, frequency: torch.Tensor, channels: int) -> torch.Tensor:
    """The (..., F, C, C) RGB (or grey) spectral covariance at ``frequency`` (F,) for one clip's (OCTAVES, 3, 3)."""
    opponent = torch.einsum("fk,kij->fij", octave_weights(frequency), covariances)
    if channels == 1:
        return opponent[..., :1, :1]
    basis = OPPONENT_BASIS.to(covariances.device)
    return basis.T @ opponent @ basis


def radial_factor(covariances: torch.Tensor, channels: int) -> torch.Tensor:
    """(RADIAL_TABLE_SIZE, C, C) factor ``F(r)`` of the unit-variance spectral covariance, float64: the noise at a
    frequency of radius r is ``F(r) w`` for white ``w``. ``covariances`` (OCTAVES, 3, 3) in the colour basis.

    The unit variance is each channel's integral of its spectral density over the frequency square, evaluated on
    a fixed :data:`NORMALISATION_GRID` grid, so it is the same for every frame size."""
    grid = _grid_radius(NORMALISATION_GRID, NORMALISATION_GRID, covariances.device)
    # rfft grid: the columns other than 0 and Nyquist stand for two bins of the full square.
    weights = torch.full(grid.shape, 2.0, dtype=torch.float64, device=grid.device)
    weights[:, 0] = weights[:, -1] = 1.0
    full = _rgb_covariance(covariances, grid.reshape(-1), channels)
    variance = (full.diagonal(dim1=-2, dim2=-1) * weights.reshape(-1, 1)).sum(0) / float(NORMALISATION_GRID**2)
    scale = variance.clamp_min(1e-30).rsqrt()
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


def _fft_size(size: int) -> int:
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


class SpectralGrid:
    """The per-frequency factor and AR(1) coefficient of one clip's spectrum on one frame size's FFT grid.

    Built once per clip and size (a stream reuses it for every frame); the white field of the previous frame is
    its state for the temporal correlation."""

    def __init__(
        self,
        covariances: torch.Tensor,
        temporal: torch.Tensor,
        channels: int,
        height: int,
        width: int,
        *,
        device: torch.device | str,
        dtype: torch.dtype = torch.float32,
    ) -> None:
        self.channels, self.height, self.width = channels, height, width
        self.grid_height = _fft_size(height + 2 * MARGIN)
        self.grid_width = _fft_size(width + 2 * MARGIN)
        radius = _grid_radius(self.grid_height, self.grid_width, device)
        index = (radius * ((RADIAL_TABLE_SIZE - 1) / _MAX_FREQUENCY)).round().long().clamp_max(RADIAL_TABLE_SIZE - 1)
        factor = radial_factor(covariances.to(device), channels)
        # (C, C, h, w): one real matrix per frequency bin; the spectrum is real and symmetric, so it multiplies the
        # real and imaginary parts of the white field alike.
        # irfft2 divides by the bin count N; a white field of unit variance has coefficients of mean square N,
        # i.e. N / 2 in each of the real and imaginary parts drawn here.
        scale = math.sqrt(self.grid_height * self.grid_width / 2.0)
        self.factor = (factor[index].permute(2, 3, 0, 1) * scale).to(dtype).contiguous()
        rho = radial_correlation(temporal.to(device))
        self.temporal = bool((rho > 0).any())
        self.rho = rho[index].to(dtype)[..., None]
        self.innovation = (1.0 - rho[index].square()).sqrt().to(dtype)[..., None]
        self.previous: torch.Tensor | None = None
        self.dtype = dtype

    def frame(self, generator: torch.Generator) -> torch.Tensor:
        """The unit noise of the next frame, (C, height, width)."""
        shape = (self.channels, *self.factor.shape[-2:], 2)
        white = torch.randn(shape, generator=generator, dtype=self.dtype, device=self.factor.device)
        if self.temporal:
            if self.previous is not None:
                white = self.previous * self.rho + white * self.innovation
            self.previous = white
        coloured = self.factor[:, 0, ..., None] * white[0]
        for source in range(1, self.channels):
            coloured.addcmul_(self.factor[:, source, ..., None], white[source])
        field = torch.fft.irfft2(torch.view_as_complex(coloured), s=(self.grid_height, self.grid_width))
        unit: torch.Tensor = field[:, MARGIN : MARGIN + self.height, MARGIN : MARGIN + self.width]
        return unit


def level_std(signal: torch.Tensor, curve: torch.Tensor) -> torch.Tensor:
    """The noise std of each pixel of ``signal`` (..., C, H, W) from ``level_curve`` (3 * 8: red's, green's, then
    blue's std at :data:`LEVEL_KNOTS`), piecewise linear between knots, held beyond them; a grey signal takes
    green's curve."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=signal.dtype, device=signal.device)
    table = curve.reshape(3, len(LEVEL_KNOTS)).to(signal.dtype)
    if signal.shape[-3] == 1:
        table = table[1:2]
    x = signal.clamp(0.0, 1.0).contiguous()
    index = torch.bucketize(x, knots[1:-1])  # the segment each value falls in, 0..6
    low, high = knots[index], knots[index + 1]
    fraction = (x - low) / (high - low)
    rows = torch.arange(table.shape[0], device=signal.device).reshape(-1, 1, 1).expand_as(x)
    return table[rows, index] * (1.0 - fraction) + table[rows, index + 1] * fraction


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
    frames, channels, height, width = signal.shape
    grid = None if state is None else state.get("spectral")
    if grid is None or (grid.channels, grid.height, grid.width) != (channels, height, width):
        grid = SpectralGrid(covariances, temporal, channels, height, width, device=signal.device, dtype=signal.dtype)
        if state is not None:
            state["spectral"] = grid
    unit = torch.stack([grid.frame(generator) for _ in range(frames)])
    return level_std(signal, curve) * unit
