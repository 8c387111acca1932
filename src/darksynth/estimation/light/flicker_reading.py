"""The exposure flicker of a reference clip: the per-frame gain of its still parts, with the noise cancelled.

Only pixels that stay still through a run of frames are read (the flows of the frame pairs, measured by
:mod:`darksynth.estimation.light.motion`, say which), split into two halves by alternating bands of columns. Per frame a
gain times the level plus an offset is fitted across groups of pixels of different brightness (the offset takes a
frame-wide noise term that would otherwise read as flicker), and the covariance of the two halves' gain series
gives the flicker's variance with the noise, independent between the halves, cancelled. A camera's auto-exposure
drifting over the clip counts as flicker too: both are a gain on the frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

FLICKER_PRIOR = 0.0
"""When flicker cannot be measured: none (a steady light and a locked exposure)."""

FLICKER_CORRELATION_PRIOR = 0.0
"""With no flicker, its correlation has no meaning; 0 keeps the profile's default of independent frames."""

STILL_SPEED = 0.3
"""Pixels moving less than this (px/frame) are still for the flicker measurement."""

MIN_FLICKER_FRAMES = 3
"""A stretch of still frames shorter than this says nothing about the frame-to-frame gain."""

FLICKER_GRID = 8
"""The still pixels are split into alternate bands of columns, this many of each half across the frame."""

MIN_STILL_PIXELS = 256
"""Fewer still pixels (at the flow's resolution) in a half: the stretch is not read for flicker."""

LEVEL_GROUPS = 8
"""Groups of still pixels by level (quantiles) in which gain and offset are told apart."""

MIN_LEVEL_SPREAD = 0.15
"""Below this std of the groups' levels relative to their mean, a gain and an offset look alike: the gain alone
is fitted (an offset then reads as flicker)."""


@dataclass(frozen=True)
class PairFlow:
    """The flow of one consecutive pair (t, t+1) at the flow's resolution, in full-resolution px/frame."""

    first: int
    flow: np.ndarray  # (h, w, 2) x, y
    valid: np.ndarray  # (h, w) bool: passed the forward-backward check
    scale: float  # full-resolution px per px of the flow map


def measure_flicker(luminance: np.ndarray, flows: list[PairFlow], frames: int) -> tuple[float, float, int, str | None]:
    """Flicker std and lag-1 correlation read on still pixels; frames used; the reason when not measured."""
    if frames < MIN_FLICKER_FRAMES:
        return 0.0, 0.0, 0, f"{frames} frame(s), fewer than {MIN_FLICKER_FRAMES}"
    by_first = {f.first: f for f in flows}
    stretches: list[list[int]] = []
    for t in range(frames):
        # Every frame joins the last stretch or starts one: frame t - 1 ends the last stretch.
        if t - 1 in by_first:
            stretches[-1].append(t)
        else:
            stretches.append([t])
    stretches = [s for s in stretches if len(s) >= MIN_FLICKER_FRAMES]
    if not stretches:
        return (
            0.0,
            0.0,
            0,
            f"no stretch of {MIN_FLICKER_FRAMES} comparable frames "
            "(scene cuts, uniform frames, flow that does not invert)",
        )
    variance_sum = lag_sum = 0.0
    own_first = own_second = 0.0
    lengths = []
    for stretch in stretches:
        halves = _gain_series(luminance, [by_first[t] for t in stretch[:-1]], stretch)
        if halves is None:
            continue
        first, second = halves
        # The two halves share the gain, not the noise: their cross products hold the gain's variance alone.
        variance_sum += float((first * second).sum())
        own_first += float((first**2).sum())
        own_second += float((second**2).sum())
        lag_sum += 0.5 * float((first[1:] * second[:-1]).sum() + (second[1:] * first[:-1]).sum())
        lengths.append(len(stretch))
    used = sum(lengths)
    if used == 0:
        return 0.0, 0.0, 0, "no part of the frame stays still through the clip"
    # The cross product's own scatter, from the two halves' variances (noise included): a gain whose variance is
    # within twice of it is too weak to read its correlation on.
    scatter = math.sqrt(own_first * own_second / used)
    if variance_sum <= 2.0 * scatter:
        return math.sqrt(max(variance_sum, 0.0) / used), 0.0, used, None
    raw_correlation = float(np.clip(lag_sum / variance_sum, -1.0, 1.0))
    # A de-meaned AR(1) series of n frames: E[r] ~ rho - (1 + 3 rho) / n (Kendall), and its variance is short by
    # the variance of its mean, about (1 + rho) / ((1 - rho) n) of it.
    n = float(np.mean(lengths))
    correlation = float(np.clip((raw_correlation * n + 1.0) / max(n - 3.0, 1.0), 0.0, 0.99))
    shortfall = min(0.8, (1.0 + correlation) / ((1.0 - correlation) * n))
    variance = variance_sum / used / (1.0 - shortfall)
    return math.sqrt(variance), correlation, used, None


def _gain_series(
    luminance: np.ndarray, flows: list[PairFlow], stretch: list[int]
) -> tuple[np.ndarray, np.ndarray] | None:
    """The relative gain g_t / mean(g) - 1 of a stretch, read twice on disjoint halves of its still pixels.

    In each half the still pixels are grouped by their level; per frame, the groups' change from their mean
    level is fitted as ``gain * level + offset``. The offset takes what adds the same to every pixel of a frame
    (a sensor's black level wandering, the frame-wide term of darksynth's periodic noise), which a plain mean
    would read as flicker; only the gain remains. The halves are alternate bands of columns, so that column noise
    falls in one of them alone. Without a spread of levels, the offset cannot be told from the gain, and the
    fit is the gain alone.
    """
    still = np.ones_like(flows[0].valid)
    for flow in flows:
        speed = np.hypot(flow.flow[..., 0], flow.flow[..., 1])
        moving = ~flow.valid | (speed >= STILL_SPEED)
        # Blur and interpolation carry a moving object's light a few px beyond where the flow says it is.
        still &= cv2.dilate(moving.astype(np.uint8), np.ones((5, 5), np.uint8)) == 0
    stack = luminance[stretch].astype(np.float64)
    level = cv2.GaussianBlur(stack.mean(axis=0), (0, 0), 2.0)
    # Saturated pixels do not follow a gain; pixels near black are clipped at 0 by their noise.
    still &= (level > 1.0 / 255) & (level < 0.9)
    width = still.shape[1]
    band = max(1, width // (2 * FLICKER_GRID))
    column_half = (np.arange(width) // band) % 2
    halves = []
    for half in (0, 1):
        mask = still & (column_half == half)[None, :]
        if mask.sum() < MIN_STILL_PIXELS:
            return None
        halves.append(_fitted_gain(stack[:, mask], level[mask]))
    return halves[0], halves[1]


def _fitted_gain(values: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Per frame, the relative gain fitted to pixels (T, N) grouped by their (smoothed) ``level`` (N,)."""
    edges = np.quantile(level, np.linspace(0, 1, LEVEL_GROUPS + 1))
    group = np.clip(np.searchsorted(edges, level, side="right") - 1, 0, LEVEL_GROUPS - 1)
    counts = np.bincount(group, minlength=LEVEL_GROUPS).astype(np.float64)
    present = counts > 0
    sums = np.stack([np.bincount(group, weights=frame, minlength=LEVEL_GROUPS) for frame in values])
    means = sums[:, present] / counts[present]
    weight = counts[present]
    mean_level = means.mean(axis=0)
    change = means - mean_level
    centre = float((weight * mean_level).sum() / weight.sum())
    spread = mean_level - centre
    if float((weight * spread**2).sum() / weight.sum()) >= (MIN_LEVEL_SPREAD * centre) ** 2:
        slope = (change * weight * spread).sum(axis=1) / float((weight * spread**2).sum())
    else:
        slope = (change * weight * mean_level).sum(axis=1) / float((weight * mean_level**2).sum())
    return np.asarray(slope)
