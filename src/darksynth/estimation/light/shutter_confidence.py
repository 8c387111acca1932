"""How far a clip's blocks can support a reading of its shutter: what :mod:`darksynth.estimation.light.motion` checks.

The blur's transfer along the motion is ``sinc^2(pi s k.d)``: shutters in [0, 1] differ only at frequencies whose
projection on the displacement ``k.d`` is a sizeable fraction of a cycle, and only where the scene has power there
above the noise. A clip whose blocks hold no such power (flat, dark, too noisy), or whose blocks each say something
different, cannot be read however the fit is done. Three measured quantities say so:

- the spread of the reading when the scene's blocks are resampled (:func:`resampled_readings`): a cluster
  bootstrap over the parts of the scene the blocks show, the blocks of one part (seen in several frame pairs)
  drawn together; the confidence is the share of resampled readings within :data:`TOLERANCE` of the reading;
- the texture's contrast against the noise on the frequencies that tell shutters apart (:func:`contrast_along`);
- how far each block's motion is ambiguous (:func:`motion_ambiguity`): a periodic texture matches itself at
  another shift, so its flow and its blur length can alias;
- whether the frames show JPEG's 8-px blocks (:func:`compression_blockiness`): its quantization reshapes the
  spectrum the same way in every block, so the blocks agree on a wrong reading and resampling them cannot see it.
"""

from __future__ import annotations

import numpy as np

TOLERANCE = 0.15
"""How close to the truth a reading of the exposure fraction is meant to be (the shutter harness's bar on the
median error): the confidence is the share of resampled readings this close to the reading."""

MIN_CONFIDENCE = 0.5
"""Below this the reading is more likely off by more than :data:`TOLERANCE` than within it, and the prior (which is
never more than 0.5 off a shutter in [0, 1]) is the better guess."""

MIN_CONFIDENCE_COMPRESSED = 0.98
"""The confidence asked of a reading when the frames show JPEG's blocks (:data:`BLOCKY`): the quantization (one
table for the whole frame) moves every block's reading alike, so the resampled spread understates the error. On the
shutter harness's develop cases (seeds 0-479) all 9 JPEG readings off by more than 0.5 had a confidence of at most
0.97, and 153 of the 206 JPEG readings reach 0.98 (a fallback costs at most 0.5, a confident miss more)."""

BLOCKY = 1.06
"""Above this :func:`compression_blockiness` the frames show JPEG's 8-px blocks: on the harness's develop cases
frames never compressed read at most 1.05, 95 % of the JPEG ones (quality 60-95, noise 0.5-15 levels) above it
and 90 % above 1.13."""

RESAMPLES = 200
"""Cluster-bootstrap resamples: the share within :data:`TOLERANCE` to about 3 % (binomial, at 0.5)."""

AMBIGUOUS_PEAK = 0.5
"""A block whose cross-correlation has a second peak, away from the blur's own ridge, at least this share of the
main one is matched about as well at another shift (a periodic texture): its motion, and so its blur length,
can alias. Half: the other shift explains at least half the correlation the right one does."""


def scene_cells(places: np.ndarray, size: int) -> np.ndarray:
    """Cluster index (N,) of each block, from its place (N, 2) (y, x) in the first frame's coordinates: blocks
    within one ``size``-px cell show the same part of the scene (in different frame pairs) and are not independent
    evidence."""
    cells = np.floor(places / size).astype(np.int64)
    _, index = np.unique(cells, axis=0, return_inverse=True)
    return np.asarray(index).reshape(-1)


def resampled_readings(scores: np.ndarray, grid: np.ndarray, cells: np.ndarray, seed: int = 0) -> np.ndarray:
    """The pooled reading (the grid value of the largest summed score) of :data:`RESAMPLES` cluster-bootstrap
    resamples: ``scores`` (G, N) per grid value and block, ``cells`` (N,) the blocks' clusters."""
    count = int(cells.max()) + 1
    rng = np.random.default_rng(seed)
    drawn = rng.multinomial(count, np.full(count, 1.0 / count), size=RESAMPLES)  # (R, clusters)
    weights = drawn[:, cells].astype(scores.dtype)  # (R, N)
    readings: np.ndarray = grid[np.argmax(weights @ scores.T, axis=1)]
    return readings


def reading_confidence(readings: np.ndarray, reading: float) -> float:
    """Share of the resampled readings within :data:`TOLERANCE` of the reading."""
    return float(np.mean(np.abs(readings - reading) <= TOLERANCE + 1e-9))


def box_transfer(length: np.ndarray) -> np.ndarray:
    """The power transfer ``sinc^2(pi L k)`` of a box blur, given ``L k`` (the box's length times the frequency
    along it, cycles): 1 at 0, 0 at every whole number."""
    small = np.abs(length) < 1e-6
    safe = np.where(small, 1.0, length)
    transfer: np.ndarray = np.where(small, 1.0, (np.sin(np.pi * safe) / (np.pi * safe)) ** 2)
    return transfer


def discriminating(along: np.ndarray) -> np.ndarray:
    """How much the transfer ``sinc^2(pi s k.d)`` changes over s in [0, 1] at each frequency, given ``along`` =
    |k.d| (cycles per frame's displacement): 1 - sinc^2(pi k.d), 0 across the motion, near 1 from a cycle on."""
    return 1.0 - box_transfer(along)


def contrast_along(cross: np.ndarray, noise: np.ndarray, along: np.ndarray) -> float:
    """The scene's power against the noise's on the frequencies that tell shutters apart: cross power (the scene's
    power times the blur, the noise cancelled) and noise power (auto minus cross), each weighted by
    :func:`discriminating`, summed over all blocks. Below 1 the noise outweighs what the blur left of the scene."""
    weight = discriminating(along)
    scene = float((weight * np.clip(cross, 0.0, None)).sum())
    floor = float((weight * np.clip(noise, 0.0, None)).sum())
    return scene / max(floor, 1e-30)


def persistent_share(persistent: np.ndarray, cross: np.ndarray, along: np.ndarray) -> float:
    """Share of the cross power, on the frequencies that tell shutters apart (weighted by :func:`discriminating`),
    that was noise staying in place (``persistent``, taken out) rather than the scene (``cross``, kept)."""
    weight = discriminating(along)
    taken = float((weight * np.abs(persistent)).sum())
    return taken / max(taken + float((weight * np.abs(cross)).sum()), 1e-30)


def motion_ambiguity(product: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """Per block (N,): the highest local peak of the pair's cross-correlation away from the blur's ridge, as a
    share of the peak at no shift. ``product`` (N, B, B//2+1) the aligned cross spectra (the second block moved onto
    the first), ``motion`` (N, 2) (dy, dx) px/frame.

    A local peak (above its 8 neighbours), not any high value: a natural texture's steep spectrum makes the
    correlation a broad hill, high at any small shift but falling away from the centre; a periodic texture rises
    again at each period. The ridge (a box of up to one displacement each way, correlated with itself) and 3 px
    around it are left out."""
    size = product.shape[-2]
    correlation = np.fft.irfft2(product, s=(size, size), axes=(-2, -1))
    peak = np.ones(correlation.shape, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                peak &= correlation > np.roll(correlation, (dy, dx), axis=(-2, -1))
    offsets = np.fft.fftfreq(size, 1.0 / size)
    dy_grid, dx_grid = offsets[:, None], offsets[None, :]
    length = np.maximum(np.hypot(motion[:, 0], motion[:, 1]), 1e-9)
    unit_y, unit_x = motion[:, 0] / length, motion[:, 1] / length
    along = dy_grid[None] * unit_y[:, None, None] + dx_grid[None] * unit_x[:, None, None]
    across = np.abs(dy_grid[None] * unit_x[:, None, None] - dx_grid[None] * unit_y[:, None, None])
    beyond = np.maximum(np.abs(along) - length[:, None, None], 0.0)
    away = peak & (np.hypot(beyond, across) > 3.0)
    centre = np.maximum(correlation[:, 0, 0], 1e-30)
    second = np.where(away, correlation, 0.0).reshape(len(product), -1).max(axis=1)
    ambiguity: np.ndarray = np.clip(second / centre, 0.0, None)
    return ambiguity


def compression_blockiness(luminance: np.ndarray) -> float:
    """How much more the image changes across the boundaries of an 8-px grid anchored at the frame's corner than
    between other neighbouring pixels: ``luminance`` (T, H, W); the mean absolute difference between neighbours,
    per position modulo 8, at the boundary (7 -> 8) over the median of the other seven, averaged over rows and
    columns. 1 for content with no grid; JPEG's blocks (and a codec's 8-px transforms) raise it."""
    ratios = []
    for axis in (2, 1):
        steps = np.abs(np.diff(luminance.astype(np.float32), axis=axis))
        profile = steps.mean(axis=(0, 1) if axis == 2 else (0, 2))
        whole = len(profile) // 8 * 8
        if whole < 16:
            continue
        by_phase = profile[:whole].reshape(-1, 8).mean(axis=0)
        inside = float(np.median(by_phase[:7]))
        if inside > 1e-9:
            ratios.append(float(by_phase[7]) / inside)
    return float(np.mean(ratios)) if ratios else 1.0
