"""The exposure fraction fitted to the cross spectra of moving block pairs, and whether the blocks support it.

:mod:`darksynth.estimation.light.motion` pairs the blocks and aligns their cross spectra; here the scene's power in each
frequency ring is compared with the box's transfer ``sinc^2(pi s k.d)`` (the fit, in :func:`fit_exposure`) and the
reading is given only where the blocks can support it (:mod:`darksynth.estimation.light.shutter_confidence`): else the
prior, with one line naming what could not be read and why.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from darksynth.estimation.light.cross_spectra import frequencies, ring_membership
from darksynth.estimation.light.shutter_confidence import (
    AMBIGUOUS_PEAK,
    BLOCKY,
    MIN_CONFIDENCE,
    MIN_CONFIDENCE_COMPRESSED,
    TOLERANCE,
    box_transfer,
    contrast_along,
    motion_ambiguity,
    persistent_share,
    reading_confidence,
    resampled_readings,
    scene_cells,
)

MOTION_BLOCK = 64
"""Side (px, full resolution) of the blocks whose blur is measured: 32 frequency rings, enough below the first
zero of a box of a few px."""

MIN_SPEED = 1.5
"""Blocks moving less than this (px/frame) are not measured: a box shorter than a pixel barely changes the
spectrum below the Nyquist frequency, so slow blocks say little, and in the real clips the flow of the darkest
ones follows the noise at about 1 px/frame (their fit then reads compression and in-camera processing as blur)."""

MIN_BLOCKS = 6
"""Fewer moving textured blocks than this: the blur is not measured (the prior is used)."""

S_GRID = np.linspace(0.0, 2.0, 101)
"""Candidate exposure fractions for the fit: steps of 0.05 first (:data:`COARSE_GRID`), then of 0.02 around the
best, refined by a parabola through the best three (the score is smooth in s: one broad peak). Up to 2, beyond any
shutter: a camera that blends frames over time (temporal noise reduction, frame averaging in the dark) smears
motion further than a shutter open for the whole interval, and a grid that stopped at 1 would read such a clip as
exactly 1, not as what it is (the profile holds the value at 1, with a warning that says why)."""

COARSE_GRID = np.linspace(0.0, 2.5, 51)
"""The first pass of the fit, also where the halves and the resampled readings are found: steps of 0.05, a third
of :data:`~darksynth.estimation.light.shutter_confidence.TOLERANCE`, so that the resampled readings resolve it. It runs
past the end of :data:`S_GRID`: a best fit held at 2 hides how far beyond it the data would go (texture or
processing that smears more along the motion than frame blending does); its resampled readings, beyond 2, then
give it a low confidence."""

SCENE_CELL = 2 * MOTION_BLOCK
"""Blocks whose content sits in one cell of this side (px, the first frame's coordinates) count as one piece of
evidence when the blocks are resampled: blocks overlap by half (a stride of MOTION_BLOCK / 2), the same part of the
scene is seen in every frame pair, and a texture's orientation holds over a few blocks."""

HALVES_DISAGREE = 0.5
"""The fit is repeated on alternate halves of the moving blocks; halves further apart than this mean no one s
explains the clip, and the prior is used. On the shared phone clips the halves of the readings kept agree within
0.2 (0.3 on one clip); clip474 read 0.0 on one half and 2.0 on the other."""


class BlockSpectra(NamedTuple):
    """The moving block pairs' spectra, aligned: all (N, MOTION_BLOCK, MOTION_BLOCK//2+1) but the last three.

    Attributes:
        scene: cross spectra with the noise that stays in place taken out (complex; the real part is the scene's
            power times the blur's transfer).
        persistent: the real part taken out with that noise.
        auto: the mean of the two blocks' power spectra.
        motion: (N, 2) (dy, dx) px/frame, the flow's with the phase fit's correction.
        correction: (N,) size of that correction, px.
        places: (N, 2) (y, x) each block's place in the first frame's coordinates (the scene's part it shows).
    """

    scene: np.ndarray
    persistent: np.ndarray
    auto: np.ndarray
    motion: np.ndarray
    correction: np.ndarray
    places: np.ndarray


@dataclass(frozen=True)
class ExposureFit:
    """The fit and the checks behind it.

    Attributes:
        reading: the fitted s (None: too few blocks to fit); kept when refused, for the record.
        refused: why the reading is not given (None: it is).
        blocks: blocks used; speed: their median speed (px/frame).
        confidence: share of resampled readings within TOLERANCE of the reading (None: not fitted).
        spread: 10th and 90th percentiles of the resampled readings.
        contrast: the scene's power against the noise's on the frequencies that tell shutters apart.
        ambiguous: blocks left out because their texture matches itself at another shift.
        persistent_share: share of the cross power, on those frequencies, that was noise staying in place.
        blockiness: the frames' :func:`~darksynth.estimation.light.shutter_confidence.compression_blockiness` (above
            :data:`~darksynth.estimation.light.shutter_confidence.BLOCKY`: JPEG's blocks show, and the reading needs a
            confidence of :data:`~darksynth.estimation.light.shutter_confidence.MIN_CONFIDENCE_COMPRESSED`).
    """

    reading: float | None
    refused: str | None
    blocks: int
    speed: float
    confidence: float | None = None
    spread: tuple[float, float] = (0.0, 0.0)
    contrast: float | None = None
    ambiguous: int = 0
    persistent_share: float | None = None
    blockiness: float = 1.0

    @property
    def min_confidence(self) -> float:
        """The confidence the reading needs: more where JPEG's quantization moves every block's reading alike."""
        return MIN_CONFIDENCE_COMPRESSED if self.blockiness > BLOCKY else MIN_CONFIDENCE


class _Rings(NamedTuple):
    """The blocks' powers on the frequencies the fit uses (N, F), and how they group into rings (F, rings)."""

    cross: np.ndarray
    noise: np.ndarray
    persistent: np.ndarray
    along: np.ndarray
    membership: np.ndarray
    weights: np.ndarray


def _rings(spectra: BlockSpectra) -> _Rings:
    """The frequencies of rings 2 to MOTION_BLOCK/2 - 1, axes left out. Rings 0 and 1 hold the mean and the window's
    leakage; beyond MOTION_BLOCK / 2 the ring is cut by the corners. The two axes hold the sensor's row and column
    patterns, which stay in place while the scene moves: their cross power oscillates with the shift and, for a
    shift of a pixel or two, reads as blur along it."""
    ky, kx = frequencies(MOTION_BLOCK)
    ring = np.rint(np.hypot(ky, kx) * MOTION_BLOCK).astype(int).ravel()
    on_axes = ((ky == 0) | (kx == 0)).ravel()
    in_rings = (ring >= 2) & (ring < MOTION_BLOCK // 2) & ~on_axes
    membership = ring_membership(ring[in_rings] - 2, MOTION_BLOCK // 2 - 2, np.float32)
    count = spectra.scene.shape[0]
    cross = spectra.scene.real.reshape(count, -1)[:, in_rings].astype(np.float32)
    noise = spectra.auto.reshape(count, -1)[:, in_rings].astype(np.float32) - cross
    persistent = spectra.persistent.reshape(count, -1)[:, in_rings].astype(np.float32)
    signal, floor = cross @ membership, noise @ membership
    snr = np.clip(signal, 0, None) / np.maximum(floor, 1e-12 * max(float(np.abs(signal).max()), 1e-30))
    # The projection of each frequency on the motion: cycles per frame's displacement.
    ky_flat, kx_flat = (k.ravel()[in_rings] for k in np.broadcast_arrays(ky, kx))
    motion = spectra.motion
    along = np.abs(motion[:, 0, None] * ky_flat[None] + motion[:, 1, None] * kx_flat[None]).astype(np.float32)
    return _Rings(cross, noise, persistent, along, membership, snr / (1.0 + snr))


def _block_scores(rings: _Rings, grid: np.ndarray) -> np.ndarray:
    """Per grid value and block (G, N): the rings' cosine similarity (squared) between the scene's powers and the
    transfer, weighted by their signal to noise and summed over the rings."""
    power_sq = (rings.cross**2) @ rings.membership
    out = np.empty((len(grid), rings.cross.shape[0]), np.float32)
    for index, s in enumerate(grid):
        transfer = box_transfer(np.float32(s) * rings.along)
        a = (rings.cross * transfer) @ rings.membership
        b = (transfer**2) @ rings.membership
        out[index] = (rings.weights * a * a / np.maximum(b * power_sq, 1e-30)).sum(axis=1)
    return out


def _refined(rings: _Rings, best: float) -> float:
    """The best s on the fine grid within a coarse step of ``best``, refined by a parabola through its neighbours."""
    step = float(COARSE_GRID[1] - COARSE_GRID[0])
    fine = S_GRID[(best - step - 1e-6 <= S_GRID) & (best + step + 1e-6 >= S_GRID)]
    fine_scores = _block_scores(rings, fine).sum(axis=1)
    index = int(np.argmax(fine_scores))
    estimate = float(fine[index])
    if 0 < index < len(fine) - 1:
        left, middle, right = fine_scores[index - 1 : index + 2]
        curvature = left - 2 * middle + right
        if curvature < 0:
            estimate += float(np.clip(0.5 * (left - right) / curvature, -1, 1) * (fine[index + 1] - fine[index]))
    return float(np.clip(estimate, 0.0, float(S_GRID[-1])))


def _usable(spectra: BlockSpectra, rings: _Rings) -> tuple[np.ndarray, np.ndarray]:
    """Blocks fit to read (N,) bool, and those left out as ambiguous (periodic texture) among the textured ones."""
    speeds = np.hypot(spectra.motion[:, 0], spectra.motion[:, 1])
    # A block whose mid rings hold no more scene than noise has no texture to read blur from.
    textured = rings.weights[:, : rings.membership.shape[1] // 2].mean(axis=1) >= 0.3
    # The cross spectrum's phase corrects the flow; where it corrects much, or finds the block slow after all, the
    # flow had followed noise (in the darkest frames it does) and the pair is not one scene moving.
    textured &= (speeds >= MIN_SPEED) & (spectra.correction <= 0.5 + 0.1 * speeds)
    ambiguous = textured & (motion_ambiguity(spectra.scene, spectra.motion) >= AMBIGUOUS_PEAK)
    return textured & ~ambiguous, ambiguous


def _select(rings: _Rings, keep: np.ndarray) -> _Rings:
    """Only the blocks ``keep`` (N,) bool marks; the ring grouping stays."""
    return rings._replace(
        cross=rings.cross[keep],
        noise=rings.noise[keep],
        persistent=rings.persistent[keep],
        along=rings.along[keep],
        weights=rings.weights[keep],
    )


def fit_exposure(spectra: BlockSpectra, blockiness: float = 1.0) -> ExposureFit:
    """The exposure fraction that best explains the blocks' cross spectra, and whether the blocks support it;
    ``blockiness``, the frames' :func:`~darksynth.estimation.light.shutter_confidence.compression_blockiness`, sets the
    confidence asked."""
    rings = _rings(spectra)
    usable, ambiguous = _usable(spectra, rings)
    speeds = np.hypot(spectra.motion[:, 0], spectra.motion[:, 1])
    if usable.sum() < MIN_BLOCKS:
        why = None
        if ambiguous.sum() >= MIN_BLOCKS:
            why = (
                f"{int(ambiguous.sum())} of the moving textured blocks match themselves at another shift "
                "(periodic texture: their motion and blur length can alias)"
            )
        return ExposureFit(
            None,
            why,
            int(usable.sum()),
            float(np.median(speeds)),
            ambiguous=int(ambiguous.sum()),
            blockiness=blockiness,
        )
    rings = _select(rings, usable)
    speed = float(np.median(speeds[usable]))
    scores = _block_scores(rings, COARSE_GRID)
    best = float(np.clip(COARSE_GRID[int(np.argmax(scores.sum(axis=1)))], S_GRID[0], S_GRID[-1]))
    reading = _refined(rings, best)
    # Resampled beyond 2 too: a reading held at 2 whose resamples lie further out is not supported.
    readings = resampled_readings(scores, COARSE_GRID, scene_cells(spectra.places[usable], SCENE_CELL))
    fit = ExposureFit(
        reading=reading,
        refused=None,
        blocks=int(usable.sum()),
        speed=speed,
        confidence=reading_confidence(readings, best),
        spread=(float(np.percentile(readings, 10)), float(np.percentile(readings, 90))),
        contrast=contrast_along(rings.cross, rings.noise, rings.along),
        ambiguous=int(ambiguous.sum()),
        persistent_share=persistent_share(rings.persistent, rings.cross, rings.along),
        blockiness=blockiness,
    )
    # The same fit on the two halves of the blocks (alternate ones): where they disagree, one s does not explain
    # the clip (texture that is not isotropic, processing the model lacks).
    halves = [
        float(np.clip(COARSE_GRID[int(np.argmax(scores[:, part::2].sum(axis=1)))], S_GRID[0], S_GRID[-1]))
        for part in (0, 1)
    ]
    if abs(halves[0] - halves[1]) > HALVES_DISAGREE:
        return replace(fit, refused=f"the two halves of the moving blocks read s = {halves[0]:.1f} and {halves[1]:.1f}")
    if fit.confidence is not None and fit.confidence < fit.min_confidence:
        return replace(fit, refused=_why_unsure(fit))
    return fit


def _why_unsure(fit: ExposureFit) -> str:
    """One line: the reading, how far resampling the scene's blocks scatters it, and the checks that explain it."""
    causes = []
    if fit.contrast is not None and fit.contrast < 1.0:
        causes.append(f"the texture along the motion holds {fit.contrast:.2f} times the noise's power")
    if fit.persistent_share is not None and fit.persistent_share >= 0.5:
        causes.append(f"noise that stays in place is {fit.persistent_share:.0%} of the cross power")
    if fit.ambiguous:
        causes.append(f"{fit.ambiguous} blocks of periodic texture left out")
    if fit.blockiness > BLOCKY:
        causes.append(
            f"the frames show JPEG's 8-px blocks (blockiness {fit.blockiness:.2f}): its quantization moves every "
            f"block's reading alike, so {MIN_CONFIDENCE_COMPRESSED} is asked"
        )
    because = f" ({'; '.join(causes)})" if causes else ""
    return (
        f"the blocks read s = {fit.reading:.2f} but, resampled over the scene, between {fit.spread[0]:.2f} and "
        f"{fit.spread[1]:.2f}: confidence {fit.confidence:.2f}, under {fit.min_confidence} of the readings within "
        f"{TOLERANCE}{because}"
    )
