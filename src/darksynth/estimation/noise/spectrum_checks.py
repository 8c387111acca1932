"""What the spectral measurement could not read, said in its record and in one-line warnings: a level that the
reference's blocks could not show or that the network disagrees with, JPEG strengths that fit alike with different
levels, coarse colour the anchor could not read, and the denoiser's strength against the fitted noise."""

from __future__ import annotations

import math
from typing import Any

import torch
import torch.nn.functional as F

from darksynth.estimation.findings import Findings
from darksynth.estimation.noise.coarse_anchor import ANCHOR_SCALE_RANGE
from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK
from darksynth.estimation.noise.self_check import far_from_network, over_network
from darksynth.noise.spectral import level_std

JPEG_AMBIGUOUS = 1.5
"""A JPEG strength whose fit's mismatch is within this factor of the best's fits the reference about as well."""

LEVEL_SPREAD = 1.5
"""Levels of the JPEG strengths that fit about as well that differ by more than this are reported as uncertain."""


def level_checks(
    curve: torch.Tensor,
    measured: torch.Tensor,
    prior_curve: torch.Tensor | None,
    level_measured: bool,
    name: str,
) -> tuple[torch.Tensor, Findings]:
    """The fitted level curve (3, 8) std, or the network's where the reference showed no unclipped block, with
    findings that compare the two and warn where they disagree by more than
    :data:`~darksynth.estimation.noise.self_check.NETWORK_DISAGREEMENT` (at the measured knots)."""
    findings = Findings({"measured_knots": [[bool(k) for k in channel] for channel in measured.tolist()]})
    if prior_curve is None:
        return curve, findings
    prior_curve = prior_curve.to(curve)
    findings.meta["network_level_curve_8bit"] = [[round(float(v) * 255, 3) for v in c] for c in prior_curve]
    if not level_measured:
        findings.warnings.append(
            f"{name}: no block free of clipped pixels (crushed black or saturated): the noise level could not be "
            "measured; the profile holds the network's level curve"
        )
        findings.meta["level_source"] = "network: no unclipped block to measure on"
        return prior_curve.clone(), findings
    findings.meta["level_source"] = "measured on unclipped blocks; unmeasured knots follow the network's curve"
    if bool(measured.any()):
        ratio = over_network(curve, prior_curve, measured)
        if far_from_network(ratio):
            levels = [float(curve[measured].mean()) * 255, float(prior_curve[measured].mean()) * 255]
            findings.warnings.append(
                f"{name}: the measured noise level ({levels[0]:.2f} 8-bit levels) and the network's "
                f"({levels[1]:.2f}) differ by {max(ratio, 1 / ratio):.1f}x at the intensities the reference shows "
                "(the self-check decides which the profile keeps)"
            )
    return curve, findings


def fitted_noise_8bit(curve: torch.Tensor, denoised: torch.Tensor, mask: torch.Tensor) -> float:
    """The fitted noise std (mean over channels) at the brightest measured block of a denoised frame (3, H, W),
    in 8-bit levels: what the denoiser's strength was meant to be. Recorded beside the strength for diagnosis; on
    the round trip it does not separate the cases texture misleads (1.2-1.3 there as on good ones), so nothing
    warns on it."""
    blocks = F.avg_pool2d(denoised[None], FLAT_BLOCK)[0]
    measured = F.avg_pool2d(mask.reshape(-1, *mask.shape[-2:])[-1][None, None], FLAT_BLOCK)[0, 0] > 0.5
    if not bool(measured.any()):
        return math.inf
    std = level_std(blocks, curve.reshape(-1).to(blocks)).mean(0)
    return float(std[measured].max()) * 255


def mean_level(curve: torch.Tensor, measured: torch.Tensor) -> float:
    """Mean of a level curve (3, 8) over the ``measured`` knots (all when none), in 8-bit levels."""
    return float(curve[measured].mean() if bool(measured.any()) else curve.mean()) * 255


def compression_ambiguity(meta: dict[str, Any]) -> tuple[list[str], float, float] | None:
    """The JPEG strengths that fit about as well as the chosen one (score within :data:`JPEG_AMBIGUOUS` of the
    best) and the lowest and highest level they give, when those differ by more than :data:`LEVEL_SPREAD`: the
    reference cannot tell how much noise the compression took (weak noise under a strong JPEG reads like weaker
    noise under none), so the level is uncertain by that much."""
    scores: dict[str, float] = meta["compression_scores"]
    levels: dict[str, float] = meta["level_by_compression_8bit"]
    best = min(scores.values())
    plausible = [c for c, score in scores.items() if score <= JPEG_AMBIGUOUS * best]
    low, high = min(levels[c] for c in plausible), max(levels[c] for c in plausible)
    return (plausible, low, high) if high > LEVEL_SPREAD * max(low, 1e-6) else None


def readability_warnings(meta: dict[str, Any], curve: torch.Tensor, measured: torch.Tensor, name: str) -> list[str]:
    """The warnings of what the fit recorded in ``meta`` it could not read: JPEG strengths that fit alike with
    different levels (:func:`compression_ambiguity`), and coarse colour whose anchor ran to a bound of its range
    without moving its statistic (``meta["coarse_octave_prior"]``: the scale each released component had)."""
    warnings = []
    if (ambiguity := compression_ambiguity(meta)) is not None:
        strengths, low, high = ambiguity
        warnings.append(
            f"{name}: JPEG strengths {', '.join(strengths)} fit it about as well, with noise levels from {low:.2f} "
            f"to {high:.2f} 8-bit levels: how much noise the compression removed cannot be read, the level "
            f"({mean_level(curve, measured):.2f}) is uncertain by that much"
        )
    released = meta.get("coarse_octave_prior", {})
    if any(not ANCHOR_SCALE_RANGE[0] * 1.001 < scale < ANCHOR_SCALE_RANGE[1] * 0.999 for scale in released.values()):
        warnings.append(
            f"{name}: the coarse {' and '.join(released)} noise (11 px and coarser) could not be read (its fit ran "
            "to a bound without moving the variance about the flat blocks' planes): it continues the finer octaves"
        )
    return warnings
