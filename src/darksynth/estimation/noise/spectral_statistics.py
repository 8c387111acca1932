"""The spectral model's statistics measured on noise maps: what the spectral fit reproduces by re-synthesis.

The statistics of a noise map (or of a residual, noisy minus denoised) are:

* per octave band (:data:`BANDS`, finest first) the 3x3 cross-power of its brightness and colour components
  (:data:`darksynth.noise.spectral.OPPONENT_BASIS`), relative to white noise of unit variance: the whole map
  is band-passed first (an ideal radial filter on its FFT), then the products are averaged over the pixels of a
  mask (all pixels, or the flat blocks of a reference), so texture outside the mask cannot leak into a band;
* per channel and level-curve knot (:data:`darksynth.noise.spectral.LEVEL_KNOTS`) the variance of the map's
  frequencies in the bands, weighted by the hat function of the knot at the pixel's intensity (the clean or
  denoised image's);
* for clips, per band the correlation of each frame's band with the next frame's.

Pure functions on tensors; the clean-aided fit and the blind estimate (:mod:`darksynth.estimation.noise.spectral_fit`,
:mod:`darksynth.estimation.noise.spectrum`) measure through them.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import torch

from darksynth.noise.spectral import LEVEL_KNOTS, OPPONENT_BASIS, grid_radius

BANDS: tuple[tuple[float, float], ...] = (
    (1 / 4, 0.71),
    (1 / 8, 1 / 4),
    (1 / 16, 1 / 8),
    (1 / 32, 1 / 16),
    (1 / 64, 1 / 32),
    (1 / 128, 1 / 64),
)
"""Radial frequency bands in cycles/px, finest first, one per octave of the model: [1/4, 0.71), [1/8, 1/4), ...,
[1/128, 1/64). The first five are the bands of the evaluation's band measure."""

MIN_KNOT_WEIGHT = 200.0
"""A knot whose hat weights sum to less than this (pixels) is not measured; it takes its neighbour's value."""


@dataclass(frozen=True)
class SpectralStatistics:
    """What :func:`measure` reads from a noise map.

    Attributes:
        cross_power: (OCTAVES, 3, 3) band cross-power in the colour basis, relative to white unit variance.
        knot_variance: (C, 8) variance per channel and knot (nan where the knot is not measured).
        temporal: (OCTAVES,) frame-to-frame correlation per band; None for a single frame.
    """

    cross_power: torch.Tensor
    knot_variance: torch.Tensor
    temporal: torch.Tensor | None


@functools.lru_cache(maxsize=4)
def band_masks(height: int, width: int, device: torch.device) -> torch.Tensor:
    """(len(BANDS), H, W // 2 + 1) float64, 1 where a frequency of an ``rfft2`` of an (H, W) map falls in a band.
    Cached: a fit measures dozens of maps of one size (the tensor is only read, never written)."""
    radius = grid_radius(height, width, device)
    return torch.stack([((radius >= low) & (radius < high)).to(torch.float64) for low, high in BANDS])


@functools.lru_cache(maxsize=4)
def band_weights(height: int, width: int, device: torch.device) -> torch.Tensor:
    """(len(BANDS), H, W // 2 + 1) :func:`band_masks` with each frequency counted twice where the ``rfft2`` half-plane
    stands for two (every column but the first and, for an even width, the last). Cached as :func:`band_masks` is:
    every map of the fit and every lag of the frame differences reads it, never writes it."""
    twice = torch.full((height, width // 2 + 1), 2.0, dtype=torch.float64, device=device)
    twice[:, 0] = 1.0
    if width % 2 == 0:
        twice[:, -1] = 1.0
    return band_masks(height, width, device) * twice


def band_fields(noise: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The band-passed colour components of noise maps (..., 3, H, W) (or grey (..., 1, H, W)):
    (..., OCTAVES, K, H, W) float64, K = 3 (or 1), each component minus its mean, and each band's share of the
    frequency square (OCTAVES,), by which a white field's band power is that share of its variance."""
    noise = noise.to(torch.float64)
    channels = noise.shape[-3]
    components = torch.einsum("ij,...jhw->...ihw", OPPONENT_BASIS.to(noise.device), noise) if channels == 3 else noise
    components = components - components.mean(dim=(-2, -1), keepdim=True)
    height, width = noise.shape[-2:]
    masks = band_masks(height, width, noise.device)
    spectrum = torch.fft.rfft2(components)
    fields = torch.stack([torch.fft.irfft2(spectrum * mask, s=(height, width)) for mask in masks], dim=-4)
    share = band_weights(height, width, noise.device).sum(dim=(-2, -1)) / float(height * width)
    return fields, share


def measure_weight(
    frames: int, height: int, width: int, mask: torch.Tensor | None, device: torch.device
) -> torch.Tensor:
    """The pixel weights (T, H, W) float64 :func:`measure` averages with: ``mask`` on every frame, or all ones."""
    weight = torch.ones(frames, height, width, dtype=torch.float64, device=device)
    return weight if mask is None else weight * mask.to(weight)


def measure(
    noise: torch.Tensor,
    intensity: torch.Tensor,
    mask: torch.Tensor | None = None,
    *,
    binning: KnotBinning | None = None,
) -> SpectralStatistics:
    """The statistics of noise maps ``noise`` (T, C, H, W) (a clip, or one frame with T = 1) whose pixels have the
    clean or denoised intensity ``intensity`` (T, C, H, W); ``mask`` (H, W) or (T, H, W) in {0, 1} selects the
    pixels averaged over (all when None). ``binning``: :func:`knot_binning` of ``intensity`` and the mask's
    :func:`measure_weight`, when a caller measures many noise maps on the same intensity (a fit)."""
    frames, channels, height, width = noise.shape
    weight = measure_weight(frames, height, width, mask, noise.device)
    total = weight.sum().clamp_min(1.0)
    fields, share = band_fields(noise)  # (T, OCTAVES, K, H, W)
    # Per band, the weighted sum of the components' products over every pixel of every frame, as one batched
    # matrix product (an einsum over the five-axis arrays took twice as long).
    flat = fields.permute(1, 2, 0, 3, 4).reshape(fields.shape[1], fields.shape[2], -1)  # (OCTAVES, K, T * H * W)
    summed = torch.bmm(flat * weight.reshape(1, 1, -1), flat.transpose(1, 2))
    cross_power = summed / total / share.clamp_min(1e-12)[:, None, None]
    temporal = None
    if frames > 1:
        pair_weight = weight[:-1] * weight[1:]
        lagged = (fields[:-1] * fields[1:] * pair_weight[:, None, None]).sum(dim=(0, 2, 3, 4))
        # Each band's weighted energy is the trace of its summed products.
        energy = summed.diagonal(dim1=-2, dim2=-1).sum(-1) * (pair_weight.sum() / total)
        temporal = lagged / energy.clamp_min(1e-30)
    # The level is read on the same frequencies as the bands (above 1/128 cycles/px): slow drifts between a noisy
    # image and its clean reference (exposure, illumination) are not noise the model could put anywhere.
    banded = fields.sum(dim=1)
    if channels == 3:
        banded = torch.einsum("ji,tjhw->tihw", OPPONENT_BASIS.to(banded.device), banded)
    return SpectralStatistics(cross_power, knot_variances(banded, intensity, weight, binning), temporal)


def knot_pieces(intensity: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The level-curve knot below each intensity of ``intensity`` (...) and the hat weight of the knot above it:
    (index (...) int64 in 0..6, fraction (...) float64 in [0, 1]). The knot below has weight 1 - fraction, every
    other knot 0; the knots (j / 7)^2 lie on the grid of step 1/49, so a value's knot is floor(sqrt(49 x))."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64, device=intensity.device)
    x = intensity.to(torch.float64).clamp(0.0, 1.0)
    index = (x * 49.0).sqrt().floor().long().clamp(0, len(LEVEL_KNOTS) - 2)
    low, high = knots[index], knots[index + 1]
    # (A value that sqrt rounds across a knot gets a fraction of 0 or 1 at it: the same weights.)
    return index, ((x - low) / (high - low)).clamp(0.0, 1.0)


@dataclass(frozen=True)
class KnotBinning:
    """Where each pixel of a (T, C, H, W) intensity map adds to the level curve's knots, with the pixel weights:
    built once for a reference's denoised frames and its mask, read by every simulation measured on them.

    Attributes:
        bins: (T * C * H * W,) int64, channel * 8 + the knot below each value.
        below, above: (T * C * H * W,) float64, the pixel's weight times the hat of the knot below and above.
        mass: (C, 8) float64, each knot's summed weights.
    """

    bins: torch.Tensor
    below: torch.Tensor
    above: torch.Tensor
    mass: torch.Tensor


def knot_binning(intensity: torch.Tensor, weight: torch.Tensor) -> KnotBinning:
    """The :class:`KnotBinning` of ``intensity`` (T, C, H, W) with pixel weights ``weight`` (T, H, W)."""
    channels, knots = intensity.shape[1], len(LEVEL_KNOTS)
    index, fraction = knot_pieces(intensity)
    pixel_weight = weight[:, None].to(torch.float64).expand_as(fraction)
    # Each pixel adds to two knots (its piece's ends): sums per (channel, knot) by counting into C * 8 bins.
    bins = (index + torch.arange(channels, device=index.device).reshape(1, -1, 1, 1) * knots).flatten()
    below, above = (pixel_weight * (1.0 - fraction)).flatten(), (pixel_weight * fraction).flatten()
    size = channels * knots
    mass = torch.bincount(bins, below, minlength=size) + torch.bincount(bins + 1, above, minlength=size)
    return KnotBinning(bins, below, above, mass.reshape(channels, knots))


def knot_variances(
    noise: torch.Tensor, intensity: torch.Tensor, weight: torch.Tensor, binning: KnotBinning | None = None
) -> torch.Tensor:
    """(C, 8) hat-weighted variance of ``noise`` (T, C, H, W) per channel and knot of ``intensity``; pixels weighted
    by ``weight`` (T, H, W); nan where a knot's weights sum to less than :data:`MIN_KNOT_WEIGHT`. ``binning``: the
    :func:`knot_binning` of ``intensity`` and ``weight``, when already built."""
    if binning is None:
        binning = knot_binning(intensity, weight)
    size = binning.mass.numel()
    centred = noise.to(torch.float64) - noise.to(torch.float64).mean(dim=(0, 2, 3), keepdim=True)
    squares = centred.square().flatten()
    total = torch.bincount(binning.bins, binning.below * squares, minlength=size)
    total += torch.bincount(binning.bins + 1, binning.above * squares, minlength=size)
    mass = binning.mass
    variance = total.reshape(mass.shape) / mass.clamp_min(1e-12)
    return torch.where(mass >= MIN_KNOT_WEIGHT, variance, torch.full_like(variance, math.nan))
