"""What the refinement (:mod:`darksynth.estimation.refine`) measures: the reference as it reads it and the
statistics of an image's residual.

With ``x_hat = D(y)`` the denoised reference (:func:`analyse`: a central crop, denoised, its smoothest pixels and
their level bins) and ``s(.)`` the statistics of the residual ``z - D(z)`` of an image z
(:func:`residual_statistics`): the residual's variance per channel and per level of x_hat (on the smoothest
pixels, where D removes noise and little else), its lag-1 autocorrelation, its red-green, green-blue and
red-blue correlations, the variance of its column means, and how its energy spreads over scales.

``D`` is a Gaussian filter (:func:`gaussian_denoise`): cheap on a CPU and with no training; the DEN's decoder
output was the other candidate (docs/refine.md compares them on synthetic references).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from darksynth.noise.correlated import filter_valid, gaussian_kernel1d
from darksynth.noise.fit import central_crop

DENOISE_SIGMA = 3.0
"""Std (pixels) of the Gaussian denoiser, chosen on a synthetic reference (tests/estimation/test_refine.py's scene,
noise of length 1.2 px): the noise D leaves in x_hat reappears in every simulation, and a wider filter leaves less
(level error -31% at 1 px, -12% at 2 px, -6% at 3 px); the texture a wider filter removes is kept out of the
statistics by the smooth-pixel mask."""

ANALYSIS_SIDE = 256
"""Side of the central crop the statistics are measured on: about 20 000 smooth pixels, a few per cent of
precision on each bin's variance; the cost of a step grows with the area."""

ANALYSIS_FRAMES = 4
"""Frames of a clip the statistics pool (the first ones)."""

SMOOTH_SHARE = 0.3
"""Share of pixels, the least textured of their level and of the whole crop, whose detail the statistics read."""

LEVEL_BINS = 8
"""Bins of x_hat's level for the per-channel residual variance."""


@dataclass(frozen=True)
class ResidualStatistics:
    """What the refinement matches: statistics of the residual z - D(z) of an image z.

    Attributes:
        variance: residual variance per channel and level bin (3, LEVEL_BINS), smooth pixels only.
        lag1: lag-1 autocorrelation along x and y of the normalised residual, smooth pixels only.
        correlations: red-green, green-blue and red-blue correlation of the residual, smooth pixels only.
        column_variance: variance over columns of the residual's column means, averaged over channels and frames.
        scale_ratio: per channel (3,), the variance of the diagonal detail of the 2x2-averaged image over that of
            the image itself, smooth pixels only: how the noise's energy spreads over scales, which compression
            (and spatial correlation) changes.
        luma_scale_ratio: the same ratio for the brightness of the image (the mean of its channels).
        colour_scale_ratio: the same ratio for its two opponent colour components (pooled): real colour noise
            is coarser than its brightness noise (in-camera chroma denoising, 4:2:0), which only these two
            ratios tell apart.
    """

    variance: torch.Tensor
    lag1: float
    correlations: tuple[float, float, float]
    column_variance: float
    scale_ratio: torch.Tensor
    luma_scale_ratio: float
    colour_scale_ratio: float

    def distance(self, other: ResidualStatistics) -> float:
        """How far the structure of two residuals is apart (levels aside, which the steps match): squared
        differences of the log scale ratios (per channel, brightness and colour), the lag-1 autocorrelation and the
        channel correlations."""
        scales = float(
            (self.scale_ratio.clamp_min(1e-12).log() - other.scale_ratio.clamp_min(1e-12).log()).square().sum()
        )
        pairs = sum((a - b) ** 2 for a, b in zip(self.correlations, other.correlations, strict=True))
        opponents = (log_ratio(self.luma_scale_ratio) - log_ratio(other.luma_scale_ratio)) ** 2
        opponents += (log_ratio(self.colour_scale_ratio) - log_ratio(other.colour_scale_ratio)) ** 2
        return scales + opponents + (self.lag1 - other.lag1) ** 2 + pairs


@dataclass(frozen=True)
class Analysis:
    """The reference as the refinement reads it: a crop, its denoised copy, the smooth mask and level bins.

    Attributes:
        noisy: the reference's crop (T, 3, H, W) in [0, 1].
        denoised: D(noisy), the stand-in for the clean image.
        smooth: the pixels the level and correlation statistics read (T, 1, H, W), bool.
        bins: level bin of every pixel and channel (T, 3, H, W), by the quantiles of ``denoised`` on ``smooth``.
        levels: mean denoised level of every channel and bin (3, LEVEL_BINS).
        scale: per-pixel std the residual is divided by before its correlations are measured (T, 3, H, W).
    """

    noisy: torch.Tensor
    denoised: torch.Tensor
    smooth: torch.Tensor
    bins: torch.Tensor
    levels: torch.Tensor
    scale: torch.Tensor


def gaussian_denoise(frames: torch.Tensor, sigma: float = DENOISE_SIGMA) -> torch.Tensor:
    """A Gaussian filter of std ``sigma`` pixels over frames (..., H, W), reflected at the borders."""
    kernel = gaussian_kernel1d(sigma, dtype=frames.dtype, device=frames.device)
    radius = kernel.numel() // 2
    shape = frames.shape
    flat = F.pad(frames.reshape(-1, 1, shape[-2], shape[-1]), (radius, radius, radius, radius), mode="reflect")
    return filter_valid(flat, kernel).reshape(shape)


def as_frames(reference: torch.Tensor) -> torch.Tensor:
    if reference.dim() == 3:
        reference = reference[None]
    if reference.dim() != 4 or reference.shape[1] != 3:
        raise ValueError(f"a reference must be an image (3, H, W) or frames (T, 3, H, W), got {tuple(reference.shape)}")
    return reference


def _local_mean(frames: torch.Tensor) -> torch.Tensor:
    flat = frames.reshape(-1, 1, *frames.shape[-2:])
    return F.avg_pool2d(flat, 15, stride=1, padding=7, count_include_pad=False).reshape(frames.shape)


def _smooth_pixels(denoised: torch.Tensor) -> torch.Tensor:
    """The pixels among the SMOOTH_SHARE least textured both of their level and of the whole denoised image
    (T, 1, H, W), bool.

    Texture is told by the local energy of the denoised image's horizontal and vertical details. It is read on
    the denoised image, not the noisy one: the fine noise the statistics measure has little left there, so the
    choice does not pick pixels where the reference's noise happens to be low (which the simulations, drawn
    afresh, would not share).
    """
    grey = denoised.sum(dim=1, keepdim=True)
    horizontal = 0.5 * (grey[..., :-1, :-1] + grey[..., 1:, :-1] - grey[..., :-1, 1:] - grey[..., 1:, 1:])
    vertical = 0.5 * (grey[..., :-1, :-1] + grey[..., :-1, 1:] - grey[..., 1:, :-1] - grey[..., 1:, 1:])
    energy = F.pad(_local_mean(horizontal.square() + vertical.square()), (0, 1, 0, 1), mode="replicate")
    level = denoised.mean(dim=1, keepdim=True)
    edges = torch.quantile(_sample(level), torch.linspace(0, 1, LEVEL_BINS + 1, dtype=level.dtype)[1:-1])
    index = torch.bucketize(level, edges)
    smooth = torch.zeros_like(level, dtype=torch.bool)
    for bin_index in range(LEVEL_BINS):
        inside = index == bin_index
        if bool(inside.any()):
            smooth |= inside & (energy <= torch.quantile(_sample(energy[inside]), SMOOTH_SHARE))
    # A level bin that lies on edges or texture (the dark strokes of a drawing on a flat wall fill bins of their
    # own) would still give its SMOOTH_SHARE least textured pixels, which are texture: a pixel must be among
    # the least textured of the whole crop as well.
    return smooth & (energy <= torch.quantile(_sample(energy), SMOOTH_SHARE))


def _sample(values: torch.Tensor) -> torch.Tensor:
    # torch.quantile refuses inputs above 16 million values; a regular subsample keeps it cheap as well.
    flat = values.flatten()
    return flat[:: max(1, flat.numel() // 200_000)]


def analysis_crop(reference: torch.Tensor) -> torch.Tensor:
    """The part of a reference image (3, H, W) or frames (T, 3, H, W) the refinement reads: the first
    ANALYSIS_FRAMES frames, a central crop of ANALYSIS_SIDE, float32 (T', 3, H', W')."""
    # float32: the statistics are sums over at most a million pixels, well within its precision, at half the cost.
    return central_crop(as_frames(reference)[:ANALYSIS_FRAMES], ANALYSIS_SIDE).to(torch.float32)


def analyse(reference: torch.Tensor, *, denoised: torch.Tensor | None = None, sigma: float = DENOISE_SIGMA) -> Analysis:
    """Crop, denoise and bin a reference image (3, H, W) or frames (T, 3, H, W) in [0, 1].

    Args:
        reference: the noisy reference.
        denoised: its denoised crop (:func:`analysis_crop`'s shape), e.g. the DEN's dark clean output; a
            Gaussian filter of std ``sigma`` pixels when not given.
    """
    noisy = analysis_crop(reference)
    if min(noisy.shape[-2:]) < 8 * sigma:
        raise ValueError(f"a reference of {noisy.shape[-1]}x{noisy.shape[-2]} is too small to refine on")
    if denoised is None:
        denoised = gaussian_denoise(noisy, sigma)
    elif denoised.shape != noisy.shape:
        raise ValueError(f"the denoised crop must be shaped {tuple(noisy.shape)}, got {tuple(denoised.shape)}")
    denoised = denoised.to(noisy.dtype).clamp(0.0, 1.0)
    smooth = _smooth_pixels(denoised)
    bins = torch.zeros_like(noisy, dtype=torch.long)
    levels = torch.zeros(3, LEVEL_BINS, dtype=torch.float64)
    for channel in range(3):
        plane = denoised[:, channel : channel + 1].contiguous()
        chosen = plane[smooth]
        edges = torch.quantile(chosen, torch.linspace(0, 1, LEVEL_BINS + 1, dtype=chosen.dtype)[1:-1])
        index = torch.bucketize(plane, edges)
        bins[:, channel : channel + 1] = index
        counts = torch.bincount(index[smooth], minlength=LEVEL_BINS).to(torch.float64)
        sums = torch.bincount(index[smooth], weights=chosen.double(), minlength=LEVEL_BINS)
        levels[channel] = torch.where(counts > 0, sums / counts.clamp_min(1.0), chosen.double().mean())
    # The correlations are read on the residual divided by a smooth std map, fixed from the reference, so that
    # bright and dark pixels weigh alike in the reference and in every simulation.
    band = F.pad(detail(noisy), (0, 1, 0, 1), mode="replicate")
    local = _local_mean(band.square()).clamp_min(1e-10).sqrt()
    return Analysis(noisy=noisy, denoised=denoised, smooth=smooth, bins=bins, levels=levels, scale=local)


def detail(frames: torch.Tensor) -> torch.Tensor:
    """The finest diagonal detail of frames (..., H, W): (a - b - c + d) / 2 over every 2x2 neighbourhood, a
    copy of white noise's variance that flat or linear content does not reach (Donoho 1995's band), shaped
    (..., H - 1, W - 1)."""
    return 0.5 * (frames[..., :-1, :-1] - frames[..., :-1, 1:] - frames[..., 1:, :-1] + frames[..., 1:, 1:])


def residual_statistics(image: torch.Tensor, analysis: Analysis) -> ResidualStatistics:
    """The statistics of the finest detail of frames shaped like ``analysis.noisy``."""
    band = detail(image)
    weight = analysis.smooth[..., :-1, :-1].expand_as(band).to(band.dtype)
    variance = level_variance(image, analysis)
    unit = band / analysis.scale[..., :-1, :-1]
    unit = (unit - (unit * weight).sum() / weight.sum()) * weight
    energy = float(unit.square().sum() / weight.sum())
    pairs_x = weight[..., :, 1:] * weight[..., :, :-1]
    pairs_y = weight[..., 1:, :] * weight[..., :-1, :]
    along_x = float((unit[..., :, 1:] * unit[..., :, :-1]).sum() / pairs_x.sum().clamp_min(1.0))
    along_y = float((unit[..., 1:, :] * unit[..., :-1, :]).sum() / pairs_y.sum().clamp_min(1.0))
    lag1 = 0.5 * (along_x + along_y) / max(energy, 1e-20)
    channels = unit.transpose(0, 1).reshape(3, -1)
    gram = channels @ channels.T
    norms = gram.diagonal().clamp_min(1e-20).sqrt()
    matrix = gram / (norms[:, None] * norms[None, :])
    correlations = (float(matrix[0, 1]), float(matrix[1, 2]), float(matrix[0, 2]))
    # Column means of the vertical-pass residual: the diagonal band would cancel a pattern constant down columns.
    columns = image - 0.5 * (image.roll(1, dims=-1) + image.roll(-1, dims=-1))
    column_variance = float(columns.mean(dim=-2)[..., 1:-1].var(dim=-1).mean())
    return ResidualStatistics(
        variance=variance,
        lag1=lag1,
        correlations=correlations,
        column_variance=column_variance,
        scale_ratio=_scale_ratio(image, analysis.smooth).double(),
        luma_scale_ratio=_pooled_scale_ratio(_project(image, _LUMA), analysis.smooth),
        colour_scale_ratio=_pooled_scale_ratio(_project(image, _COLOUR), analysis.smooth),
    )


_LUMA = torch.full((1, 3, 1, 1), 1.0 / math.sqrt(3.0))
_COLOUR = torch.tensor([[1.0, 0.0, -1.0], [1.0, -2.0, 1.0]])
_COLOUR = (_COLOUR / _COLOUR.norm(dim=1, keepdim=True)).view(2, 3, 1, 1)
"""An orthonormal opponent basis: brightness (R + G + B) / sqrt 3 and the colour differences (R - B) / sqrt 2 and
(R - 2G + B) / sqrt 6. Fixed rather than the noise's principal axes, which the residual's texture would tilt."""


def level_variance(image: torch.Tensor, analysis: Analysis) -> torch.Tensor:
    """The variance of the level band of frames shaped like ``analysis.noisy`` per channel and level bin
    (3, LEVEL_BINS), float64, smooth pixels only; 0 where a bin holds fewer than two pixels."""
    band = detail(image)
    weight = analysis.smooth[..., :-1, :-1].expand_as(band).to(band.dtype)
    index = analysis.bins[..., :-1, :-1] + LEVEL_BINS * torch.arange(3).view(1, 3, 1, 1)
    counts = torch.zeros(3 * LEVEL_BINS, dtype=band.dtype).scatter_add_(0, index.flatten(), weight.flatten())
    sums = torch.zeros_like(counts).scatter_add_(0, index.flatten(), (band * weight).flatten())
    squares = torch.zeros_like(counts).scatter_add_(0, index.flatten(), (band.square() * weight).flatten())
    mean = sums / counts.clamp_min(1.0)
    return ((squares / counts.clamp_min(1.0) - mean.square()) * (counts > 1)).reshape(3, LEVEL_BINS).double()


def _two_scale_details(
    image: torch.Tensor, smooth: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The finest detail of frames (T, K, H, W) and of their 2x2 average, each with its smooth-pixel mask
    (a coarse pixel counts when all four of its pixels are smooth): fine, fine_mask, coarse, coarse_mask."""
    fine = detail(image)
    fine_mask = smooth[..., :-1, :-1].to(image.dtype)
    coarse = detail(F.avg_pool2d(image, 2))
    coarse_mask = (F.avg_pool2d(smooth.to(image.dtype), 2) == 1.0)[..., :-1, :-1].to(image.dtype)
    return fine, fine_mask, coarse, coarse_mask


def _scale_ratio(image: torch.Tensor, smooth: torch.Tensor) -> torch.Tensor:
    fine, fine_mask, coarse, coarse_mask = _two_scale_details(image, smooth)

    def variance(band: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        count = mask.sum(dim=(0, 2, 3)).clamp_min(1.0)
        mean = (band * mask).sum(dim=(0, 2, 3)) / count
        return (band.square() * mask).sum(dim=(0, 2, 3)) / count - mean.square()

    return variance(coarse, coarse_mask) / variance(fine, fine_mask).clamp_min(1e-20)


def log_ratio(value: float) -> float:
    """The log of a ratio of variances, floored: an empty band gives 0, not an error."""
    return math.log(max(value, 1e-12))


def _project(image: torch.Tensor, basis: torch.Tensor) -> torch.Tensor:
    """Frames (T, 3, H, W) on the components of ``basis`` (K, 3, 1, 1): (T, K, H, W)."""
    return (image[:, None] * basis.to(image.dtype)).sum(dim=2)


def _pooled_scale_ratio(components: torch.Tensor, smooth: torch.Tensor) -> float:
    """:func:`_scale_ratio` of frames (T, K, H, W) with the K components' variances pooled."""
    fine, fine_mask, coarse, coarse_mask = _two_scale_details(components, smooth)

    def energy(band: torch.Tensor, mask: torch.Tensor) -> float:
        count = float(mask.sum()) * band.shape[1]
        return float((band.square() * mask).sum()) / max(count, 1.0)

    return energy(coarse, coarse_mask) / max(energy(fine, fine_mask), 1e-20)
