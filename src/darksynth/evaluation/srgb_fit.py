"""Clean-aided (oracle) fit of the sRGB noise model, in the parameter table's terms.

The model is the one of :mod:`darksynth.noise.components` (green's shot and read, red's and blue's
``channel_gain``, one ``correlation_length``, the three pairwise ``channel_correlation`` values,
``compression``); the fit returns :class:`~darksynth.noise.values.NoiseValues` and every synthetic image goes
through the one composer, :func:`darksynth.noise.simulate.add_noise`. From one real pair (noisy, clean),
float64 (3, H, W) on the [0, 1] scale:

1. the per-channel Poisson-Gaussian law var = a_c x + b_c of noisy - clean against clean
   (:func:`~darksynth.noise.fit.oracle_poisson_gaussian`). Green's law gives shot = sqrt(a_g) and
   read = sqrt(b_g); red's (blue's) gain is the square root of the ratio of its law's mean variance to
   green's law's over its own levels, so each channel keeps its mean noise level. The table's model has one
   law shape for all channels: a_c / b_c can no longer differ between channels;
2. the noise normalised by the model's std, u = (noisy - clean) / s(clean), whose autocorrelation at lags 1-3
   along x and along y together gives the one (isotropic) Gaussian kernel length (least squares against the
   kernel's theory, :func:`~darksynth.noise.correlated.kernel_autocorrelation`);
3. the correlation coefficients of u between red-green, green-blue and red-blue (or their mean for all three,
   an ablation);
4. the compression (or none), by search over JPEG qualities: for each candidate, the noise is synthesised on
   a central crop, the levels (green's shot and read, red's and blue's gains) and the length are corrected
   once so that the compressed result's per-channel std and lag-1 autocorrelation match the real ones, and
   the candidate is scored by the KL divergence between the real and synthetic histograms of the noise and of
   its horizontal and vertical neighbour differences. The lowest score wins; "no JPEG" is a candidate, so PNG
   sets need no special case. A quality q is the compression c = 1 - q / 100.

Every value is clipped to its parameter's bounds in the table (:class:`~darksynth.noise.components.Parameter`).
The pure statistics (steps 1-3) live in :mod:`darksynth.noise.fit`, shared with the blind refinement
(:mod:`darksynth.estimation.refine`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from darksynth.noise.correlated import kernel_autocorrelation
from darksynth.noise.fit import (
    autocorrelation,
    central_crop,
    channel_correlations,
    clipped,
    fit_correlation_length,
    lag1_correlation,
    length_for_lag1,
    normalised_noise,
    oracle_poisson_gaussian,
    values_of_law,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels

JPEG_CANDIDATES: tuple[int | None, ...] = (None, 60, 70, 80, 90, 95)
"""Candidate JPEG qualities of the search (None: no compression)."""

SEARCH_CROP = 256
"""Side of the central crop the JPEG search synthesises on (aligned to the 16-pixel JPEG grid)."""


@dataclass(frozen=True)
class OracleComponents:
    """Which parts of the model the oracle fits; a part left out keeps its neutral value (white, uncorrelated,
    uncompressed noise). Shot, read and the channel gains (each channel's level) are always fitted.

    Attributes:
        spatial: the correlation length.
        chromatic: the channel correlations.
        pairwise: one coefficient per pair of channels; False gives all three pairs their mean (one rho).
        chroma: with ``spatial`` and ``chromatic``, the colour part's own length (``chroma_length``): the
            correlation length is fitted on the main principal component of the noise, the chroma length on
            the other two.
        jpeg: the search over ``candidates`` with its correction of the levels and the length.
        candidates: JPEG qualities searched (None: no compression); ``(None,)`` corrects the levels only.
    """

    spatial: bool = True
    chromatic: bool = True
    pairwise: bool = True
    chroma: bool = True
    jpeg: bool = True
    candidates: tuple[int | None, ...] = JPEG_CANDIDATES


FULL = OracleComponents()
"""The whole model: what ``srgb-oracle`` fits."""

WHITE = OracleComponents(spatial=False, chromatic=False, jpeg=False)
"""The per-channel heteroscedastic law alone: white, uncorrelated, uncompressed noise."""


def compression_of_quality(quality: int | None) -> float:
    """The compression strength c = 1 - q / 100 of a JPEG quality q (0 for none), within the table's bounds."""
    return 0.0 if quality is None else clipped("compression", 1.0 - quality / 100.0)


def synthesize_image(clean: torch.Tensor, values: NoiseValues, generator: torch.Generator) -> torch.Tensor:
    """clean + f(v) through the composer (:func:`~darksynth.noise.simulate.add_noise`), on 8-bit levels.

    Args:
        clean: clean image (3, H, W) in [0, 1].
        values: unbatched noise values.
        generator: source of randomness.

    Returns:
        The noisy image (3, H, W), clipped and on 8-bit levels (JPEG-compressed when ``compression`` is set).
    """
    return to_8bit_levels(add_noise(clean[None], values, generator=generator)[0])


def principal_noise(unit: torch.Tensor, values: NoiseValues) -> tuple[torch.Tensor, torch.Tensor]:
    """The noise on the principal components of its channel covariance: the main (brightness-like) one
    (1, H, W) and the other two (colour, 2, H, W), as the table's ``chroma_length`` draws them.

    ``unit`` is divided by each channel's std; multiplied back by the gains it is the noise over the common
    level, whose covariance is the model's G R G."""
    gains = values["channel_gain"].to(unit.dtype)
    scale = torch.stack([gains[0], torch.ones_like(gains[0]), gains[1]]).view(3, 1, 1)
    noise = unit * scale
    _, vectors = torch.linalg.eigh(torch.cov(noise.reshape(3, -1)))
    components = torch.einsum("ji,jhw->ihw", vectors, noise)
    return components[2:], components[:2]


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


def correct_levels(
    values: NoiseValues, real: torch.Tensor, clean: torch.Tensor, seed: int, *, spatial: bool
) -> tuple[NoiseValues, float]:
    """One correction of the levels and the length so that the synthetic noise's per-channel std and lag-1
    correlation match the real ones.

    Args:
        values: unbatched noise values to correct (their compression stays).
        real: the real noise, noisy - clean, (3, H, W).
        clean: the clean image (3, H, W) it was measured on.
        seed: seed of the synthetic noise.
        spatial: also correct the correlation length.

    Returns:
        The corrected values and their structure score (the sum of the histogram KLs of the noise and of its
        neighbour differences along x and y against the real ones; lower is closer).
    """
    synthetic = synthesize_image(clean, values, torch.Generator().manual_seed(seed)) - clean
    ratio = [float(r) for r in real.std(dim=(-2, -1)) / synthetic.std(dim=(-2, -1)).clamp_min(1e-6)]
    # Green's ratio scales shot and read; red's and blue's gains are relative to green.
    red, blue = (float(g) for g in values["channel_gain"].tolist())
    corrected = values.replace(
        shot=clipped("shot", values.scalar("shot") * ratio[1]),
        read=clipped("read", values.scalar("read") * ratio[1]),
        channel_gain=[
            clipped("channel_gain", red * ratio[0] / ratio[1]),
            clipped("channel_gain", blue * ratio[2] / ratio[1]),
        ],
    )
    if spatial:
        length = values.scalar("correlation_length")
        wanted = min(
            0.99, max(0.0, kernel_autocorrelation(length, 1) + lag1_correlation(real) - lag1_correlation(synthetic))
        )
        corrected = corrected.replace(correlation_length=length_for_lag1(wanted))
    synthetic = synthesize_image(clean, corrected, torch.Generator().manual_seed(seed)) - clean
    return corrected, _structure_score(real, synthetic)


def fit_srgb_noise(
    noisy: torch.Tensor,
    clean: torch.Tensor,
    components: OracleComponents = FULL,
    *,
    seed: int = 0,
) -> NoiseValues:
    """Fit the table's sRGB model to one real pair with its clean image (an oracle).

    Args:
        noisy: the real noisy image (3, H, W) in [0, 1].
        clean: its clean image (3, H, W) in [0, 1].
        components: which parts are fitted (ablations leave some neutral).
        seed: seed of the synthetic noise of the JPEG search.

    Returns:
        Unbatched noise values; the paper's quantization, banding and periodic components are neutral.
    """
    values = values_of_law(oracle_poisson_gaussian(noisy, clean), clean)
    unit = normalised_noise(noisy, clean, values)
    if components.spatial:
        values = values.replace(correlation_length=fit_correlation_length(autocorrelation(unit)))
    if components.chromatic:
        pairs = channel_correlations(unit)
        values = values.replace(channel_correlation=pairs if components.pairwise else sum(pairs) / len(pairs))
    if components.spatial and components.chromatic and components.chroma:
        brightness, colour = principal_noise(unit, values)
        length = fit_correlation_length(autocorrelation(brightness))
        colour_length = fit_correlation_length(autocorrelation(colour))
        chroma = clipped("chroma_length", math.sqrt(max(colour_length**2 - length**2, 0.0)))
        values = values.replace(correlation_length=length, chroma_length=chroma)
    if not components.jpeg:
        return values
    real = central_crop(noisy - clean, SEARCH_CROP)
    clean_crop = central_crop(clean, SEARCH_CROP)
    best, best_score = values, math.inf
    for quality in components.candidates:
        candidate = values.replace(compression=compression_of_quality(quality))
        corrected, score = correct_levels(candidate, real, clean_crop, seed, spatial=components.spatial)
        if score < best_score:
            best, best_score = corrected, score
    return best
