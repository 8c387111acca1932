"""Clean-aided (oracle) fit of the sRGB noise model, in the parameter table's terms.

The model is the one of :mod:`darksynth.noise.components` (green's shot and read, red's and blue's
``channel_gain``, one ``correlation_length``, the three pairwise ``channel_correlation`` values,
``compression``); the fit returns :class:`~darksynth.noise.values.NoiseValues` and every synthetic image goes
through the one composer, :func:`darksynth.noise.simulate.add_noise`. From one real pair (noisy, clean),
float64 (3, H, W) on the [0, 1] scale:

1. the per-channel Poisson-Gaussian law var = a_c x + b_c of noisy - clean against clean
   (:func:`~darksynth.evaluation.classical.oracle_poisson_gaussian`). Green's law gives shot = sqrt(a_g) and
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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

from darksynth.evaluation.classical import PoissonGaussian, oracle_poisson_gaussian
from darksynth.noise.components import noise_parameter
from darksynth.noise.correlated import kernel_autocorrelation
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels

MAX_LAG = 3
"""Autocorrelation lags (pixels) the correlation length is fitted on."""

LENGTH_GRID = tuple(round(0.02 * i, 2) for i in range(0, 201))
"""Candidate correlation lengths, 0 to 4 pixels."""

JPEG_CANDIDATES: tuple[int | None, ...] = (None, 60, 70, 80, 90, 95)
"""Candidate JPEG qualities of the search (None: no compression)."""

SEARCH_CROP = 256
"""Side of the central crop the JPEG search synthesises on (aligned to the 16-pixel JPEG grid)."""

CHANNEL_PAIRS = ((0, 1), (1, 2), (0, 2))
"""The channel pairs of ``channel_correlation``, in the table's order: red-green, green-blue, red-blue."""


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


def _clipped(name: str, value: float) -> float:
    parameter = noise_parameter(name)
    return min(parameter.maximum, max(parameter.minimum, value))


def compression_of_quality(quality: int | None) -> float:
    """The compression strength c = 1 - q / 100 of a JPEG quality q (0 for none), within the table's bounds."""
    return 0.0 if quality is None else _clipped("compression", 1.0 - quality / 100.0)


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
        gains.append(_clipped("channel_gain", math.sqrt(own / green)) if green > 0.0 else 1.0)
    return NoiseValues.from_values(
        {
            "shot": _clipped("shot", math.sqrt(green_a)),
            "read": _clipped("read", math.sqrt(green_b)),
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
    return _clipped("correlation_length", float(LENGTH_GRID[int(np.argmin(error))]))


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


def channel_correlations(unit: torch.Tensor) -> list[float]:
    """Correlation coefficients of red-green, green-blue and red-blue noise in a (3, H, W) map."""
    matrix = torch.corrcoef(unit.reshape(unit.shape[0], -1))
    return [_clipped("channel_correlation", float(matrix[i, j])) for i, j in CHANNEL_PAIRS]


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


def _lag1(noise: torch.Tensor) -> float:
    """Lag-1 autocorrelation along x and y together."""
    centred = noise - noise.mean(dim=(-2, -1), keepdim=True)
    along_x, along_y = autocorrelation(centred, 1)
    return 0.5 * (along_x[0] + along_y[0])


def _length_for_lag1(correlation: float) -> float:
    index = int(np.argmin(np.abs(_theory_table()[:, 0] - correlation)))
    return _clipped("correlation_length", float(LENGTH_GRID[index]))


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
        shot=_clipped("shot", values.scalar("shot") * ratio[1]),
        read=_clipped("read", values.scalar("read") * ratio[1]),
        channel_gain=[
            _clipped("channel_gain", red * ratio[0] / ratio[1]),
            _clipped("channel_gain", blue * ratio[2] / ratio[1]),
        ],
    )
    if spatial:
        length = values.scalar("correlation_length")
        wanted = min(0.99, max(0.0, kernel_autocorrelation(length, 1) + _lag1(real) - _lag1(synthetic)))
        corrected = corrected.replace(correlation_length=_length_for_lag1(wanted))
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
        chroma = _clipped("chroma_length", math.sqrt(max(colour_length**2 - length**2, 0.0)))
        values = values.replace(correlation_length=length, chroma_length=chroma)
    if not components.jpeg:
        return values
    real = _central_crop(noisy - clean, SEARCH_CROP)
    clean_crop = _central_crop(clean, SEARCH_CROP)
    best, best_score = values, math.inf
    for quality in components.candidates:
        candidate = values.replace(compression=compression_of_quality(quality))
        corrected, score = correct_levels(candidate, real, clean_crop, seed, spatial=components.spatial)
        if score < best_score:
            best, best_score = corrected, score
    return best
