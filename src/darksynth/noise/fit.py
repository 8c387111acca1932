"""Fitting the table's sRGB noise model to a noise residual: the pure statistics of the clean-aided fit.

Given a noisy image and an image taken as its clean version (the real clean image for the oracle,
:mod:`darksynth.evaluation.srgb_fit`; a denoised copy of the reference for the blind refinement,
:mod:`darksynth.estimation.refine`), these functions read the per-channel variance law var = a_c x + b_c, turn it into
the table's green shot and read and red's and blue's gains, and measure the normalised residual's spatial
autocorrelation and cross-channel correlation. Images are (3, H, W) on the [0, 1] scale; every value returned is
clipped to its parameter's bounds in the table (:class:`~darksynth.noise.components.Parameter`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

from darksynth.noise.components import noise_parameter
from darksynth.noise.correlated import kernel_autocorrelation
from darksynth.noise.values import NoiseValues

LEVEL_BINS = 16
"""Intensity bins of the variance-against-level fits."""

MAX_LAG = 3
"""Autocorrelation lags (pixels) the correlation length is fitted on."""

LENGTH_GRID = tuple(round(0.02 * i, 2) for i in range(0, 201))
"""Candidate correlation lengths, 0 to 4 pixels."""

CHANNEL_PAIRS = ((0, 1), (1, 2), (0, 2))
"""The channel pairs of ``channel_correlation``, in the table's order: red-green, green-blue, red-blue."""


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


def central_crop(image: torch.Tensor, side: int) -> torch.Tensor:
    """The central ``side`` x ``side`` crop of (..., H, W), its corner on the 16-pixel grid: JPEG blocks and the
    4-column phase of periodic noise stay where the image has them."""
    height, width = image.shape[-2:]
    top = max(0, (height - side) // 2) // 16 * 16
    left = max(0, (width - side) // 2) // 16 * 16
    return image[..., top : top + side, left : left + side]


def clipped(name: str, value: float) -> float:
    """A value of the parameter ``name`` clipped to its bounds in the table."""
    parameter = noise_parameter(name)
    return min(parameter.maximum, max(parameter.minimum, value))


def model_std(clean: torch.Tensor, values: NoiseValues) -> torch.Tensor:
    """The model's per-pixel noise std g_c sqrt(shot^2 x + read^2) for a clean image (3, H, W), gains
    g = (red, 1, blue)."""
    shot, read = values.scalar("shot"), values.scalar("read")
    red, blue = (float(g) for g in values["channel_gain"].tolist())
    gains = torch.tensor([red, 1.0, blue], dtype=clean.dtype, device=clean.device).view(3, 1, 1)
    return gains * (shot**2 * clean.clamp_min(0.0) + read**2).sqrt()


def values_of_law(law: PoissonGaussian, clean: torch.Tensor) -> NoiseValues:
    """Green's shot and read and red's and blue's gains from a per-channel law var = a_c x + b_c.

    The gain of a channel c is sqrt(mean(a_c x_c + b_c) / mean(a_g x_c + b_g)) over the channel's clean levels
    x_c: with it, the model's mean noise variance on that channel equals the law's.
    """
    green_a, green_b = law.a[1], law.b[1]
    gains = []
    for channel in (0, 2):
        level = float(clean[channel].clamp_min(0.0).mean())
        own = law.a[channel] * level + law.b[channel]
        green = green_a * level + green_b
        gains.append(clipped("channel_gain", math.sqrt(own / green)) if green > 0.0 else 1.0)
    return NoiseValues.from_values(
        {
            "shot": clipped("shot", math.sqrt(green_a)),
            "read": clipped("read", math.sqrt(green_b)),
            "channel_gain": gains,
        }
    )


def normalised_noise(noisy: torch.Tensor, clean: torch.Tensor, values: NoiseValues) -> torch.Tensor:
    """(noisy - clean) / s(clean), per channel mean removed: unit-variance noise where the model is right."""
    unit = (noisy - clean) / model_std(clean, values).clamp_min(1e-4)
    return unit - unit.mean(dim=(-2, -1), keepdim=True)


def autocorrelation(unit: torch.Tensor, max_lag: int = MAX_LAG) -> tuple[list[float], list[float]]:
    """Autocorrelation of a (C, H, W) zero-mean noise map at lags 1..max_lag along x and along y."""
    energy = float(unit.square().mean())
    along_x = [float((unit[..., :, :-d] * unit[..., :, d:]).mean()) / energy for d in range(1, max_lag + 1)]
    along_y = [float((unit[..., :-d, :] * unit[..., d:, :]).mean()) / energy for d in range(1, max_lag + 1)]
    return along_x, along_y


@lru_cache(maxsize=1)
def _theory_table() -> np.ndarray[tuple[int, int], np.dtype[np.float64]]:
    return np.array([[kernel_autocorrelation(length, d) for d in range(1, MAX_LAG + 1)] for length in LENGTH_GRID])


def fit_correlation_length(correlations: Sequence[Sequence[float]]) -> float:
    """The kernel length whose theoretical autocorrelation at lags 1..MAX_LAG is closest (least squares summed
    over the given directions, e.g. x and y: the table's length is isotropic)."""
    theory = _theory_table()
    error = sum(np.square(theory - np.asarray(list(lags)[:MAX_LAG])[None, :]).sum(axis=1) for lags in correlations)
    return clipped("correlation_length", float(LENGTH_GRID[int(np.argmin(error))]))


def channel_correlations(unit: torch.Tensor) -> list[float]:
    """Correlation coefficients of red-green, green-blue and red-blue noise in a (3, H, W) map."""
    matrix = torch.corrcoef(unit.reshape(unit.shape[0], -1))
    return [clipped("channel_correlation", float(matrix[i, j])) for i, j in CHANNEL_PAIRS]


def lag1_correlation(noise: torch.Tensor) -> float:
    """Lag-1 autocorrelation along x and y together."""
    centred = noise - noise.mean(dim=(-2, -1), keepdim=True)
    along_x, along_y = autocorrelation(centred, 1)
    return 0.5 * (along_x[0] + along_y[0])


def length_for_lag1(correlation: float) -> float:
    """The kernel length whose theoretical lag-1 autocorrelation is closest to ``correlation``."""
    index = int(np.argmin(np.abs(_theory_table()[:, 0] - correlation)))
    return clipped("correlation_length", float(LENGTH_GRID[index]))
