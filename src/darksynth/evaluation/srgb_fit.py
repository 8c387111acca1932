"""Clean-aided (oracle) fit of the extended sRGB noise model of :mod:`darksynth.noise.correlated`.

From one real pair (noisy, clean), float64 (3, H, W) on the [0, 1] scale:

1. the per-channel Poisson-Gaussian law var = a_c x + b_c of noisy - clean against clean
   (:func:`~darksynth.evaluation.classical.oracle_poisson_gaussian`);
2. the noise normalised by that law's std, u = (noisy - clean) / s(clean), whose autocorrelation at lags 1-3
   along x and along y gives the Gaussian kernel's lengths (least squares against the kernel's theory,
   :func:`~darksynth.noise.correlated.kernel_autocorrelation`);
3. the mean correlation coefficient of u between pairs of channels gives rho;
4. the JPEG quality (or none): for each candidate, the noise is synthesised on a central crop, its per-channel
   gains and lengths corrected once so that the compressed result's std and lag-1 autocorrelation match the
   real ones, and the candidate is scored by the KL divergence between the real and synthetic histograms of
   the noise and of its horizontal and vertical neighbour differences. The lowest score wins; "no JPEG" is a
   candidate, so PNG sets need no special case.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import torch

from darksynth.evaluation.classical import PoissonGaussian, oracle_poisson_gaussian
from darksynth.noise.correlated import add_correlated_noise, kernel_autocorrelation

MAX_LAG = 3
"""Autocorrelation lags (pixels) the correlation lengths are fitted on."""

LENGTH_GRID = tuple(round(0.02 * i, 2) for i in range(0, 201))
"""Candidate correlation lengths, 0 to 4 pixels."""

JPEG_CANDIDATES: tuple[int | None, ...] = (None, 60, 70, 80, 90, 95)
"""Candidate JPEG qualities of the search (None: no compression)."""

SEARCH_CROP = 256
"""Side of the central crop the JPEG search synthesises on (aligned to the 16-pixel JPEG grid)."""

RHO_LIMITS = (-0.45, 0.95)
"""rho is clipped to this range to keep the channel correlation matrix well conditioned."""


@dataclass(frozen=True)
class SrgbNoise:
    """Parameters of the extended sRGB model (see :func:`darksynth.noise.correlated.add_correlated_noise`)."""

    law: PoissonGaussian
    gains: tuple[float, float, float] = (1.0, 1.0, 1.0)
    correlation_length: float = 0.0
    correlation_length_y: float = 0.0
    rho: float = 0.0
    jpeg_quality: int | None = None

    def summary(self) -> dict[str, object]:
        return {
            "a": list(self.law.a),
            "b": list(self.law.b),
            "gains": list(self.gains),
            "correlation_length": self.correlation_length,
            "correlation_length_y": self.correlation_length_y,
            "rho": self.rho,
            "jpeg_quality": self.jpeg_quality,
        }


def synthesize_srgb(clean: torch.Tensor, noise: SrgbNoise, generator: torch.Generator) -> torch.Tensor:
    """clean + the extended model's noise, on 8-bit levels (JPEG-compressed when the quality is set)."""
    return add_correlated_noise(
        clean,
        generator,
        a=noise.law.a,
        b=noise.law.b,
        gains=noise.gains,
        correlation_length=noise.correlation_length,
        correlation_length_y=noise.correlation_length_y,
        rho=noise.rho,
        jpeg_quality=noise.jpeg_quality,
    )


def normalised_noise(noisy: torch.Tensor, clean: torch.Tensor, law: PoissonGaussian) -> torch.Tensor:
    """(noisy - clean) / s(clean), per channel mean removed: unit-variance noise where the law is right."""
    unit = (noisy - clean) / law.std(clean).clamp_min(1e-4)
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


def fit_correlation_length(correlations: list[float]) -> float:
    """The kernel length whose theoretical autocorrelation at lags 1..MAX_LAG is closest (least squares)."""
    error = np.square(_theory_table() - np.asarray(correlations[:MAX_LAG])[None, :]).sum(axis=1)
    return float(LENGTH_GRID[int(np.argmin(error))])


def channel_correlation(unit: torch.Tensor) -> float:
    """Mean correlation coefficient between the noise of pairs of channels of a (C, H, W) map."""
    matrix = torch.corrcoef(unit.reshape(unit.shape[0], -1))
    channels = unit.shape[0]
    upper = matrix[torch.triu_indices(channels, channels, offset=1).unbind()]
    return float(upper.mean())


def _histogram_kl(real: torch.Tensor, synthetic: torch.Tensor) -> float:
    """KL(real || synthetic) of histograms on integer 8-bit levels, add-one smoothed (nats)."""
    edges = np.arange(-255.5, 256.0, 1.0)
    p, _ = np.histogram(np.round(real.flatten().cpu().numpy() * 255.0), bins=edges)
    q, _ = np.histogram(np.round(synthetic.flatten().cpu().numpy() * 255.0), bins=edges)
    keep = (p + q) > 0
    p_s = (p[keep] + 1.0) / (p[keep] + 1.0).sum()
    q_s = (q[keep] + 1.0) / (q[keep] + 1.0).sum()
    return float(np.sum(p_s * np.log(p_s / q_s)))


def _structure_score(real: torch.Tensor, synthetic: torch.Tensor) -> float:
    """Sum of histogram KLs of the noise and of its neighbour differences along x and y."""
    score = _histogram_kl(real, synthetic)
    score += _histogram_kl(real[..., :, 1:] - real[..., :, :-1], synthetic[..., :, 1:] - synthetic[..., :, :-1])
    score += _histogram_kl(real[..., 1:, :] - real[..., :-1, :], synthetic[..., 1:, :] - synthetic[..., :-1, :])
    return score


def _central_crop(image: torch.Tensor, size: int) -> torch.Tensor:
    height, width = image.shape[-2:]
    top = max(0, (height - size) // 2) // 16 * 16
    left = max(0, (width - size) // 2) // 16 * 16
    return image[..., top : top + size, left : left + size]


def _lag1(noise: torch.Tensor) -> tuple[float, float]:
    centred = noise - noise.mean(dim=(-2, -1), keepdim=True)
    along_x, along_y = autocorrelation(centred, 1)
    return along_x[0], along_y[0]


def _corrected(
    params: SrgbNoise, real: torch.Tensor, clean: torch.Tensor, seed: int, *, spatial: bool
) -> tuple[SrgbNoise, float]:
    """One correction of gains and lengths so the synthetic noise's std and lag-1 correlation match, and the
    structure score of the corrected parameters."""
    synthetic = synthesize_srgb(clean, params, torch.Generator().manual_seed(seed)) - clean
    real_std = real.std(dim=(-2, -1))
    synth_std = synthetic.std(dim=(-2, -1)).clamp_min(1e-6)
    gains = tuple(float(g) * float(r / s) for g, r, s in zip(params.gains, real_std, synth_std, strict=True))
    lengths = [params.correlation_length, params.correlation_length_y]
    for axis, (length, target, got) in enumerate(
        zip((params.correlation_length, params.correlation_length_y), _lag1(real), _lag1(synthetic), strict=True)
    ):
        if spatial:
            wanted = min(0.99, max(0.0, kernel_autocorrelation(length, 1) + target - got))
            lengths[axis] = _length_for_lag1(wanted)
    corrected = replace(
        params,
        gains=(gains[0], gains[1], gains[2]),
        correlation_length=lengths[0],
        correlation_length_y=lengths[1],
    )
    synthetic = synthesize_srgb(clean, corrected, torch.Generator().manual_seed(seed)) - clean
    return corrected, _structure_score(real, synthetic)


def _length_for_lag1(correlation: float) -> float:
    index = int(np.argmin(np.abs(_theory_table()[:, 0] - correlation)))
    return float(LENGTH_GRID[index])


def fit_srgb_noise(
    noisy: torch.Tensor,
    clean: torch.Tensor,
    *,
    spatial: bool = True,
    chromatic: bool = True,
    jpeg: bool = True,
    candidates: tuple[int | None, ...] = JPEG_CANDIDATES,
    seed: int = 0,
) -> SrgbNoise:
    """Fit the extended model to one real pair with its clean image (an oracle). The switches leave out a
    component (its parameter stays at the white / uncorrelated / uncompressed value) for ablations."""
    law = oracle_poisson_gaussian(noisy, clean)
    unit = normalised_noise(noisy, clean, law)
    params = SrgbNoise(law=law)
    if spatial:
        along_x, along_y = autocorrelation(unit)
        params = replace(
            params,
            correlation_length=fit_correlation_length(along_x),
            correlation_length_y=fit_correlation_length(along_y),
        )
    if chromatic:
        rho = channel_correlation(unit)
        params = replace(params, rho=float(min(RHO_LIMITS[1], max(RHO_LIMITS[0], rho))))
    if not jpeg:
        return params
    real = _central_crop(noisy - clean, SEARCH_CROP)
    clean_crop = _central_crop(clean, SEARCH_CROP)
    best, best_score = params, math.inf
    for quality in candidates:
        candidate, score = _corrected(replace(params, jpeg_quality=quality), real, clean_crop, seed, spatial=spatial)
        if score < best_score:
            best, best_score = candidate, score
    return best
