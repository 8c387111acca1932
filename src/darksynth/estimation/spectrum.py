"""The spectral model measured on a real reference, blind: octave by octave, per intensity, and in time.

No clean image: the residual of a denoiser, ``y - D(y)``, stands for the noise. Two biases are removed by
indirect inference (the statistics of a simulation on ``D(y)``, denoised again, must equal the reference's):
what the denoiser leaves of the noise (nearly all of the coarse octaves: no denoiser tells a 60-px colour blotch
from the scene) and what it takes of the scene. The steps:

1. An analysis window of the reference (at most :data:`WINDOW` px a side) with the most flat blocks, the same
   in every analysed frame.
2. ``D``: OpenCV's non-local means, its strength from the fine-scale noise of the window's flattest blocks.
3. The flat blocks: the :data:`FLAT_SHARE` of 32x32 blocks of ``D(y)`` with the least gradient energy (texture
   is read as noise elsewhere), for a clip those that also stay still between the frames.
4. The statistics (:func:`darksynth.noise.spectral_fit.measure`): the residual band-passed as a whole, then its
   band cross-powers averaged over the flat blocks (a masked spectrum would leak mid frequencies into the coarse
   bands), the variance per channel and intensity knot, and for a clip the frame-to-frame correlation per band.
5. The fit by re-synthesis for each JPEG strength of :data:`~darksynth.noise.spectral_fit.COMPRESSION_CANDIDATES`;
   the best match is refined further.

A reference that cannot show something gets the prior for it, with a warning: a single image has no temporal
correlation to read (0, independent frames); a clip whose every block moves the same; a reference without flat
blocks is measured on its least textured ones, with a warning that texture may be read as noise.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import torch
import torch.nn.functional as F

from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES, OPPONENT_BASIS, level_std
from darksynth.noise.spectral_fit import (
    COMPRESSION_CANDIDATES,
    KnotBinning,
    SpectralParameters,
    SpectralStatistics,
    continue_octaves,
    fill_knots_along,
    fit_by_resynthesis,
    initial_parameters,
    knot_binning,
    measure,
    measure_weight,
    quantised,
    uncensored_signal,
)
from darksynth.noise.values import NoiseValues

WINDOW = 384
"""Side of the analysis window: enough frequencies in the coarsest band (1/128-1/64 cycles/px: about 80 per
frame), and a few seconds of denoising for all the simulations of the fit."""

BLOCK = 32
"""Side of the blocks whose flatness is judged."""

FLAT_SHARE = 0.3
"""Share of the blocks (the flattest) the statistics are read on."""

TEXTURED_GRADIENT = 4.0 / 255
"""A reference whose flat blocks still have a mean gradient magnitude of the denoised image above this (in the
[0, 1] scale per pixel) is textured all over: the estimate warns that texture may be read as noise."""

TEMPORAL_FRAMES = 4
"""Consecutive frames a clip is analysed on for the frame-to-frame correlation."""

STILL_CHANGE = 2.0 / 255
"""A block is still when the mean absolute change of the denoised frames, from the first, is below this or below
:data:`STILL_NOISE_FACTOR` times the change the noise alone leaves in a still simulation, whichever is larger."""

STILL_NOISE_FACTOR = 1.5
"""How far above the noise-only change (the median over blocks of a still simulation's) a still block may go.
Strong noise leaves a change of its own in the denoised frames (the starlight video, 4 levels of noise: every
block above 2 levels, so no block was still and its persistence was not read)."""

MIN_STILL_BLOCKS = 4
"""Fewer still flat blocks than this: the clip's temporal correlation is not measured (the prior, 0)."""

NLM_TEMPLATE, NLM_SEARCH = 5, 13
"""Non-local means patch and search window sides: OpenCV's defaults (7, 21) cost 2.5x the time for the same
statistics after the correction by re-synthesis."""

NLM_STRENGTH = 1.0
"""Non-local means strength ``h`` in 8-bit levels per 8-bit level of the flat blocks' noise std (the pilot reads
the noisiest intensity: :func:`flat_block_std`). With ``h`` under the noise, non-local means finds no patch like a
pixel's own and returns the noise: its residual shrinks as the noise grows (at 0.7x it keeps 75 % of white noise's
std, at 1x 95 %), and a fit by re-synthesis can settle on a level far too weak. 1.25 was tried: the round trip's
first 15 cases read the same (median |std ratio - 1| 0.097), but the stronger smoothing flattened a coarse
texture so that a panning clip looked still."""

START_ITERATIONS, FINAL_ITERATIONS = 2, 3
"""Corrections with each JPEG candidate (one draw), then with the best one (two draws)."""

PROBED_OCTAVES = range(2, OCTAVES)
"""Octaves whose visibility is probed (11 px and coarser); the two finest are always in the denoiser's residual."""

PROBE_BOOST = 4.0
"""Factor by which a probe raises one octave's power over white noise."""

ANCHOR_GAIN = 1.5
"""Exponent on the anchor's variance ratio per step: the unmeasured octaves hold only part of the detrended
variance, so the ratio alone moves their scale too little."""

ANCHOR_WARM_STEPS = 4
"""Updates of the anchor's scale alone before the last fit."""

ANCHOR_SCALE_RANGE = (0.1, 100.0)
"""Bounds of the factor on the unmeasured octaves' power: real cameras' coarse colour mottle reaches some 80x white
noise's power (docs/spectral-noise.md), against 1x where the prior continues a flat spectrum."""

KNOT_PROBE_BOOST = 1 / 1.5
"""Factor by which the probe of :func:`knot_responses` moves the level curve: down, since noise raised above the
denoiser's strength stops raising the residual (a flat grey reference read a response of 0.26 probed upward)."""

CLIPPED_LEVEL = 0.5 / 255
"""A pixel whose channel lies within this of 0 or of full scale is clipped: an 8-bit value of 0 or 255."""

CLIPPED_SHARE = 0.5
"""A block with more than this share of clipped pixels does not measure the level: its noise was mostly cut off
at 0 or at full scale (crushed blacks, a lamp) and its residual hardly moves with the noise's strength. Blocks
clipped less are measured, and the re-synthesis clips as the camera did (on the signal the clipped mean came
from: :func:`darksynth.noise.spectral_fit.uncensored_signal`)."""

STRENGTH_CLIPPED_SHARE = 0.01
"""The denoiser's strength is read on blocks clipped at most this much when there are :data:`MIN_LEVEL_BLOCKS`
of them (for Gaussian noise a block mean about 2.3 std from the limit, where clipping takes under 2 % of the
variance), else on the least clipped quarter of the blocks: crushed black reads as no noise, and a dark
reference's denoiser set from it was 10x too weak and left its noise in place."""

MIN_LEVEL_BLOCKS = 3
"""Fewer unclipped blocks than this in the analysis window: the level cannot be measured and the network's level
curve stands, with a warning (a black frame, a reference that is crushed black but for a few lamps)."""

LEVEL_DISAGREEMENT = 3.0
"""Measured and network level curves further apart than this factor (their geometric mean ratio over the measured
knots) get a warning naming both: one of the two misread the reference."""

MIN_RESPONSE = 0.35
"""An octave is measured when its band's statistic follows its power with at least this exponent (1: in
proportion; 0: not at all). Below it the band holds mostly other octaves' leakage and the scene, a fit would
read noise of its own sampling error (on a 384-px LOL reference the 90-px octave came out 1000x the others')."""


@dataclass
class SpectrumEstimate:
    """The spectral parameters by name (with ``compression``), and what the measurement says about itself."""

    values: dict[str, torch.Tensor]
    meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def _to_uint8(frame: torch.Tensor) -> np.ndarray:
    array: np.ndarray = (frame.clamp(0.0, 1.0) * 255.0).round().to(torch.uint8).permute(1, 2, 0).cpu().numpy()
    return np.ascontiguousarray(array)


NLM_OVERLAP = 16
"""Rows of overlap between the bands a frame's denoising is split into: a pixel's result reads the pixels within
the search radius plus the patch radius (6 + 2 rows), so with 8 or more the bands give the whole frame's bits."""

_nlm_pool: ThreadPoolExecutor | None = None


def _forget_nlm_pool() -> None:
    # A forked child inherits the pool without its threads (work sent to it would wait for ever): it makes its own.
    global _nlm_pool
    _nlm_pool = None


os.register_at_fork(after_in_child=_forget_nlm_pool)


def _nlm_workers() -> int:
    return max(1, torch.get_num_threads())


def _nlm(image: np.ndarray, strength: float) -> np.ndarray:
    # On the RGB values themselves: the colour variant compares patches in 8-bit Lab, whose steep dark end spreads
    # the noise of dark pixels, so that a strength that denoises mid-grey returns the noise of a pixel at 5 levels
    # (a residual of 0.5 levels where the noise was 4: the fit by re-synthesis then read dark references far too
    # weak). Here a strength equal to the noise's std removes about 95 % of it at every intensity.
    result: np.ndarray = cv2.fastNlMeansDenoising(image, None, strength, NLM_TEMPLATE, NLM_SEARCH)
    return result


def nlm_denoise(frames: torch.Tensor, strength: float) -> torch.Tensor:
    """Non-local means (OpenCV) of each frame of (T, 3, H, W) in [0, 1] on 8-bit levels, patches compared on the
    three RGB channels together, strength ``h`` in 8-bit levels; float32 on the input's device.

    OpenCV's non-local means runs on one core: each frame is cut into bands of rows (one per torch thread,
    overlapping by :data:`NLM_OVERLAP`) denoised side by side in threads (OpenCV releases the GIL), which gives the
    whole frame's result exactly (tested) in about half the time on two cores."""
    global _nlm_pool
    workers = _nlm_workers()
    if workers > 1 and _nlm_pool is None:
        _nlm_pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="darksynth-nlm")
    images = [_to_uint8(frame) for frame in frames]
    height = images[0].shape[0]
    band = -(-height // workers)
    if workers == 1 or band <= 2 * NLM_OVERLAP or _nlm_pool is None:
        results = [_nlm(image, float(strength)) for image in images]
    else:
        # Every band of every frame is queued at once, so neither thread waits for the other's last band of a frame.
        starts = range(0, height, band)
        jobs = [
            [
                _nlm_pool.submit(
                    _nlm,
                    np.ascontiguousarray(image[max(0, top - NLM_OVERLAP) : min(height, top + band + NLM_OVERLAP)]),
                    float(strength),
                )
                for top in starts
            ]
            for image in images
        ]
        results = [
            np.concatenate(
                [
                    job.result()[top - max(0, top - NLM_OVERLAP) :][: min(band, height - top)]
                    for top, job in zip(starts, frame_jobs, strict=True)
                ]
            )
            for frame_jobs in jobs
        ]
    out = [torch.from_numpy(result).permute(2, 0, 1).to(torch.float32) / 255.0 for result in results]
    return torch.stack(out).to(frames.device)


def block_gradient(image: torch.Tensor) -> torch.Tensor:
    """Mean gradient magnitude (over channels) of each BLOCK x BLOCK block of ``image`` (3, H, W):
    (H // BLOCK, W // BLOCK)."""
    grey = image.mean(0, keepdim=True)[None]
    dx = (grey[..., :, 1:] - grey[..., :, :-1]).abs()[..., :-1, :]
    dy = (grey[..., 1:, :] - grey[..., :-1, :]).abs()[..., :, :-1]
    magnitude = F.pad(dx + dy, (0, 1, 0, 1))
    return F.avg_pool2d(magnitude, BLOCK)[0, 0]


def clipped_share(frames: torch.Tensor) -> torch.Tensor:
    """Share (H // BLOCK, W // BLOCK) of the pixels of each block whose channel is clipped (within
    :data:`CLIPPED_LEVEL` of 0 or 1) in any of the frames (T, 3, H, W) or in the frame (3, H, W)."""
    frames = frames if frames.dim() == 4 else frames[None]
    clipped = ((frames <= CLIPPED_LEVEL) | (frames >= 1.0 - CLIPPED_LEVEL)).any(dim=1).any(dim=0)
    return F.avg_pool2d(clipped.to(torch.float32)[None, None], BLOCK)[0, 0]


def _blocks_to_mask(blocks: torch.Tensor, height: int, width: int) -> torch.Tensor:
    mask = blocks.to(torch.float32).repeat_interleave(BLOCK, 0).repeat_interleave(BLOCK, 1)
    return F.pad(mask, (0, width - mask.shape[1], 0, height - mask.shape[0]))


def analysis_window(frame: torch.Tensor, side: int = WINDOW) -> tuple[int, int, int, int]:
    """(top, left, height, width) of the window of ``frame`` (3, H, W) at most ``side`` px a side whose flattest
    unclipped blocks are flattest: candidates on a grid of half-window steps, judged on a lightly blurred copy.
    A window holding fewer unclipped blocks than the measurement reads loses to any that holds them (crushed
    black is the flattest thing in a night photo and measures no noise)."""
    height, width = frame.shape[-2:]
    window_height, window_width = min(side, height), min(side, width)
    smooth = F.avg_pool2d(frame[None], 3, stride=1, padding=1)[0]
    gradient = block_gradient(smooth)
    unclipped = clipped_share(frame)[: gradient.shape[0], : gradient.shape[1]] <= CLIPPED_SHARE
    rows_per, cols_per = max(window_height // BLOCK, 1), max(window_width // BLOCK, 1)
    best, best_score = (0, 0), (math.inf, math.inf)
    for top in range(0, max(gradient.shape[0] - rows_per, 0) + 1, max(rows_per // 2, 1)):
        for left in range(0, max(gradient.shape[1] - cols_per, 0) + 1, max(cols_per // 2, 1)):
            inside = gradient[top : top + rows_per, left : left + cols_per].flatten()
            usable = inside[unclipped[top : top + rows_per, left : left + cols_per].flatten()]
            if inside.numel() == 0:
                continue
            wanted = max(1, int(FLAT_SHARE * inside.numel()))
            flattest = (usable if usable.numel() else inside).sort().values[:wanted]
            score = (float(max(wanted - usable.numel(), 0)), float(flattest.mean()))
            if score < best_score:
                best, best_score = (top * BLOCK, left * BLOCK), score
    return best[0], best[1], window_height, window_width


def level_stratum(intensity: torch.Tensor) -> torch.Tensor:
    """The level curve's segment (0-6, int64) each intensity in [0, 1] falls in: the knots are (j / 7)^2."""
    return (intensity.clamp(0.0, 1.0) * 49.0).sqrt().floor().long().clamp(0, len(LEVEL_KNOTS) - 2)


def flat_blocks(denoised: torch.Tensor, usable: torch.Tensor) -> torch.Tensor:
    """The measured blocks (H // BLOCK, W // BLOCK) bool of a denoised frame (3, H, W): among the ``usable``
    blocks, the :data:`FLAT_SHARE` with the least gradient within each segment of the level curve, so that flat
    means flat for the noise at that intensity (noise left by the denoiser grows with the level: the flattest blocks
    in absolute terms are the darkest) and every intensity the reference shows reaches its knots."""
    gradient = block_gradient(denoised)
    usable = usable[: gradient.shape[0], : gradient.shape[1]]
    stratum = level_stratum(F.avg_pool2d(denoised.mean(0)[None, None], BLOCK)[0, 0])[: gradient.shape[0]]
    chosen = torch.zeros_like(usable)
    for segment in sorted(set(stratum[usable].tolist())):
        members = usable & (stratum == segment)
        count = max(1, round(FLAT_SHARE * int(members.sum())))
        threshold = gradient[members].sort().values[count - 1]
        chosen |= members & (gradient <= threshold)
    return chosen


def flat_mask(denoised: torch.Tensor, usable: torch.Tensor | None = None) -> tuple[torch.Tensor, float]:
    """The measured blocks of a denoised frame (3, H, W) (see :func:`flat_blocks`; all blocks usable by default)
    as a pixel mask (H, W), and the mean gradient of the :data:`FLAT_SHARE` flattest usable blocks (how flat the
    reference's flattest region is, for the warning that texture may be read as noise)."""
    gradient = block_gradient(denoised)
    if usable is None or not bool(usable.any()):
        usable = torch.ones_like(gradient, dtype=torch.bool)
    usable = usable[: gradient.shape[0], : gradient.shape[1]]
    chosen = flat_blocks(denoised, usable)
    candidates = gradient[usable].sort().values
    flattest = candidates[: max(1, round(FLAT_SHARE * candidates.numel()))]
    return _blocks_to_mask(chosen, *denoised.shape[-2:]), float(flattest.mean())


def _plane_projection(side: int) -> torch.Tensor:
    """(side^2, side^2) least-squares projection of a side x side block onto planes a + b x + c y."""
    y, x = torch.meshgrid(torch.linspace(-1, 1, side), torch.linspace(-1, 1, side), indexing="ij")
    basis = torch.stack([torch.ones(side * side), x.flatten(), y.flatten()], dim=1)
    projection: torch.Tensor = basis @ torch.linalg.pinv(basis)
    return projection


def flat_block_std(frames: torch.Tensor) -> float:
    """Std in 8-bit levels of the noise on the flattest little-clipped blocks of the first frame of (T, 3, H, W), at
    the intensity where it is strongest: per block and channel the std about the block's least-squares plane
    (shading across a flat wall is not noise: about its mean, a clean 8-bit ramp read as 3.7 levels of noise),
    averaged over the channels; per segment of the level curve the median over its flattest blocks; the largest
    over the segments that hold :data:`MIN_LEVEL_BLOCKS` blocks. It holds every scale of the noise below the block
    size and little texture: the strength the denoiser is set from. Non-local means with a strength well under the
    noise finds no patch like a pixel's own and returns the noise; its residual then shrinks as the noise grows, and
    a fit by re-synthesis settles on far too weak a noise (a dark reference read 10x weak when the strength came
    from its darkest blocks). Which blocks count as little clipped: :data:`STRENGTH_CLIPPED_SHARE`."""
    frame = frames[0]
    blocks = F.unfold(frame[:, None], BLOCK, stride=BLOCK)  # (3, BLOCK^2, blocks)
    detrended = blocks - torch.einsum("ij,cjn->cin", _plane_projection(BLOCK).to(blocks), blocks)
    std = (detrended.square().sum(dim=1) / (BLOCK * BLOCK - 3)).sqrt().mean(0)  # (blocks,)
    smooth = F.avg_pool2d(frame[None], 5, stride=1, padding=2)[0]
    gradient = block_gradient(smooth).flatten()[: std.numel()]
    stratum = level_stratum(F.avg_pool2d(frame.mean(0)[None, None], BLOCK)[0, 0]).flatten()[: std.numel()]
    share = clipped_share(frame).flatten()[: std.numel()]
    little = share <= STRENGTH_CLIPPED_SHARE
    if int(little.sum()) < MIN_LEVEL_BLOCKS:
        little = share <= share.sort().values[max(0, share.numel() // 4 - 1)]
    levels: list[tuple[bool, float]] = []
    for segment in sorted(set(stratum[little].tolist())):
        members = (little & (stratum == segment)).nonzero().flatten()
        if members.numel() >= MIN_LEVEL_BLOCKS or not levels:
            flattest = members[gradient[members].argsort()[: max(1, round(FLAT_SHARE * members.numel()))]]
            levels.append((members.numel() >= MIN_LEVEL_BLOCKS, float(std[flattest].median())))
    supported = [level for enough, level in levels if enough] or [level for _, level in levels]
    return max(supported) * 255.0


def block_change(denoised: torch.Tensor) -> torch.Tensor:
    """Mean absolute change (H // BLOCK, W // BLOCK) of each block of denoised frames (T, 3, H, W) from the first
    frame, over the frames and channels, after each frame's median change per channel: a change of the whole
    frame's brightness (auto-exposure, flicker: the starlight video dims by 7 levels in 4 frames) moves nothing."""
    difference = denoised - denoised[:1]
    global_change = difference.flatten(-2).median(dim=-1).values[..., None, None]
    change = (difference - global_change).abs().mean(dim=(0, 1))[None, None]
    return F.avg_pool2d(change, BLOCK)[0, 0]


def noise_only_change(
    denoised_first: torch.Tensor, values: NoiseValues, frames: int, strength: float, *, seed: int = 0
) -> float:
    """The median block change (see :func:`block_change`) of a still clip made of the first denoised frame
    (1, 3, H, W) and independent noise of ``values`` in each of ``frames`` frames, denoised like the reference."""
    # Its own stream of the estimate's seed (the fit's simulations use seed * 1009 + draw).
    generator = torch.Generator(device=denoised_first.device).manual_seed(7919 + seed * 1009)
    still = denoised_first.expand(frames, -1, -1, -1)
    synthetic = quantised(add_noise(still[None], values, generator=generator)[0])
    return float(block_change(nlm_denoise(synthetic, strength)).median())


def octave_responses(
    simulate_and_measure: Callable[[SpectralParameters, int], SpectralStatistics], start: SpectralParameters
) -> torch.Tensor:
    """How much each octave's band statistic follows that octave's power on this reference: white noise at the
    measured level, then each probed octave's power times :data:`PROBE_BOOST`, through the same simulation; the
    exponent ``log(band ratio) / log(boost)`` per octave (1 for the unprobed fine ones)."""
    identity = torch.eye(3, dtype=torch.float64).expand(OCTAVES, 3, 3)
    white = SpectralParameters(covariances=identity.clone(), curve=start.curve, temporal=start.temporal)
    base = simulate_and_measure(white, 0).cross_power.diagonal(dim1=-2, dim2=-1).sum(-1)
    responses = torch.ones(OCTAVES, dtype=torch.float64)
    for octave in PROBED_OCTAVES:
        covariances = identity.clone()
        covariances[octave] = covariances[octave] * PROBE_BOOST
        boosted = SpectralParameters(covariances=covariances, curve=start.curve, temporal=start.temporal)
        power = simulate_and_measure(boosted, 0).cross_power.diagonal(dim1=-2, dim2=-1).sum(-1)
        responses[octave] = torch.log(power[octave] / base[octave].clamp_min(1e-30)) / math.log(PROBE_BOOST)
    return responses


def _still_flat_mask(
    frames: torch.Tensor,
    denoised: torch.Tensor,
    mask: torch.Tensor,
    strength: float,
    seed: int,
    meta: dict[str, Any],
    warnings: list[str],
    name: str,
) -> torch.Tensor | None:
    """The measured blocks of a clip that stay still over its frames, as a pixel mask; None (with a warning) when
    fewer than :data:`MIN_STILL_BLOCKS` do."""
    height, width = frames.shape[-2:]
    first = initial_parameters(measure(frames[:1] - denoised[:1], denoised[:1], mask))
    first_values = NoiseValues.from_values(first.as_values(), dtype=torch.float32)
    threshold = max(
        STILL_CHANGE,
        STILL_NOISE_FACTOR * noise_only_change(denoised[:1], first_values, frames.shape[0], strength, seed=seed),
    )
    meta["still_threshold_8bit"] = round(threshold * 255, 3)
    still = block_change(denoised) < threshold
    flat = F.avg_pool2d(mask[None, None], BLOCK)[0, 0] > 0.5
    both = still[: flat.shape[0], : flat.shape[1]] & flat
    meta["still_flat_blocks"] = int(both.sum())
    if int(both.sum()) < MIN_STILL_BLOCKS:
        warnings.append(
            f"{name}: only {int(both.sum())} flat blocks stay still over {frames.shape[0]} frames (the camera "
            "or the scene moves): the frame-to-frame correlation of the noise is the prior 0 (independent frames)"
        )
        return None
    if frames.shape[0] == 2:
        warnings.append(
            f"{name}: 2 frames: the frame-to-frame correlation of the noise is read on one pair of frames "
            "(uncertain; give more frames)"
        )
    return _blocks_to_mask(both, height, width)


def _level_checks(
    curve: torch.Tensor,
    measured: torch.Tensor,
    prior_curve: torch.Tensor | None,
    level_measured: bool,
    meta: dict[str, Any],
    warnings: list[str],
    name: str,
) -> torch.Tensor:
    """The fitted level curve (3, 8) std, or the network's where the reference showed no unclipped block, with the
    comparison of the two in ``meta`` and a warning where they disagree by more than :data:`LEVEL_DISAGREEMENT`."""
    meta["measured_knots"] = [[bool(k) for k in channel] for channel in measured.tolist()]
    if prior_curve is None:
        return curve
    prior_curve = prior_curve.to(curve)
    meta["network_level_curve_8bit"] = [[round(float(v) * 255, 3) for v in c] for c in prior_curve]
    if not level_measured:
        warnings.append(
            f"{name}: no block free of clipped pixels (crushed black or saturated): the noise level could not be "
            "measured; the profile holds the network's level curve"
        )
        meta["level_source"] = "network: no unclipped block to measure on"
        return prior_curve.clone()
    meta["level_source"] = "measured on unclipped blocks; unmeasured knots follow the network's curve"
    if bool(measured.any()):
        ratio = float((curve[measured] / prior_curve[measured].clamp_min(1e-6)).log().mean().exp())
        if not 1.0 / LEVEL_DISAGREEMENT <= ratio <= LEVEL_DISAGREEMENT:
            levels = [float(curve[measured].mean()) * 255, float(prior_curve[measured].mean()) * 255]
            warnings.append(
                f"{name}: the measured noise level ({levels[0]:.2f} 8-bit levels) and the network's "
                f"({levels[1]:.2f}) differ by {max(ratio, 1 / ratio):.1f}x at the intensities the reference shows; "
                "the profile keeps the measurement"
            )
    return curve


def _block_grid(frame: torch.Tensor) -> torch.Tensor:
    """(3, BLOCK^2, rows * cols) the BLOCK x BLOCK blocks of ``frame`` (3, H, W), row by row."""
    return F.unfold(frame[:, None], BLOCK, stride=BLOCK)


def detrended_block_variance(frame: torch.Tensor, blocks: torch.Tensor) -> torch.Tensor:
    """Variance about each chosen block's least-squares plane of the brightness and the two colour components
    (:data:`~darksynth.noise.spectral.OPPONENT_BASIS`): (3, n) for the ``blocks`` (rows, cols) bool of ``frame``
    (3, H, W). Every scale of noise under the block size is in it."""
    components = torch.einsum("ij,jhw->ihw", OPPONENT_BASIS.to(frame), frame)
    grid = _block_grid(components)[..., blocks[: frame.shape[-2] // BLOCK, : frame.shape[-1] // BLOCK].flatten()]
    detrended = grid - torch.einsum("ij,cjn->cin", _plane_projection(BLOCK).to(grid), grid)
    return detrended.square().sum(dim=1) / (BLOCK * BLOCK - 3)


def block_planes(frame: torch.Tensor) -> torch.Tensor:
    """``frame`` (3, H, W) with each whole BLOCK x BLOCK block replaced by its least-squares plane (the rest
    kept): a flat block's scene without the noise at any scale under the block size."""
    height, width = frame.shape[-2:]
    rows, cols = height // BLOCK, width // BLOCK
    grid = _block_grid(frame)
    planes = torch.einsum("ij,cjn->cin", _plane_projection(BLOCK).to(grid), grid)
    folded = F.fold(planes, (rows * BLOCK, cols * BLOCK), BLOCK, stride=BLOCK)[:, 0]
    result = frame.clone()
    result[:, : rows * BLOCK, : cols * BLOCK] = folded
    return result


ANCHOR_QUANTILE = 0.25
"""The quantile over blocks of the detrended variance the anchor matches (the same in the reference and the
simulations, so any quantile is unbiased for noise): texture left in a flat block only raises its variance, and a
low quantile reads the blocks it left alone."""


def anchor_statistic(variances: torch.Tensor) -> torch.Tensor:
    """The :data:`ANCHOR_QUANTILE` over blocks of detrended variances (3, n): (3,) float64."""
    return variances.to(torch.float64).quantile(ANCHOR_QUANTILE, dim=1)


@dataclass
class CoarseAnchor:
    """The noise under the block size that the denoiser's residual cannot show, read about planes.

    Non-local means leaves noise coarser than its search window in the image it returns, so octaves from about
    11 px up barely move its residual and take a prior (the finer octaves' spectrum continued). On a flat block the
    scene is close to a plane, and the variance about the plane holds every octave under 32 px: the median over the
    measured blocks of the reference's, against that of the model's noise added to the blocks' planes (no denoiser:
    no scene, no coarse noise of the reference in the base), scales the unmeasured octaves (``scale``). Texture left
    in a flat block reads as coarse noise here, which is why the median over blocks flat for their level is used.
    Brightness and colour are anchored apart: cameras low-pass their colour noise far more than their brightness.

    Attributes:
        target: the reference's median detrended block variance, brightness and the two colours (3,).
        planes: the denoised frame's blocks as planes (3, H, W), the base of the simulations.
        blocks: (rows, cols) bool, the measured blocks.
        scale: the factor (3,) on the unmeasured octaves' power of each component, moved by :meth:`update`.
    """

    target: torch.Tensor
    planes: torch.Tensor
    blocks: torch.Tensor
    scale: torch.Tensor = field(default_factory=lambda: torch.ones(3, dtype=torch.float64))
    last: torch.Tensor | None = None

    def simulated(self, values: NoiseValues, curve: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        signal = uncensored_signal(self.planes, level_std(self.planes, curve.reshape(-1).to(self.planes)))
        synthetic = quantised(add_noise(signal[None, None], values, generator=generator)[0, 0])
        return anchor_statistic(detrended_block_variance(synthetic, self.blocks))

    def update(self) -> None:
        """Move ``scale`` by the ratio of the target to the last simulation (bounded per step and overall)."""
        if self.last is not None and bool((self.last > 0.0).all()):
            step = (self.target / self.last).pow(ANCHOR_GAIN).clamp(0.25, 4.0)
            # Brightness keeps the prior: texture left in flat blocks is brightness, and even the lower quartile of
            # the blocks read it as coarse brightness noise (up to 70x white on textured images of the round trip,
            # where colour stayed within 0.8-1.25; docs/spectral-noise.md).
            step[0] = 1.0
            self.scale = (self.scale * step).clamp(*ANCHOR_SCALE_RANGE)
        self.last = None

    def apply(self, covariances: torch.Tensor, first_unmeasured: int) -> torch.Tensor:
        """The octaves' covariances with the unmeasured ones' components scaled (their correlations kept)."""
        covariances = covariances.clone()
        root = self.scale.sqrt().to(covariances)
        covariances[first_unmeasured:] *= root[:, None] * root[None, :]
        return covariances


def knot_responses(
    simulate_and_measure: Callable[[SpectralParameters, int], SpectralStatistics], start: SpectralParameters
) -> torch.Tensor:
    """How much each level knot's variance statistic follows that knot's noise on this reference: the start's
    curve, then the curve times :data:`KNOT_PROBE_BOOST`, through the same simulation; the exponent of the
    variance ratio over the factor's square per channel and knot (C, 8): 1 in proportion, nan where unmeasured. A
    knot whose pixels are mostly clipped, or where the denoiser returned the noise, reads the same whatever the
    noise: its statistic cannot set it."""
    base = simulate_and_measure(start, 0).knot_variance
    boosted = SpectralParameters(
        covariances=start.covariances, curve=start.curve * KNOT_PROBE_BOOST, temporal=start.temporal
    )
    raised = simulate_and_measure(boosted, 0).knot_variance
    return (raised / base.clamp_min(1e-30)).log() / (2.0 * math.log(KNOT_PROBE_BOOST))


def estimate_spectrum(
    reference: torch.Tensor, *, seed: int = 0, name: str = "reference", prior_curve: torch.Tensor | None = None
) -> SpectrumEstimate:
    """The spectral model's parameters measured on reference frames (T, 3, H, W) in [0, 1] (see the module).

    Args:
        prior_curve: (3, 8) noise std per channel at the level knots from another source (the network): the knots
            the reference cannot show (no unclipped flat block at that intensity) follow its shape through the
            measured ones, and it stands alone when no block is unclipped.

    Returns:
        The parameters (``level_curve``, ``octave_power``, ``octave_correlation``, ``temporal_correlation``,
        ``compression``) and a record of the measurement for the profile's ``meta``, with warnings.
    """
    warnings: list[str] = []
    reference = reference.to(torch.float32)
    clip = reference.shape[0] >= 2
    frames = reference[:TEMPORAL_FRAMES] if clip else reference[:1]
    top, left, height, width = analysis_window(frames[0])
    frames = frames[..., top : top + height, left : left + width]
    strength = min(max(NLM_STRENGTH * flat_block_std(frames), 1.0), 40.0)
    denoised = nlm_denoise(frames, strength)
    unclipped = clipped_share(frames) <= CLIPPED_SHARE
    mask, flat_gradient = flat_mask(denoised[0], unclipped)
    meta: dict[str, Any] = {
        "method": "blind spectral measurement (docs/spectral-noise.md): non-local-means residual on the flat "
        "unclipped blocks of each intensity, band-passed per octave, corrected by re-synthesis on the denoised "
        "reference",
        "window": [top, left, height, width],
        "frames": int(frames.shape[0]),
        "denoiser_strength_8bit": round(strength, 3),
        "flat_block_gradient_8bit": round(flat_gradient * 255, 3),
        "unclipped_blocks": f"{int(unclipped.sum())} of {unclipped.numel()}",
    }
    if flat_gradient > TEXTURED_GRADIENT:
        warnings.append(
            f"{name}: no flat region (its flattest blocks still have a gradient of {flat_gradient * 255:.1f} 8-bit "
            "levels per pixel): fine texture may be read as noise, the level may be too high"
        )
    temporal_mask = None
    if clip:
        temporal_mask = _still_flat_mask(frames, denoised, mask, strength, seed, meta, warnings, name)
    else:
        meta["temporal_prior"] = "single image: frame-to-frame correlation of the noise not measurable; prior 0"
    # Moving pixels carry the scene's change, not the noise's persistence: a clip is read on its still blocks.
    measured_mask = temporal_mask if temporal_mask is not None else mask
    analysed = frames if temporal_mask is not None else frames[:1]
    analysed_denoised = denoised if temporal_mask is not None else denoised[:1]
    target = measure(analysed - analysed_denoised, analysed_denoised, measured_mask)
    measured_knots = ~torch.isnan(target.knot_variance).expand(3, -1)
    fitted = _fit(analysed, analysed_denoised, measured_mask, target, strength, seed, meta, measured_knots, prior_curve)
    fitted.curve = _level_checks(
        fitted.curve, measured_knots, prior_curve, int(unclipped.sum()) >= MIN_LEVEL_BLOCKS, meta, warnings, name
    )
    if target.temporal is None:
        fitted.temporal = torch.zeros(OCTAVES, dtype=torch.float64)
    values = fitted.as_values() | {"compression": torch.tensor([meta["compression_chosen"]], dtype=torch.float64)}
    return SpectrumEstimate(values=values, meta=meta, warnings=warnings)


def _fit(
    analysed: torch.Tensor,
    analysed_denoised: torch.Tensor,
    measured_mask: torch.Tensor,
    target: SpectralStatistics,
    strength: float,
    seed: int,
    meta: dict[str, Any],
    measured_knots: torch.Tensor,
    prior_curve: torch.Tensor | None,
) -> SpectralParameters:
    """The fit by re-synthesis on the denoised frames: the octaves the reference shows probed, each JPEG strength
    fitted on the first frame, the best fitted further on all analysed frames; the choice and what was left over
    in ``meta``."""
    height, width = analysed.shape[-2:]
    binnings: dict[int, KnotBinning] = {}

    def constrain_curve(parameters: SpectralParameters) -> SpectralParameters:
        if prior_curve is not None:
            parameters.curve = fill_knots_along(parameters.curve, measured_knots, prior_curve)
        return parameters

    def simulator(compression: float, frame_count: int = analysed.shape[0]) -> Any:
        denoised = analysed_denoised[:frame_count]
        if frame_count not in binnings:
            # Every simulation is measured on the same denoised frames and mask: their knots are found once.
            weight = measure_weight(frame_count, height, width, measured_mask, denoised.device)
            binnings[frame_count] = knot_binning(denoised, weight)
        binning = binnings[frame_count]

        def simulate_and_measure(parameters: SpectralParameters, draw: int) -> SpectralStatistics:
            values = NoiseValues.from_values(parameters.as_values() | {"compression": compression}, dtype=torch.float32)
            generator = torch.Generator(device=analysed.device).manual_seed(seed * 1009 + draw)
            # The camera clipped its noise about the signal, not about the denoised (clipped) mean.
            signal = uncensored_signal(denoised, level_std(denoised, parameters.curve.reshape(-1).to(denoised)))
            synthetic = quantised(add_noise(signal[None], values, generator=generator)[0])
            again = nlm_denoise(synthetic, strength)
            return measure(synthetic - again, denoised, measured_mask, binning=binning)

        return simulate_and_measure

    start = constrain_curve(initial_parameters(target))
    # The probes and the search over JPEG strengths are spatial: a clip's first frame is enough for them (a 16-frame
    # 1080p clip took 20 s with every analysed frame in every simulation); the last fit reads all of them.
    spatial_target = (
        target
        if analysed.shape[0] == 1
        else measure(analysed[:1] - analysed_denoised[:1], analysed_denoised[:1], measured_mask)
    )
    responses = octave_responses(simulator(0.0, 1), start)
    first_unmeasured = next((k for k in PROBED_OCTAVES if responses[k] < MIN_RESPONSE), OCTAVES)
    meta["octave_response"] = [round(float(r), 3) for r in responses]
    if first_unmeasured < OCTAVES:
        meta["octave_prior"] = (
            f"octaves {first_unmeasured + 1}-{OCTAVES} (wavelengths from {2 ** (first_unmeasured + 1.5):.0f} px) "
            "barely move this reference's statistics: they continue the finer octaves' spectrum"
        )

    blocks = (
        F.avg_pool2d(measured_mask[-1][None, None] if measured_mask.dim() == 3 else measured_mask[None, None], BLOCK)[
            0, 0
        ]
        > 0.5
    )
    anchor = CoarseAnchor(
        target=anchor_statistic(detrended_block_variance(analysed[0], blocks))
        if bool(blocks.any())
        else torch.zeros(3, dtype=torch.float64),
        planes=block_planes(analysed_denoised[0]),
        blocks=blocks,
    )

    def constrain(parameters: SpectralParameters) -> SpectralParameters:
        parameters = continue_octaves(parameters, first_unmeasured)
        anchor.update()
        if first_unmeasured < OCTAVES:
            parameters.covariances = anchor.apply(parameters.covariances, first_unmeasured)
        return constrain_curve(parameters)

    scores: dict[float, float] = {}
    fits: dict[float, SpectralParameters] = {}
    for compression in COMPRESSION_CANDIDATES:
        fits[compression], scores[compression] = fit_by_resynthesis(
            spatial_target,
            simulator(compression, 1),
            start=start,
            iterations=START_ITERATIONS,
            draws=1,
            constrain=constrain,
        )
    chosen = min(scores, key=lambda c: scores[c])
    # A knot's response is probed where the fit has brought the level: at the raw residual's level (too weak on
    # textured references) texture dominates every knot's statistic and none would seem to respond.
    responses_per_knot = knot_responses(simulator(chosen, 1), fits[chosen])
    unresponsive = ~(responses_per_knot >= MIN_RESPONSE)
    meta["knot_response"] = [[round(float(r), 2) for r in row] for row in responses_per_knot.nan_to_num(0.0)]
    # In place: the caller's record of which knots were measured, for its checks of the level.
    measured_knots &= ~unresponsive
    target = dataclasses.replace(target, knot_variance=target.knot_variance.masked_fill(unresponsive, math.nan))
    # Two draws of one frame, or one draw of a clip's frames (which hold as many pixels again).
    draws = 2 if analysed.shape[0] == 1 else 1
    simulate = simulator(chosen)

    def simulate_with_anchor(parameters: SpectralParameters, draw: int) -> SpectralStatistics:
        if draw == 0 and first_unmeasured < OCTAVES and bool((anchor.target > 0.0).all()):
            values = NoiseValues.from_values(parameters.as_values() | {"compression": chosen}, dtype=torch.float32)
            generator = torch.Generator(device=analysed.device).manual_seed(seed * 1009 + 7)
            anchor.last = anchor.simulated(values, parameters.curve, generator)
        statistics: SpectralStatistics = simulate(parameters, draw)
        return statistics

    start = fits[chosen]
    if first_unmeasured < OCTAVES and bool((anchor.target > 0.0).all()):
        # The anchor alone first (no denoiser in its simulation: cheap), so that the fit starts near its scale; a
        # colour mottle 50x white needs more steps than the fit makes.
        for _ in range(ANCHOR_WARM_STEPS):
            values = NoiseValues.from_values(start.as_values() | {"compression": chosen}, dtype=torch.float32)
            generator = torch.Generator(device=analysed.device).manual_seed(seed * 1009 + 7)
            anchor.last = anchor.simulated(values, start.curve, generator)
            start = constrain(start)
    fitted, left_over = fit_by_resynthesis(
        target, simulate_with_anchor, start=start, iterations=FINAL_ITERATIONS, draws=draws, constrain=constrain
    )
    meta["coarse_octave_scale"] = [round(float(v), 3) for v in anchor.scale]
    meta["compression_scores"] = {str(c): round(v, 4) for c, v in scores.items()}
    meta["compression_chosen"] = chosen
    meta["mismatch"] = round(left_over, 4)
    return fitted
