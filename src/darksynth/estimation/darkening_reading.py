"""The darkening of a reference: alpha and gamma read off its tones against the prior of clean scenes, with the
reference's per-frame range for a clip and what the profile says about where they came from; and the reference's
tone target, which ``apply`` matches each input's exposure to.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.estimation.reference import Reference, spread_frames
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening
from darksynth.light.tone_blocks import NOISE_BLOCKS, BlockStatistics, block_side, block_statistics
from darksynth.light.tone_fit import (
    ALPHA_BOUNDS,
    GAMMA_BOUNDS,
    TONE_PRIOR_LOG_QUANTILES,
    DarkeningEstimate,
    fit_darkening,
)
from darksynth.light.tones import (
    PROBABILITIES,
    TONE_BLOCK,
    ToneTarget,
    colour_cast,
    luminance_quantiles,
    median_noise,
    noise_of_quantiles,
    sampled_blocks,
    tone_quantiles,
)


def estimate_darkening(
    frames: torch.Tensor,
    *,
    block: int = TONE_BLOCK,
    prior: tuple[float, ...] | np.ndarray = TONE_PRIOR_LOG_QUANTILES,
    use_prior: bool = True,
    source: str = "reference",
) -> DarkeningEstimate:
    """Estimate alpha and gamma of a low-light reference.

    Args:
        frames: reference frames (T, C, H, W) or one frame (C, H, W), values on the [0, 1] scale; all frames
            are pooled.
        block: side of the median blocks (the prior was measured with :data:`~darksynth.light.tones.TONE_BLOCK`;
            keep it).
        prior: mean clean log quantiles measured with the same ``block``.
        use_prior: see :func:`fit_darkening`.
        source: the name error messages start with.

    Returns:
        The estimate; see :class:`DarkeningEstimate` for its confidence.

    Raises:
        DarksynthError: the reference is too dark (all black) or too flat to tell a tone curve.
    """
    if frames.dim() not in (3, 4):
        raise ValueError(f"expected frames shaped (T, C, H, W) or (C, H, W), got shape {tuple(frames.shape)}")
    quantiles = tone_quantiles(frames, block=block)
    return fit_darkening(quantiles, median_noise(frames, block), prior=prior, use_prior=use_prior, source=source)


def estimate_darkening_pooled_and_per_frame(
    frames: torch.Tensor,
    *,
    block: int = TONE_BLOCK,
    source: str = "reference",
    statistics: list[BlockStatistics] | None = None,
) -> tuple[DarkeningEstimate, list[DarkeningEstimate | None]]:
    """:func:`estimate_darkening` of frames (T, C, H, W) pooled, and of each frame alone (None where one is too
    dark or flat), from one sort of each frame's blocks (:func:`~darksynth.light.tone_blocks.block_statistics`; given
    as ``statistics`` when the caller has them) instead of four passes.

    The pooled figures are read from the frames' block statistics concatenated in frame order, the order in which
    :func:`estimate_darkening` reads them: the same numbers, as long as one frame's blocks are few enough to be
    read without subsampling (up to :data:`NOISE_BLOCKS`, past 4K per frame); past that the pooled noise is read
    from every step-th block of the frames' subsamples.

    Raises:
        DarksynthError: the pooled reference is too dark or too flat (see :func:`estimate_darkening`).
    """
    medians, centres, uppers = [], [], []
    per_frame: list[DarkeningEstimate | None] = []
    side = block_side(frames, block)
    if statistics is None:
        statistics = [block_statistics(frame, block) for frame in frames]
    for found in statistics:
        frame_medians = found.medians.flatten().numpy().astype(np.float64)
        centre, upper = found.noise_quantiles()
        medians.append(frame_medians)
        centres.append(centre)
        uppers.append(upper)
        per_frame.append(_fit_or_none(frame_medians, centre, upper, side, source))
    centre_all, upper_all = torch.cat(centres), torch.cat(uppers)
    step = max(1, centre_all.shape[0] // NOISE_BLOCKS)
    pooled_noise = noise_of_quantiles(centre_all[::step], upper_all[::step], side)
    pooled = fit_darkening(np.quantile(np.concatenate(medians), PROBABILITIES), pooled_noise, source=source)
    return pooled, per_frame


def estimate_darkening_spread(
    frames: torch.Tensor,
    *,
    regions: int = 2,
    block: int = TONE_BLOCK,
    source: str = "reference",
    statistics: list[BlockStatistics] | None = None,
) -> list[DarkeningEstimate]:
    """Estimates on parts of the reference: each frame cut into ``regions`` x ``regions`` tiles.

    The spread of these estimates shows how much the content, rather than the camera, moves the estimate;
    regions too dark to fit are skipped (the list may be empty). ``statistics``: each frame's
    :func:`~darksynth.light.tone_blocks.block_statistics`, which a region on their block grid reads its own from.
    """
    if frames.dim() == 3:
        frames = frames[None]
    height, width = frames.shape[-2], frames.shape[-1]
    rows = np.linspace(0, height, regions + 1).round().astype(int)
    columns = np.linspace(0, width, regions + 1).round().astype(int)
    estimates = []
    for index, frame in enumerate(frames):
        whole = statistics[index] if statistics is not None else block_statistics(frame, block)
        for top, bottom in itertools.pairwise(rows):
            for left, right in itertools.pairwise(columns):
                part = frame[:, top:bottom, left:right]
                if min(part.shape[-2:]) < block:
                    continue
                found = whole.region(top, bottom, left, right) or block_statistics(part, block)
                block_medians = found.medians.flatten().numpy().astype(np.float64)
                estimate = _fit_or_none(block_medians, *found.noise_quantiles(), found.side, source)
                if estimate is not None:
                    estimates.append(estimate)
    return estimates


def _fit_or_none(
    block_medians: np.ndarray, centre: torch.Tensor, upper: torch.Tensor, side: int, source: str
) -> DarkeningEstimate | None:
    """The darkening fitted to one frame's or region's blocks (their medians and noise quantiles, as
    :class:`~darksynth.light.tone_blocks.BlockStatistics` gives them); None where they are too dark or too flat."""
    quantiles = np.quantile(block_medians, PROBABILITIES)
    try:
        return fit_darkening(quantiles, noise_of_quantiles(centre, upper, side), source=source)
    except DarksynthError:
        return None


DARKENING_FRAMES = 3
"""Frames (evenly spread) on which the darkening and its per-frame range are estimated."""

DARKENING_BLOCKS = 1 << 18
"""At most about this many 4x4 blocks per channel and frame are read for the darkening (every k-th block row and
column beyond): a 1080p or smaller frame is read whole, a 12 MP photo on a quarter of its blocks."""

LOW_DARKENING_CONFIDENCE = 0.1
"""Below this confidence (:attr:`~darksynth.light.tone_fit.DarkeningEstimate.confidence`) the darkening estimate
comes with a note in the profile's ``meta``.

On held-out Kodak images (``scripts/den/estimate_warnings.py --confidence``) the median tone-curve error is 0.43
below 0.1 (90th percentile 1.12) against 0.21-0.33 above it; a threshold of 0.2 would flag half of those images
and of the real references, while the estimates between 0.1 and 0.2 (error 0.33) are about as good as those
between 0.2 and 0.3 (0.31)."""


SEARCH_BOUNDS = {"alpha": ALPHA_BOUNDS, "gamma": GAMMA_BOUNDS}

PRIOR_DOMINATES = 0.5
"""A darkening parameter whose precision comes more than this share from the prior is reported as the prior's."""

_BOUND_MEANING = {
    ("alpha", "lower"): "darker",
    ("alpha", "upper"): "brighter",
    ("gamma", "lower"): "steeper in the shadows",
    ("gamma", "upper"): "flatter (brighter mid-tones)",
}


def _darkening_origin(name: str, value: float, found: DarkeningEstimate) -> dict[str, Any]:
    """Where an estimated alpha or gamma came from: the reference's tones, the paper's prior, or a bound."""
    share = found.prior_share.get(name)
    if name in found.bounds_hit:
        origin = f"fit, clipped to the {found.bounds_hit[name]} bound of its search range {list(SEARCH_BOUNDS[name])}"
    elif share is not None and share > PRIOR_DOMINATES:
        origin = "mostly prior: the reference's tones leave it undetermined, the paper's range sets it"
    else:
        origin = "fit to the reference's tones"
    return {"value": round(value, 4), "source": origin, "prior_share": None if share is None else round(share, 3)}


@dataclass(frozen=True)
class DarkeningReading:
    """What :func:`estimate_profile_darkening` read: the darkening (None: not readable), the tone target, a clip's
    per-frame ranges of alpha and gamma, the profile's ``meta.darkening`` and the warnings."""

    darkening: Darkening | None
    tone: ToneTarget | None
    ranges: dict[str, tuple[tuple[float, float], ...]]
    meta: dict[str, Any]
    warnings: list[str]


def estimate_profile_darkening(reference: Reference) -> DarkeningReading:
    """The reference's darkening, its per-frame range for a clip, and how it was found; and its tone quantiles,
    which ``apply`` matches each input's exposure to.

    A reference too dark to read gives no darkening (``apply`` then falls back to the paper's ranges) and a
    warning, not an error: the noise estimate is still good.
    """
    # The tone distribution is read on a few frames spread over the clip: more frames of one scene add time,
    # not information (all 16 frames of a 1080p clip took 6 s more).
    source = reference.name
    frames = reference.frames[spread_frames(reference.frames.shape[0], DARKENING_FRAMES)]
    # Each frame's blocks sorted once (a photo's regions below are read from the same sort), on a sample of a large
    # frame's blocks: a 12 MP photo's 750 k a channel fix its tone quantiles no better than a quarter of them.
    sampled = sampled_blocks(frames, most=DARKENING_BLOCKS)
    statistics = [block_statistics(frame, TONE_BLOCK) for frame in sampled]
    try:
        # The pooled estimate and each frame's own (for the clip's range) from one pass over the frames.
        found, per_frame_found = estimate_darkening_pooled_and_per_frame(sampled, source=source, statistics=statistics)
    except DarksynthError as error:
        meta = {
            "method": "not estimated: too dark or too flat",
            "alpha": {"source": f"prior: apply draws it from the paper's range {list(ALPHA_RANGE)}"},
            "gamma": {"source": f"prior: apply draws it from the paper's range {list(GAMMA_RANGE)}"},
        }
        warning = f"{error}; the profile has no darkening, apply will draw it from the paper's ranges"
        return DarkeningReading(None, None, {}, meta, [warning])
    # A single image has no frames to spread over: its four regions say how much the estimate depends on content.
    regions = estimate_darkening_spread(sampled[:1], statistics=statistics) if reference.frames.shape[0] == 1 else []
    meta = _darkening_meta(found, regions)
    notes = _darkening_notes(found, source)
    if notes:
        meta["notes"] = [
            *notes,
            "apply and synthesize match each input to the reference's tones (the profile's tone), not to this alpha "
            "and gamma, which remain the profile's darkening for readers that do not match",
        ]
    ranges: dict[str, tuple[tuple[float, float], ...]] = {}
    if frames.shape[0] > 1:
        per_frame = [estimated.darkening for estimated in per_frame_found if estimated is not None]
        if len(per_frame) > 1:
            ranges = _per_frame_ranges(found.darkening, per_frame)
            meta["ranges"] = "10th-90th percentile over frames"
    return DarkeningReading(found.darkening, _tone_target(found, frames), ranges, meta, [])


def _darkening_meta(found: DarkeningEstimate, regions: list[DarkeningEstimate]) -> dict[str, Any]:
    """How the darkening was found: the fit's figures, where alpha and gamma came from, and for an image the 10th
    and 90th percentile of its regions' estimates (None for a clip)."""

    def region_percentiles(name: str) -> list[float] | None:
        if not regions:
            return None
        return [round(float(v), 4) for v in np.percentile([getattr(e.darkening, name) for e in regions], [10, 90])]

    return {
        "method": "tone quantiles of 4x4 block medians fitted to the clean-image prior (docs/darkening-estimate.md)",
        "quantiles_used": found.quantiles_used,
        "fit_rms": round(found.fit_rms, 4),
        "confidence": round(found.confidence, 3),
        **{name: _darkening_origin(name, float(getattr(found.darkening, name)), found) for name in ("alpha", "gamma")},
        "region_alpha": region_percentiles("alpha"),
        "region_gamma": region_percentiles("gamma"),
    }


def _darkening_notes(found: DarkeningEstimate, source: str) -> list[str]:
    """Doubts about the fitted alpha and gamma: a bound hit, a low confidence.

    ``apply`` matches each input to the reference's tones (the profile's tone), not to this (alpha, gamma), so the
    doubts are notes in ``meta``, not warnings (as warnings they fired on 19 of 20 held-out photos).
    """
    notes: list[str] = []
    for name, side in found.bounds_hit.items():
        low, high = SEARCH_BOUNDS[name]
        notes.append(
            f"{source}: the fitted {name} sits on the {side} bound {high if side == 'upper' else low:g} of its "
            f"search range [{low:g}, {high:g}]: the tone curve is {_BOUND_MEANING[name, side]} than the darkening "
            "can express"
        )
    if found.confidence < LOW_DARKENING_CONFIDENCE:
        notes.append(
            f"{source}: the darkening estimate is uncertain (confidence {found.confidence:.2f} < "
            f"{LOW_DARKENING_CONFIDENCE}: {found.quantiles_used} of {len(PROBABILITIES)} tone quantiles usable, "
            f"fit rms {found.fit_rms:.2f}{', a bound hit' if found.clipped else ''}); on held-out images such "
            "estimates have about twice the tone-curve error"
        )
    return notes


def _per_frame_ranges(point: Darkening, per_frame: list[Darkening]) -> dict[str, tuple[tuple[float, float], ...]]:
    """The ranges of alpha and gamma over a clip's frames: their 10th to 90th percentile, widened to hold the
    pooled estimate ``point``."""
    ranges: dict[str, tuple[tuple[float, float], ...]] = {}
    for name in ("alpha", "gamma"):
        value = getattr(point, name)
        low, high = np.percentile([getattr(d, name) for d in per_frame], [10, 90])
        ranges[name] = ((min(float(low), value), max(float(high), value)),)
    return ranges


def _tone_target(found: DarkeningEstimate, frames: torch.Tensor) -> ToneTarget:
    """What ``apply`` matches each input's exposure to: the reference's block-median tone quantiles and their
    noise (from ``found``), its colour cast and the quantiles of its pixels' luminance, read on ``frames``."""
    return ToneTarget(
        quantiles=found.tone_quantiles,
        noise=found.block_noise,
        colour=colour_cast(frames),
        luminance=tuple(float(q) for q in luminance_quantiles(frames)),
    )
