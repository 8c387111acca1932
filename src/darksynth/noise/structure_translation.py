"""The sRGB structure of version-2 and version-3 profiles (and of the estimation network's vector), drawn as the
spectral model (:mod:`darksynth.noise.spectral`).

Those profiles describe their noise as ``g_c sqrt(shot^2 x + read^2)`` times unit noise whose channels have the
correlations ``R`` (``channel_correlation``) and whose spatial structure is a separable Gaussian kernel of std
``l`` px (``correlation_length``); with a colour length ``e`` (``chroma_length``), the two principal components of
the channel covariance ``S = G R G`` other than the main one take a kernel of std ``sqrt(l^2 + e^2)``. That is a
level curve and a spectrum, which the spectral model holds directly:

* ``level_curve``: ``g_c sqrt(shot^2 x + read^2)`` at each knot, per channel (red, green, blue gains ``g``);
* the spectrum of the unit noise ``G^-1 z'' `` (the gains are in the curve) is, in the colour basis ``B``,
  ``A_main P_l(f) + A_colour P_lc(f)``: ``A`` the components' covariances ``B G^-1 lambda v v^T G^-1 B^T``
  (without a colour length, ``A_main = B R B^T`` and no colour part), ``P_l`` the power spectrum of the
  normalised discrete Gaussian kernel of std ``l`` along x times along y (unit integral over the frequency square);
* each ``P`` becomes one density per octave node, ``p >= 0``, chosen so that the spectral model's density between
  the nodes (hat weights in log frequency) has the kernel's power in each band (the five bands the round trip
  reports plus everything coarser) with the smallest largest relative error (:func:`octave_densities`); the
  octave covariances are ``C_k = A_main p_k(l) + A_colour p_k(lc)``, positive semi-definite by construction.

A Gaussian kernel of 1-3 px falls by one or two orders of magnitude within an octave, faster than the spectral
model's density, linear between nodes an octave apart, can follow: no choice of the nodes puts every band within
16 % of the kernel's power there (27 % near 1.2 and 2.5 px). Kernels under 0.8 px and the level curve translate
exactly up to the curve's linear pieces (docs/spectral-noise.md).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence

import numpy as np
import torch

from darksynth.noise.spectral import (
    LEVEL_KNOTS,
    OCTAVES,
    OPPONENT_BASIS,
    covariance_parameters,
    octave_weights,
)

STRUCTURE_NEUTRAL = {"channel_gain": 1.0, "correlation_length": 0.0, "channel_correlation": 0.0, "chroma_length": 0.0}
"""The parameters of the sRGB structure and their neutral values (the table's): the spectral model takes them over,
with shot and read."""

KERNEL_RADIUS_STDS = 3.0
"""The version-3 model cut its Gaussian kernels at this many standard deviations (at least one pixel each side)."""

LENGTH_STEP = 0.01
"""Kernel lengths are translated on this grid (px): a training batch draws every clip's lengths anew, and the band
powers change by well under 1 % within a step."""

SPECTRUM_GRID = 512
"""Side of the frequency grid the kernels' band powers are integrated on."""

BAND_EDGES = (1 / 4, 1 / 8, 1 / 16, 1 / 32, 1 / 64)
"""Lower edges (cycles/px) of the bands matched, finest first; the last band is everything below 1/64."""


def gaussian_kernel1d(length: float) -> torch.Tensor:
    """The version-3 model's normalised (sum 1) 1-D Gaussian of std ``length`` px, float64; ``[1.]`` at 0."""
    if length < 0.0 or not math.isfinite(length):
        raise ValueError(f"correlation length must be finite and >= 0, got {length}")
    if length == 0.0:
        return torch.ones(1, dtype=torch.float64)
    radius = max(1, math.ceil(KERNEL_RADIUS_STDS * length))
    offsets = torch.arange(-radius, radius + 1, dtype=torch.float64)
    kernel = torch.exp(-0.5 * (offsets / length) ** 2)
    return kernel / kernel.sum()


def valid_channel_correlation(pairs: Sequence[float]) -> torch.Tensor:
    """The (3, 3) correlation matrix of the red-green, green-blue and red-blue coefficients ``pairs``, made
    positive definite when the three are inconsistent (eigenvalues raised to 1e-3, diagonal rescaled to 1),
    float64, as the version-3 model drew it."""
    rg, gb, rb = (float(v) for v in pairs)
    matrix = torch.tensor([[1.0, rg, rb], [rg, 1.0, gb], [rb, gb, 1.0]], dtype=torch.float64)
    eigenvalues, eigenvectors = torch.linalg.eigh(matrix)
    if bool((eigenvalues >= 1e-3).all()):
        return matrix
    repaired: torch.Tensor = eigenvectors @ torch.diag(eigenvalues.clamp_min(1e-3)) @ eigenvectors.T
    scale = repaired.diagonal().rsqrt()
    return repaired * scale[:, None] * scale[None, :]


@functools.cache
def _band_geometry() -> tuple[np.ndarray, np.ndarray]:
    """(band of each bin of the frequency grid, flattened; (bands, OCTAVES) integral of each octave's hat weight
    over each band, as a share of the frequency square)."""
    frequency = np.fft.fftfreq(SPECTRUM_GRID)
    radius = np.sqrt(frequency[:, None] ** 2 + frequency[None, :] ** 2).reshape(-1)
    band = np.full(radius.shape, len(BAND_EDGES), dtype=np.intp)
    for index, edge in reversed(list(enumerate(BAND_EDGES))):
        band[radius >= edge] = index
    weights = octave_weights(torch.from_numpy(radius)).numpy()
    hats = np.stack([np.bincount(band, weights=weights[:, k], minlength=len(BAND_EDGES) + 1) for k in range(OCTAVES)])
    return band, hats.T / radius.size


def _band_powers(length: float) -> np.ndarray:
    """(bands,) the power of unit-variance noise filtered by the kernel of ``length`` in each band: the kernel's
    normalised power spectrum along x times along y, integrated over the band."""
    kernel = gaussian_kernel1d(length).numpy()
    offsets = np.arange(kernel.size) - kernel.size // 2
    frequency = np.fft.fftfreq(SPECTRUM_GRID)
    response = (kernel[None, :] * np.cos(2 * np.pi * frequency[:, None] * offsets[None, :])).sum(axis=1)
    along_axis = response**2 / np.square(kernel).sum()
    band, _ = _band_geometry()
    power = (along_axis[:, None] * along_axis[None, :]).reshape(-1)
    powers: np.ndarray = np.bincount(band, weights=power, minlength=len(BAND_EDGES) + 1) / power.size
    return powers


def non_negative_least_squares(matrix: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The x >= 0 that minimises |matrix x - target|^2, by active sets (Lawson and Hanson 1974, Solving Least
    Squares Problems, ch. 23): variables join the free set by the steepest gradient and leave it when a step would
    make them negative."""
    count = matrix.shape[1]
    solution = np.zeros(count)
    free = np.zeros(count, dtype=bool)
    tolerance = 1e-12 * max(1.0, float(np.abs(matrix).max()))
    for _ in range(3 * count):
        gradient = matrix.T @ (target - matrix @ solution)
        candidates = ~free & (gradient > tolerance)
        if not candidates.any():
            break
        free[np.argmax(np.where(candidates, gradient, -np.inf))] = True
        while True:
            trial = np.zeros(count)
            trial[free] = np.linalg.lstsq(matrix[:, free], target, rcond=None)[0]
            if (trial[free] > 0).all():
                solution = trial
                break
            blocking = free & (trial <= 0)
            step = np.min(solution[blocking] / (solution[blocking] - trial[blocking]))
            solution = solution + step * (trial - solution)
            free &= solution > tolerance
            solution[~free] = 0.0
    return solution


MINIMAX_ITERATIONS = 60
"""Reweightings of :func:`octave_densities`' least squares (Lawson's: each band's weight times its error)."""


@functools.lru_cache(maxsize=1024)
def octave_densities(length: float) -> tuple[float, ...]:
    """(OCTAVES,) node densities, relative to white noise, with which the spectral model's interpolated density
    comes closest to the power of the kernel of ``length`` px in every band: the smallest largest relative error
    over the bands (1 everywhere for a length of 0: white noise).

    Non-negative least squares on the relative errors, reweighted by Lawson's rule (Lawson 1961, Contributions to
    the theory of linear least maximum approximation): the weights grow where the error is largest, which leads to
    the minimax solution; here it reaches the bound the node spacing sets (about 16-27 % for lengths of 1-3 px,
    none below 0.8 px)."""
    if length == 0.0:
        return (1.0,) * OCTAVES
    _, hats = _band_geometry()
    relative = hats / np.maximum(_band_powers(length), 1e-30)[:, None]
    weights = np.ones(relative.shape[0])
    densities = np.ones(OCTAVES)
    for _ in range(MINIMAX_ITERATIONS):
        root = np.sqrt(weights)
        densities = non_negative_least_squares(relative * root[:, None], root)
        error = np.abs(relative @ densities - 1.0)
        if error.max() < 1e-6:
            break
        weights = np.maximum(weights * error / (weights * error).sum(), 1e-12)
    return tuple(float(p) for p in densities)


def _clip_covariances(length: float, chroma: float, pairs: Sequence[float], gains: Sequence[float]) -> torch.Tensor:
    """(OCTAVES, 3, 3) octave covariances in the colour basis of one clip's structure."""
    scale = torch.tensor([gains[0], 1.0, gains[1]], dtype=torch.float64)
    correlation = valid_channel_correlation(pairs)
    basis = OPPONENT_BASIS
    main = torch.tensor(octave_densities(length), dtype=torch.float64)
    if chroma <= 0.0:
        return main[:, None, None] * (basis @ correlation @ basis.T)
    covariance = correlation * scale[:, None] * scale[None, :]
    eigenvalues, eigenvectors = torch.linalg.eigh(covariance)  # ascending: the main component is the last
    unit = eigenvectors / scale[:, None] * eigenvalues.clamp_min(0.0).sqrt()[None, :]
    in_basis = basis @ unit
    main_part = in_basis[:, 2:] @ in_basis[:, 2:].T
    colour_part = in_basis[:, :2] @ in_basis[:, :2].T
    colour = torch.tensor(octave_densities(_on_grid(math.sqrt(length**2 + chroma**2))), dtype=torch.float64)
    covariances: torch.Tensor = main[:, None, None] * main_part + colour[:, None, None] * colour_part
    return covariances


def _on_grid(length: float) -> float:
    return round(length / LENGTH_STEP) * LENGTH_STEP


def _level_curve(shot: float, read: float, gains: Sequence[float]) -> torch.Tensor:
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64)
    std = (shot**2 * knots + read**2).sqrt()
    return torch.cat([gain * std for gain in (gains[0], 1.0, gains[1])])


def structure_set(values: Mapping[str, torch.Tensor]) -> torch.Tensor:
    """(*batch,) bool: the clips whose sRGB structure is set (some structure parameter not neutral)."""
    flags = [(values[name] != value).any(dim=-1) for name, value in STRUCTURE_NEUTRAL.items()]
    return torch.stack(flags).any(dim=0)


def spectral_tensors(values: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The values with the sRGB structure of every clip that has one drawn as the spectral model: its
    ``level_curve``, ``octave_power`` and ``octave_correlation`` set, its shot, read and structure neutral.
    Clips without a structure (white noise) keep their values. Tensors shaped (*batch, size), as the table's.

    Raises:
        ValueError: a clip has both a structure and a spectral level curve (two descriptions of one noise).
    """
    translated = dict(values)
    chosen = structure_set(values)
    if not bool(chosen.any()):
        return translated
    if bool((chosen & (values["level_curve"] != 0.0).any(dim=-1)).any()):
        raise ValueError(
            "noise values have both an sRGB structure (channel_gain, correlation_length, channel_correlation, "
            "chroma_length) and a spectral level_curve; give one of the two"
        )
    batch = chosen.shape
    flat = {
        name: tensor.reshape(-1, tensor.shape[-1]).to("cpu", torch.float64, copy=True)
        for name, tensor in values.items()
    }
    for index in torch.nonzero(chosen.reshape(-1)).reshape(-1).tolist():
        gains = flat["channel_gain"][index].tolist()
        covariances = _clip_covariances(
            _on_grid(float(flat["correlation_length"][index, 0])),
            _on_grid(float(flat["chroma_length"][index, 0])),
            flat["channel_correlation"][index].tolist(),
            gains,
        )
        power, correlation = covariance_parameters(covariances)
        curve = _level_curve(float(flat["shot"][index, 0]), float(flat["read"][index, 0]), gains)
        for name, value in (("level_curve", curve), ("octave_power", power), ("octave_correlation", correlation)):
            flat[name][index] = value
        for name, neutral in (("shot", 0.0), ("read", 0.0), *STRUCTURE_NEUTRAL.items()):
            flat[name][index] = neutral
    for name, tensor in values.items():
        translated[name] = flat[name].reshape(*batch, tensor.shape[-1]).to(tensor.device, tensor.dtype)
    return translated
