"""A reference clip's shutter (the exposure fraction behind its motion blur) and its exposure flicker.

The model measured is the one darksynth synthesizes: frame t integrates the clean scene, in linear light, over a
window of ``s`` frame intervals centred on t, so a pixel moving by ``d`` px/frame is smeared by a box of length
``L = s * |d|`` along ``d``; then a per-frame gain ``g_t = 1 + std * z_t`` (z a unit-variance AR(1) sequence with
lag-1 correlation rho) multiplies the darkened signal before the noise.

Exposure fraction, the steps:

1. Luminance, brightened to a common level (divided by a high percentile of each frame), reduced to at most
   :data:`FLOW_WIDTH` px wide and lightly blurred, as 8-bit frames for OpenCV's DIS optical flow between
   consecutive frames; pairs across a scene cut or with a uniform frame are skipped, and a forward-backward check
   rejects flow that does not invert.
2. Moving blocks (:data:`MOTION_BLOCK` px at full resolution) whose flow is consistent and at least :data:`MIN_SPEED`
   px/frame. Each block of frame t is paired with the block of frame t+1 the flow takes it to; the sub-pixel
   remainder, and what the flow missed, are read from the phase of the pair's cross spectrum (a block whose
   correction is large, or which turns out slower than :data:`MIN_SPEED`, is dropped: its flow followed noise).
3. The blur is read from the block pair's cross-power spectrum ``Re(F_t conj(F_t+1))`` after the sub-pixel
   remainder of the shift is undone in phase. The noise of the two frames is independent, so it averages out of
   the cross spectrum (the auto spectrum would need the noise floor subtracted, and the reference's noise is
   neither white nor known here); the scene is the same content seen twice, blurred by the same box, so its
   power ``S(|k|) sinc^2(pi s k.d)`` remains. With locally isotropic texture, ``S`` depends on ``|k|`` alone:
   in every ring of frequencies (the two axes left out: a sensor's column and row patterns stay in place while the
   scene moves) the measured powers must be proportional to the box's transfer
   ``sinc^2(pi s k.d)``. The fit maximises, over a grid of ``s``, the pooled (over rings, blocks and frame pairs)
   cosine similarity between the powers of each ring and the transfer, rings weighted by their signal to noise.
   Noise in a ring adds the same amount to every ``s`` (it is uncorrelated with the transfer), so it blurs the
   optimum but does not move it. A pooled score rather than a median of per-block fits: one block's 64x64
   periodogram is too noisy to fit alone, and pooling weights each block by how much its rings say.
4. Not identifiable -> :data:`EXPOSURE_FRACTION_PRIOR` with a note: one frame, no usable pair, fewer than
   :data:`~darksynth.estimation.light.shutter_fit.MIN_BLOCKS` moving textured blocks (blocks whose texture matches
   itself at another shift, a periodic pattern whose motion can alias, are left out), or a reading the blocks do not
   support: its confidence, the share of readings within 0.15 of it when the scene's blocks are resampled (a
   cluster bootstrap, :mod:`darksynth.estimation.light.shutter_confidence`), under one half, or under 0.98 when the
   frames show JPEG's 8-px blocks (its quantization moves every block's reading alike, which resampling cannot see). The
   note names the reading, the resampled spread, and what explains it (texture contrast against the noise on the
   frequencies that tell shutters apart, the share of noise that stays in place, periodic blocks, JPEG's blocks).

What it assumes: texture that is, over the pooled blocks, isotropic (a scene of mostly parallel edges along the
motion reads as a shorter shutter, across it as a longer one; a periodic pattern can read as 0); and that the
camera added nothing that blurs along the motion (a phone's temporal denoising smears moving content and reads as
a longer shutter, up to 2 here, held at 1 in the profile). Noise that persists from frame to frame (temporal noise
reduction, codecs) is modelled (:func:`~darksynth.estimation.light.cross_spectra.align_along`,
:func:`~darksynth.estimation.light.cross_spectra.without_persistent_noise`); a fit whose alternate
halves of blocks disagree by more than :data:`~darksynth.estimation.light.shutter_fit.HALVES_DISAGREE` is refused.

Flicker: on the pixels that stay still (flow below :data:`STILL_SPEED`, away from moving ones) through a stretch of
frames between scene cuts (a cut, a uniform frame or a pair whose flow does not invert ends a stretch). The still
pixels are split into two halves (alternate bands of columns) and, in each, grouped by level; per frame, the
groups' change from their mean level is fitted as ``gain * level + offset``. The fitted gain is g_t / mean(g) - 1;
the offset takes what adds the same amount to every pixel of a frame (a wandering black level, or darksynth's own
frame-wide periodic term, which alone read as 2 % "flicker" on a dark scene when a plain mean level was used).
The two halves share the gain and not the noise, so the covariance between their gain series is the gain's
variance with no noise model to subtract (the same for the lag-1 covariance). Both are corrected for the bias of
a short de-meaned AR(1) series. A slow trend, such as a camera's auto-exposure settling, is read as flicker of high
correlation: darksynth cannot tell them apart, and to a viewer both are the brightness of the clip changing.
Fewer than :data:`MIN_FLICKER_FRAMES` comparable frames in every stretch, or too few still pixels (a handheld clip
moves everywhere) -> the priors 0 and 0, with a note. A gain too weak to stand out of its own scatter is reported
(near 0) with correlation 0.

References:
    Kroeger et al. 2016, Fast optical flow using dense inverse search (OpenCV's DIS).
    Yitzhaky & Kopeika 1997, Identification of blur parameters from motion blurred images (the box's spectral
    zeros along the motion).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import cv2
import numpy as np
import torch

from darksynth.estimation.light.cross_spectra import align_along, align_phase, phase_ramp, without_persistent_noise
from darksynth.estimation.light.flicker_reading import (
    FLICKER_CORRELATION_PRIOR,
    FLICKER_PRIOR,
    PairFlow,
    measure_flicker,
)
from darksynth.estimation.light.shutter_confidence import compression_blockiness
from darksynth.estimation.light.shutter_fit import (
    MIN_BLOCKS,
    MIN_SPEED,
    MOTION_BLOCK,
    S_GRID,
    BlockSpectra,
    ExposureFit,
    fit_exposure,
)
from darksynth.estimation.reference import scene_cuts, uniform_frames
from darksynth.light.motion_blur import dense_flow, pixel_grid

EXPOSURE_FRACTION_PRIOR = 0.5
"""When the blur cannot be measured: the 180-degree shutter, the convention of video cameras (exposure half the
frame interval), which most phones and cameras follow in video unless the light forces a longer one."""

FLOW_WIDTH = 640
"""The flow runs on frames at most this wide: DIS at 640 px takes a few ms a pair, and blur is measured at full
resolution anyway; the flow only has to say where a block went."""

FLOW_BLUR_SIGMA = 1.0
"""Gaussian blur (px, at the flow's resolution) against the noise of a dark frame before the flow."""

BRIGHT_PERCENTILE = 99.5
"""Each frame is scaled so that this percentile of its luminance is white: dark frames use the 8-bit range."""

MIN_CONSISTENT_SHARE = 0.4
"""A pair whose flow passes the forward-backward check on less of the frame than this is taken as a scene cut:
between frames of one scene even fast motion leaves most of the frame consistent (occlusions are edges)."""

MAX_BLOCKS = 256
"""At most this many blocks enter the fit (spread over the frame pairs): the score's cost grows with them."""

SHUTTER_LIMIT = 1.0
"""The longest blur a shutter gives: open for the whole frame interval."""

BLOCKINESS_FRAMES, BLOCKINESS_SIZE = 8, 512
"""JPEG's blocks are looked for on at most this many frames and this many px from the top left corner, where the
8-px grid is anchored: enough rows and columns to average the grid out of the content, at a small cost."""


@dataclass(frozen=True)
class MotionEstimate:
    """What a reference clip shows of its shutter and its flicker, and how sure that is.

    Attributes:
        exposure_fraction: s, the share of the frame interval the shutter is open (the prior when not measured);
            above 1 (up to 2) when the blur along the motion is longer than any shutter gives, which the profile
            holds at 1.
        exposure_measured: whether ``exposure_fraction`` was measured (False: it is the prior).
        moving_share: share of the frame area whose flow is at least :data:`MIN_SPEED` px/frame (mean over pairs).
        displacement: median speed (px/frame, full resolution) of the blocks the fit used (when too few, of the
            moving blocks found; 0 without any).
        blocks: blocks the fit used.
        pairs: consecutive frame pairs compared (flow computed and consistent).
        skipped_pairs: consecutive pairs not compared: a scene cut, a uniform frame, flow that does not invert.
        flicker: std of the relative per-frame gain (the prior when not measured).
        flicker_correlation: lag-1 correlation of the gain, in [0, 0.99].
        flicker_measured: whether the two flicker values were measured.
        flicker_frames: frames in the still stretches the flicker was read on.
        notes: one line for each thing not measured, with the prior used.
        exposure_fit: the fit behind the exposure fraction and its checks (None: no block to fit): its reading
            (kept when the prior is used), its confidence and what the blocks show of contrast, periodic texture
            and noise that stays in place.
    """

    exposure_fraction: float
    exposure_measured: bool
    moving_share: float
    displacement: float
    blocks: int
    pairs: int
    skipped_pairs: int
    flicker: float
    flicker_correlation: float
    flicker_measured: bool
    flicker_frames: int
    notes: tuple[str, ...] = field(default=())
    exposure_fit: ExposureFit | None = None

    @property
    def exposure_confidence(self) -> float:
        """In [0, 1]: the share of readings, with the scene's blocks resampled, within
        :data:`~darksynth.estimation.light.shutter_confidence.TOLERANCE` of the reading; 0 when nothing was read."""
        fit = self.exposure_fit
        return 0.0 if fit is None or fit.confidence is None else round(fit.confidence, 3)

    def to_meta(self) -> dict[str, Any]:
        """JSON-ready record for a profile's ``meta``: the values, what was measured, the priors and why."""
        return {
            "exposure_fraction": round(self.exposure_fraction, 4),
            "exposure_measured": self.exposure_measured,
            "exposure_prior": None if self.exposure_measured else EXPOSURE_FRACTION_PRIOR,
            "exposure_confidence": self.exposure_confidence,
            "exposure_checks": _fit_checks(self.exposure_fit),
            "moving_share": round(self.moving_share, 4),
            "displacement": round(self.displacement, 3),
            "blocks": self.blocks,
            "pairs": self.pairs,
            "skipped_pairs": self.skipped_pairs,
            "flicker": round(self.flicker, 5),
            "flicker_correlation": round(self.flicker_correlation, 4),
            "flicker_measured": self.flicker_measured,
            "flicker_prior": None if self.flicker_measured else [FLICKER_PRIOR, FLICKER_CORRELATION_PRIOR],
            "flicker_frames": self.flicker_frames,
            "notes": list(self.notes),
        }


def estimate_motion(
    reference: torch.Tensor, *, uniform: list[int] | None = None, cuts: list[int] | None = None
) -> MotionEstimate:
    """Measure the exposure fraction and the flicker of a reference.

    Args:
        reference: frames (T, 3, H, W), sRGB values in [0, 1], as :func:`darksynth.estimation.reference.load_reference`
            reads them; any T >= 1.
        uniform, cuts: the reference's :func:`~darksynth.estimation.reference.uniform_frames` and
            :func:`~darksynth.estimation.reference.scene_cuts`, when the caller has them (else found here).

    Returns:
        The estimate; what cannot be measured is the prior, with a note.
    """
    if reference.dim() != 4 or reference.shape[1] not in (1, 3):
        raise ValueError(f"expected a reference shaped (T, 3, H, W), got shape {tuple(reference.shape)}")
    frames = reference.shape[0]
    skipped = set(uniform_frames(reference) if uniform is None else uniform) if frames > 1 else set()
    cut_before = set(scene_cuts(reference) if cuts is None else cuts)
    pairs = [t for t in range(frames - 1) if t not in skipped and t + 1 not in skipped and t + 1 not in cut_before]
    scale, small = _reduced_luminance(reference)
    flow_frames = _flow_frames(small, skipped) if pairs else []
    computed = [_pair_flow(flow_frames[t], flow_frames[t + 1], scale, t) for t in pairs]
    # A cut between two frames of the same dark tones moves the block means too little for scene_cuts; the flow
    # between unrelated frames does not invert.
    flows = [f for f in computed if f.valid.mean() >= MIN_CONSISTENT_SHARE]

    moving = [(f.valid & (np.hypot(f.flow[..., 0], f.flow[..., 1]) >= MIN_SPEED)).mean() for f in flows]
    moving_share = float(np.mean(moving)) if flows else 0.0
    exposure = _read_exposure(reference, flows, moving_share)
    notes = list(exposure.notes)
    flicker, correlation, flicker_frames, why_not = measure_flicker(small, flows, frames)
    flicker_measured = why_not is None
    if why_not is not None:
        notes.append(f"{why_not}: flicker is the prior {FLICKER_PRIOR} (correlation {FLICKER_CORRELATION_PRIOR})")
        flicker, correlation = FLICKER_PRIOR, FLICKER_CORRELATION_PRIOR
    return MotionEstimate(
        exposure_fraction=float(exposure.value),
        exposure_measured=exposure.measured,
        moving_share=moving_share,
        displacement=exposure.displacement,
        blocks=exposure.blocks,
        pairs=len(flows),
        skipped_pairs=frames - 1 - len(flows) if frames > 1 else 0,
        flicker=float(flicker),
        flicker_correlation=float(correlation),
        flicker_measured=flicker_measured,
        flicker_frames=flicker_frames,
        notes=tuple(notes),
        exposure_fit=exposure.fit,
    )


class _Exposure(NamedTuple):
    """The exposure fraction given (the prior when not measured), and what the estimate records of it."""

    value: float
    measured: bool
    blocks: int
    displacement: float
    fit: ExposureFit | None
    notes: list[str]


def _read_exposure(reference: torch.Tensor, flows: list[PairFlow], moving_share: float) -> _Exposure:
    """The exposure fraction from the flows' moving blocks, or the prior with a note that says why."""
    frames = reference.shape[0]
    prior = f"exposure fraction is the prior {EXPOSURE_FRACTION_PRIOR}"
    if frames < 2:
        return _Exposure(EXPOSURE_FRACTION_PRIOR, False, 0, 0.0, None, [f"a single frame shows no motion: {prior}"])
    if not flows:
        why = (
            "no pair of consecutive frames to compare (uniform frames, scene cuts, or flow that does not invert: "
            "too dark or unrelated frames)"
        )
        return _Exposure(EXPOSURE_FRACTION_PRIOR, False, 0, 0.0, None, [f"{why}: {prior}"])
    spectra = _block_spectra(reference, flows)
    corner = reference[:BLOCKINESS_FRAMES, :, :BLOCKINESS_SIZE, :BLOCKINESS_SIZE]
    fit = fit_exposure(spectra, compression_blockiness(_luminance(corner))) if spectra is not None else None
    blocks, displacement = (fit.blocks, fit.speed) if fit is not None else (0, 0.0)
    if fit is None or fit.reading is None or fit.refused is not None:
        why = (fit.refused if fit is not None else None) or (
            f"no motion of {MIN_SPEED} px/frame or more between frames"
            if moving_share < 0.01
            else f"only {blocks} moving textured blocks (at least {MIN_BLOCKS} needed)"
        )
        return _Exposure(EXPOSURE_FRACTION_PRIOR, False, blocks, displacement, fit, [f"{why}: {prior}"])
    notes = []
    if fit.reading > SHUTTER_LIMIT:
        notes.append(
            f"the blur along the motion is {'at least ' if fit.reading >= S_GRID[-1] else ''}{fit.reading:.2f} "
            "times the displacement a frame, longer than a shutter open for the whole frame interval gives: the "
            "camera blends frames over time (temporal noise reduction or frame averaging); the exposure fraction "
            "is held at 1"
        )
    return _Exposure(fit.reading, True, blocks, displacement, fit, notes)


def _luminance(frames: torch.Tensor) -> np.ndarray:
    """Rec. 709 luma of sRGB frames (..., 3 or 1, H, W) -> (..., H, W) float32, NaN-free."""
    if frames.shape[-3] == 1:
        luma = frames[..., 0, :, :].float()
    else:
        channels = frames.float()
        luma = (channels[..., 0, :, :] * 0.2126).add_(channels[..., 1, :, :], alpha=0.7152)
        luma = luma.add_(channels[..., 2, :, :], alpha=0.0722)
    return torch.nan_to_num(luma.float(), nan=0.0, posinf=1.0, neginf=0.0).cpu().numpy()


def _reduced_luminance(reference: torch.Tensor) -> tuple[float, np.ndarray]:
    """Luminance (T, h, w) at most :data:`FLOW_WIDTH` wide (pooled), and the factor from its px to full-resolution px.

    Reduced before the luminance is taken: the full-resolution luminance of 16 1080p frames alone took 0.2-0.5 s,
    and the blocks read their own from the reference.
    """
    factor = math.ceil(reference.shape[-1] / FLOW_WIDTH)
    if factor == 1 or min(reference.shape[-2:]) < 2 * factor:
        return 1.0, _luminance(reference)
    # An integer factor: pooling is several times faster than an area resize to an arbitrary size.
    return float(factor), _luminance(torch.nn.functional.avg_pool2d(reference.float(), factor))


def _flow_frames(luminance: np.ndarray, skipped: set[int]) -> list[np.ndarray]:
    """8-bit frames for the flow: each brightened to a common level, lightly blurred against the noise."""
    out = []
    for t, frame in enumerate(luminance):
        top = float(np.percentile(frame[::2, ::2], BRIGHT_PERCENTILE)) if t not in skipped else 0.0
        bright = frame * (255.0 / top) if top > 1e-6 else np.zeros_like(frame)
        bright = cv2.GaussianBlur(bright, (0, 0), FLOW_BLUR_SIGMA)
        out.append(np.clip(bright, 0, 255).astype(np.uint8))
    return out


def _pair_flow(first: np.ndarray, second: np.ndarray, scale: float, t: int) -> PairFlow:
    """DIS flow from ``first`` to ``second`` (full-resolution px/frame) and where it survives the backward check."""
    forward, backward = dense_flow(first, second), dense_flow(second, first)
    height, width = first.shape
    grid_x, grid_y = pixel_grid(height, width)
    # Where each pixel lands in the second frame.
    x, y = grid_x + forward[..., 0], grid_y + forward[..., 1]
    back_at = cv2.remap(backward, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    error = np.hypot(*(forward + back_at).transpose(2, 0, 1))
    speed = np.hypot(forward[..., 0], forward[..., 1])
    inside = (x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1)
    # Half a pixel, or a tenth of the motion: DIS is less exact on fast motion, and the block pairing only needs
    # the shift to a fraction of a pixel at full resolution.
    valid = inside & (error <= 0.5 + 0.1 * speed) & np.isfinite(speed)
    return PairFlow(first=t, flow=np.nan_to_num(forward) * np.float32(scale), valid=valid, scale=scale)


def _moving_blocks(flow: PairFlow, shape: tuple[int, int]) -> list[tuple[int, int, float, float]]:
    """Blocks (top, left, dy, dx) of frame t, full resolution, that move consistently by (dx, dy) px/frame.

    The flow statistics of every block come from box filters over the flow map (the mean flow of its valid
    pixels and their spread), read at the block's centre: one pass per pair instead of one per block.
    """
    height, width = shape
    small_h, small_w = flow.valid.shape
    side = max(1, round(MOTION_BLOCK / flow.scale))
    valid = flow.valid.astype(np.float32)
    fx, fy = flow.flow[..., 0] * valid, flow.flow[..., 1] * valid
    square = (flow.flow[..., 0] ** 2 + flow.flow[..., 1] ** 2) * valid
    box = [cv2.blur(a, (side, side), borderType=cv2.BORDER_REPLICATE) for a in (valid, fx, fy, square)]
    stride = MOTION_BLOCK // 2
    tops = np.arange(0, height - MOTION_BLOCK + 1, stride)
    lefts = np.arange(0, width - MOTION_BLOCK + 1, stride)
    rows = np.clip(((tops + MOTION_BLOCK / 2) / flow.scale).astype(int), 0, small_h - 1)
    columns = np.clip(((lefts + MOTION_BLOCK / 2) / flow.scale).astype(int), 0, small_w - 1)
    share, sum_x, sum_y, sum_sq = (a[np.ix_(rows, columns)] for a in box)
    count = np.maximum(share, 1e-6)
    dx, dy = sum_x / count, sum_y / count
    speed = np.hypot(dx, dy)
    spread = np.sqrt(np.maximum(sum_sq / count - speed**2, 0.0))
    top_grid, left_grid = np.meshgrid(tops, lefts, indexing="ij")
    target_top, target_left = top_grid + np.round(dy), left_grid + np.round(dx)
    good = (
        (share >= 0.7)
        & (speed >= MIN_SPEED)
        # A block that moves as one: its flow varies by a fraction of a pixel (more for fast motion, which DIS
        # measures less exactly).
        & (spread <= 0.35 + 0.1 * speed)
        & (target_top >= 0)
        & (target_top <= height - MOTION_BLOCK)
        & (target_left >= 0)
        & (target_left <= width - MOTION_BLOCK)
    )
    return [
        (int(top_grid[i, j]), int(left_grid[i, j]), float(dy[i, j]), float(dx[i, j]))
        for i, j in zip(*np.nonzero(good), strict=True)
    ]


def _block_spectra(reference: torch.Tensor, flows: list[PairFlow]) -> BlockSpectra | None:
    """The moving block pairs' cross and auto spectra, aligned, with their motions and places (None: no block)."""
    height, width = reference.shape[-2:]
    chosen: list[tuple[int, int, int, float, float]] = []
    per_pair = [_moving_blocks(f, (height, width)) for f in flows]
    total = sum(len(b) for b in per_pair)
    if total == 0:
        return None
    keep_share = min(1.0, MAX_BLOCKS / total)
    for flow, blocks in zip(flows, per_pair, strict=True):
        if keep_share < 1.0 and blocks:
            index = np.unique(np.linspace(0, len(blocks) - 1, max(1, round(len(blocks) * keep_share))).round())
            blocks = [blocks[int(i)] for i in index]
        chosen.extend((flow.first, top, left, dy, dx) for top, left, dy, dx in blocks)
    pieces = []
    for t, top, left, dy, dx in chosen:
        ry, rx = top + round(dy), left + round(dx)
        pieces.append(reference[t, :, top : top + MOTION_BLOCK, left : left + MOTION_BLOCK])
        pieces.append(reference[t + 1, :, ry : ry + MOTION_BLOCK, rx : rx + MOTION_BLOCK])
    luminance = _luminance(torch.stack(pieces))
    first, second = luminance[0::2], luminance[1::2]
    motion = np.array([(dy, dx) for *_, dy, dx in chosen], np.float64)
    window = np.outer(np.hanning(MOTION_BLOCK), np.hanning(MOTION_BLOCK)).astype(np.float32)
    first = (first - first.mean(axis=(1, 2), keepdims=True)) * window
    second = (second - second.mean(axis=(1, 2), keepdims=True)) * window
    spectrum_first = np.fft.rfft2(first)
    spectrum_second = np.fft.rfft2(second)
    # The second block starts at the rounded shift; the sub-pixel remainder is a phase ramp, undone here.
    remainder = motion - np.round(motion)
    product = spectrum_first * np.conj(spectrum_second)
    product *= phase_ramp(remainder, MOTION_BLOCK)
    # Noise that stays in place pulls the flow and the phase towards no shift. The shift the flow missed along the
    # motion is found first with that noise in the model (align_along), then the rest of it (both directions, a
    # fraction of a pixel) on the spectra without that noise.
    error = align_along(product, motion)
    product = product * phase_ramp(error, MOTION_BLOCK)
    _, missed = align_phase(without_persistent_noise(product, motion + error))
    product = product * phase_ramp(missed, MOTION_BLOCK)
    error += missed
    auto = 0.5 * (np.abs(spectrum_first) ** 2 + np.abs(spectrum_second) ** 2)
    shift = motion + error
    scene = without_persistent_noise(product, shift)
    # Where each block's content sits in the first frame: blocks of different pairs showing one part of the scene.
    start = np.array([(top - t * dy, left - t * dx) for t, top, left, dy, dx in chosen], np.float64).reshape(-1, 2)
    correction = np.hypot(error[:, 0], error[:, 1])
    return BlockSpectra(scene, product.real - scene.real, auto, shift, correction, start)


def _fit_checks(fit: ExposureFit | None) -> dict[str, Any] | None:
    """The fit's reading (also when the prior is used) and its checks, JSON-ready (None: no block was fitted)."""
    if fit is None:
        return None

    def rounded(value: float | None) -> float | None:
        return None if value is None else round(value, 4)

    return {
        "reading": rounded(fit.reading),
        "resampled_10_90": [round(fit.spread[0], 3), round(fit.spread[1], 3)],
        "contrast_along_motion": rounded(fit.contrast),
        "periodic_blocks": fit.ambiguous,
        "persistent_share": rounded(fit.persistent_share),
        "jpeg_blockiness": rounded(fit.blockiness),
    }
