"""Classical noise-level estimators of the baselines: blind Gaussian, blind and clean-aided Poisson-Gaussian.

All work per channel on float64 tensors (3, H, W) on the [0, 1] scale and describe the noise by the
Poisson-Gaussian law var(x) = a * x + b (Foi et al. 2008), a Gaussian being a = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from darksynth.tensors import to_8bit_levels

__all__ = [
    "PoissonGaussian",
    "add_poisson_gaussian",
    "blind_gaussian_sigma",
    "blind_poisson_gaussian",
    "oracle_poisson_gaussian",
]

FIT_BLOCK = 8
"""Side of the blocks of the single-image Poisson-Gaussian fit."""

SMOOTH_FRACTION = 0.3
"""Share of the blocks of each intensity bin, the least textured, that the single-image fit keeps."""

LEVEL_BINS = 16
"""Intensity bins of the variance-against-level fits."""


@dataclass(frozen=True)
class PoissonGaussian:
    """Per-channel variance law var = a * x + b; a Gaussian has a = 0."""

    a: tuple[float, float, float]
    b: tuple[float, float, float]

    def std(self, signal: torch.Tensor) -> torch.Tensor:
        """Per-pixel standard deviation for a clean signal (3, H, W)."""
        a = torch.tensor(self.a, dtype=signal.dtype, device=signal.device).view(3, 1, 1)
        b = torch.tensor(self.b, dtype=signal.dtype, device=signal.device).view(3, 1, 1)
        return (a * signal.clamp_min(0.0) + b).clamp_min(0.0).sqrt()


def weighted_line(level: np.ndarray, variance: np.ndarray, weight: np.ndarray) -> tuple[float, float]:
    """Least-squares a, b >= 0 of variance = a * level + b."""
    design = np.stack([level, np.ones_like(level)], axis=1) * weight[:, None]
    (a, b), *_ = np.linalg.lstsq(design, variance * weight, rcond=None)
    if a < 0.0:  # the variance does not grow with the level: a Gaussian fits best
        a, b = 0.0, float(np.average(variance, weights=weight**2))
    if b < 0.0:
        b = 0.0
        a = float(np.sum(weight**2 * level * variance) / max(np.sum(weight**2 * level * level), 1e-20))
    return float(a), float(b)


def oracle_poisson_gaussian(noisy: torch.Tensor, clean: torch.Tensor) -> PoissonGaussian:
    """Poisson-Gaussian parameters fitted with the clean image: variance of noisy - clean against clean."""
    a_values, b_values = [], []
    for noisy_channel, clean_channel in zip(noisy, clean, strict=True):
        level = clean_channel.flatten()
        noise = (noisy_channel - clean_channel).flatten()
        order = torch.argsort(level)
        levels, variances, sizes = [], [], []
        for chunk in torch.tensor_split(order, LEVEL_BINS):
            if len(chunk) < 16:
                continue
            levels.append(float(level[chunk].mean()))
            variances.append(float(noise[chunk].var()))
            sizes.append(len(chunk))
        variance_array = np.array(variances)
        weights = np.sqrt(np.array(sizes, dtype=np.float64)) / np.maximum(variance_array, 1e-8)
        a, b = weighted_line(np.array(levels), variance_array, weights)
        a_values.append(a)
        b_values.append(b)
    return PoissonGaussian(a=(a_values[0], a_values[1], a_values[2]), b=(b_values[0], b_values[1], b_values[2]))


def add_poisson_gaussian(clean: torch.Tensor, law: PoissonGaussian, generator: torch.Generator) -> torch.Tensor:
    """clean + N(0, a x + b), clipped to [0, 1] and rounded to 8-bit levels as a real sRGB image is."""
    noise = torch.randn(clean.shape, generator=generator, dtype=clean.dtype, device=clean.device)
    return to_8bit_levels(clean + noise * law.std(clean))


def blind_gaussian_sigma(noisy: torch.Tensor) -> tuple[float, float, float]:
    """Per-channel sigma from the noisy image alone: scikit-image's wavelet (MAD) estimator (Donoho 1995)."""
    from skimage.restoration import estimate_sigma

    pixels = noisy.permute(1, 2, 0).cpu().numpy()
    sigmas = estimate_sigma(pixels, channel_axis=-1, average_sigmas=False)  # type: ignore[no-untyped-call]
    return (float(sigmas[0]), float(sigmas[1]), float(sigmas[2]))


def blind_poisson_gaussian(noisy: torch.Tensor) -> PoissonGaussian:
    """Poisson-Gaussian parameters from the noisy image alone, in the manner of Foi et al. 2008.

    Each channel is cut into blocks; in each block the level is the block mean and the noise variance comes
    from the finest diagonal wavelet-like detail (a 2x2 difference whose variance is the noise variance for
    white noise and which cancels constant and linear content). In each intensity bin only the least textured
    blocks are kept (the lowest SMOOTH_FRACTION of detail variance, corrected for the bias of keeping a lower
    fraction of a chi-square spread by the median-based estimate), then var = a x + b is fitted over the bins.
    """
    a_values, b_values = [], []
    for channel in noisy:
        image = channel[None, None]
        detail = (image[..., :-1, :-1] - image[..., 1:, :-1] - image[..., :-1, 1:] + image[..., 1:, 1:]) / 2.0
        height = (detail.shape[-2] // FIT_BLOCK) * FIT_BLOCK
        width = (detail.shape[-1] // FIT_BLOCK) * FIT_BLOCK
        block_variance = F.avg_pool2d(detail[..., :height, :width].square(), FIT_BLOCK).flatten()
        block_level = F.avg_pool2d(image[..., :height, :width], FIT_BLOCK).flatten()
        order = torch.argsort(block_level)
        levels, variances, sizes = [], [], []
        for chunk in torch.tensor_split(order, LEVEL_BINS):
            if len(chunk) < 4:
                continue
            chunk_variance = block_variance[chunk]
            keep = max(1, int(len(chunk) * SMOOTH_FRACTION))
            smooth = torch.topk(chunk_variance, keep, largest=False).indices
            # Without texture, block variances scatter around the noise variance; the median of the kept
            # lowest fraction sits at their SMOOTH_FRACTION / 2 quantile, which is scaled back to the mean.
            quantile = float(torch.quantile(chunk_variance[smooth], 0.5))
            levels.append(float(block_level[chunk][smooth].mean()))
            variances.append(quantile)
            sizes.append(keep)
        level_array = np.array(levels)
        variance_array = np.array(variances) * _lower_quantile_correction(FIT_BLOCK * FIT_BLOCK, SMOOTH_FRACTION / 2)
        weights = np.sqrt(np.array(sizes, dtype=np.float64)) / np.maximum(variance_array, 1e-8)
        a, b = weighted_line(level_array, variance_array, weights)
        a_values.append(a)
        b_values.append(b)
    return PoissonGaussian(a=(a_values[0], a_values[1], a_values[2]), b=(b_values[0], b_values[1], b_values[2]))


def _lower_quantile_correction(samples: int, quantile: float) -> float:
    """Mean / quantile of a chi-square variance estimate with ``samples`` degrees of freedom."""
    from scipy.stats import chi2

    return float(samples / chi2.ppf(quantile, samples))
