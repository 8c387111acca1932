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
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.spectral_fit import (
    COMPRESSION_CANDIDATES,
    KnotBinning,
    SpectralParameters,
    SpectralStatistics,
    continue_octaves,
    fit_by_resynthesis,
    initial_parameters,
    knot_binning,
    measure,
    measure_weight,
    quantised,
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
"""Non-local means strength ``h`` in 8-bit levels per 8-bit level of the flat blocks' noise std."""

START_ITERATIONS, FINAL_ITERATIONS = 2, 3
"""Corrections with each JPEG candidate (one draw), then with the best one (two draws)."""

PROBED_OCTAVES = range(2, OCTAVES)
"""Octaves whose visibility is probed (11 px and coarser); the two finest are always in the denoiser's residual."""

PROBE_BOOST = 4.0
"""Factor by which a probe raises one octave's power over white noise."""

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
    result: np.ndarray = cv2.fastNlMeansDenoisingColored(image, None, strength, strength, NLM_TEMPLATE, NLM_SEARCH)
    return result


def nlm_denoise(frames: torch.Tensor, strength: float) -> torch.Tensor:
    """Non-local means (OpenCV) of each frame of (T, 3, H, W) in [0, 1] on 8-bit levels, strength ``h`` in 8-bit
    levels for brightness and colour alike; float32 on the input's device.

    OpenCV's colour non-local means runs on one core: each frame is cut into bands of rows (one per torch thread,
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


def _blocks_to_mask(blocks: torch.Tensor, height: int, width: int) -> torch.Tensor:
    mask = blocks.to(torch.float32).repeat_interleave(BLOCK, 0).repeat_interleave(BLOCK, 1)
    return F.pad(mask, (0, width - mask.shape[1], 0, height - mask.shape[0]))


def analysis_window(frame: torch.Tensor, side: int = WINDOW) -> tuple[int, int, int, int]:
    """(top, left, height, width) of the window of ``frame`` (3, H, W) at most ``side`` px a side whose flattest
    blocks are flattest: candidates on a grid of half-window steps, judged on a lightly blurred copy."""
    height, width = frame.shape[-2:]
    window_height, window_width = min(side, height), min(side, width)
    smooth = F.avg_pool2d(frame[None], 3, stride=1, padding=1)[0]
    gradient = block_gradient(smooth)
    rows_per, cols_per = max(window_height // BLOCK, 1), max(window_width // BLOCK, 1)
    best, best_score = (0, 0), math.inf
    for top in range(0, max(gradient.shape[0] - rows_per, 0) + 1, max(rows_per // 2, 1)):
        for left in range(0, max(gradient.shape[1] - cols_per, 0) + 1, max(cols_per // 2, 1)):
            inside = gradient[top : top + rows_per, left : left + cols_per].flatten()
            if inside.numel() == 0:
                continue
            score = float(inside.sort().values[: max(1, int(FLAT_SHARE * inside.numel()))].mean())
            if score < best_score:
                best, best_score = (top * BLOCK, left * BLOCK), score
    return best[0], best[1], window_height, window_width


def flat_mask(denoised: torch.Tensor) -> tuple[torch.Tensor, float]:
    """The flat blocks of a denoised frame (3, H, W) as a pixel mask (H, W), and their mean gradient."""
    gradient = block_gradient(denoised)
    count = max(1, round(FLAT_SHARE * gradient.numel()))
    threshold = gradient.flatten().sort().values[count - 1]
    flat = gradient <= threshold
    return _blocks_to_mask(flat, *denoised.shape[-2:]), float(gradient[flat].mean())


def _plane_projection(side: int) -> torch.Tensor:
    """(side^2, side^2) least-squares projection of a side x side block onto planes a + b x + c y."""
    y, x = torch.meshgrid(torch.linspace(-1, 1, side), torch.linspace(-1, 1, side), indexing="ij")
    basis = torch.stack([torch.ones(side * side), x.flatten(), y.flatten()], dim=1)
    projection: torch.Tensor = basis @ torch.linalg.pinv(basis)
    return projection


def flat_block_std(frames: torch.Tensor) -> float:
    """Std in 8-bit levels of the noise on the flattest blocks of the first frame of (T, 3, H, W): per block and
    channel the std about the block's least-squares plane (shading across a flat wall is not noise: about its
    mean, a clean 8-bit ramp read as 3.7 levels of noise), the median over the blocks, averaged over the channels.
    It holds every scale of the noise below the block size (the finest detail alone misses correlated noise) and
    little texture: the strength the denoiser is set from."""
    frame = frames[0]
    blocks = F.unfold(frame[:, None], BLOCK, stride=BLOCK)  # (3, BLOCK^2, blocks)
    detrended = blocks - torch.einsum("ij,cjn->cin", _plane_projection(BLOCK).to(blocks), blocks)
    std = (detrended.square().sum(dim=1) / (BLOCK * BLOCK - 3)).sqrt()  # (3, blocks)
    smooth = F.avg_pool2d(frame[None], 5, stride=1, padding=2)[0]
    gradient = block_gradient(smooth).flatten()[: std.shape[1]]
    count = max(1, round(FLAT_SHARE * gradient.numel()))
    flattest = gradient.argsort()[:count]
    return float(std[:, flattest].median(dim=1).values.mean()) * 255.0


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


def estimate_spectrum(reference: torch.Tensor, *, seed: int = 0, name: str = "reference") -> SpectrumEstimate:
    """The spectral model's parameters measured on reference frames (T, 3, H, W) in [0, 1] (see the module).

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
    mask, flat_gradient = flat_mask(denoised[0])
    meta: dict[str, Any] = {
        "method": "blind spectral measurement (docs/spectral-noise.md): non-local-means residual on the flat "
        "blocks, band-passed per octave, corrected by re-synthesis on the denoised reference",
        "window": [top, left, height, width],
        "frames": int(frames.shape[0]),
        "denoiser_strength_8bit": round(strength, 3),
        "flat_block_gradient_8bit": round(flat_gradient * 255, 3),
    }
    if flat_gradient > TEXTURED_GRADIENT:
        warnings.append(
            f"{name}: no flat region (its flattest blocks still have a gradient of {flat_gradient * 255:.1f} 8-bit "
            "levels per pixel): fine texture may be read as noise, the level may be too high"
        )
    temporal_mask: torch.Tensor | None = None
    if clip:
        first = initial_parameters(measure(frames[:1] - denoised[:1], denoised[:1], mask))
        first_values = NoiseValues.from_values(first.as_values(), dtype=torch.float32)
        threshold = max(
            STILL_CHANGE,
            STILL_NOISE_FACTOR * noise_only_change(denoised[:1], first_values, frames.shape[0], strength, seed=seed),
        )
        meta["still_threshold_8bit"] = round(threshold * 255, 3)
        still = block_change(denoised) < threshold
        flat_blocks = F.avg_pool2d(mask[None, None], BLOCK)[0, 0] > 0.5
        both = still[: flat_blocks.shape[0], : flat_blocks.shape[1]] & flat_blocks
        meta["still_flat_blocks"] = int(both.sum())
        if int(both.sum()) >= MIN_STILL_BLOCKS:
            temporal_mask = _blocks_to_mask(both, height, width)
            if frames.shape[0] == 2:
                warnings.append(
                    f"{name}: 2 frames: the frame-to-frame correlation of the noise is read on one pair of frames "
                    "(uncertain; give more frames)"
                )
        else:
            warnings.append(
                f"{name}: only {int(both.sum())} flat blocks stay still over {frames.shape[0]} frames (the camera "
                "or the scene moves): the frame-to-frame correlation of the noise is the prior 0 (independent frames)"
            )
    if not clip:
        meta["temporal_prior"] = "single image: frame-to-frame correlation of the noise not measurable; prior 0"
    # Moving pixels carry the scene's change, not the noise's persistence: a clip is read on its still blocks.
    measured_mask = temporal_mask if temporal_mask is not None else mask
    analysed = frames if temporal_mask is not None else frames[:1]
    analysed_denoised = denoised if temporal_mask is not None else denoised[:1]
    target = measure(analysed - analysed_denoised, analysed_denoised, measured_mask)

    binnings: dict[int, KnotBinning] = {}

    def simulator(compression: float, frame_count: int = analysed.shape[0]) -> Any:
        base = analysed_denoised[:frame_count]
        if frame_count not in binnings:
            # Every simulation is measured on the same denoised frames and mask: their knots are found once.
            weight = measure_weight(frame_count, height, width, measured_mask, base.device)
            binnings[frame_count] = knot_binning(base, weight)
        binning = binnings[frame_count]

        def simulate_and_measure(parameters: SpectralParameters, draw: int) -> SpectralStatistics:
            values = NoiseValues.from_values(parameters.as_values() | {"compression": compression}, dtype=torch.float32)
            generator = torch.Generator(device=analysed.device).manual_seed(seed * 1009 + draw)
            synthetic = quantised(add_noise(base[None], values, generator=generator)[0])
            again = nlm_denoise(synthetic, strength)
            return measure(synthetic - again, base, measured_mask, binning=binning)

        return simulate_and_measure

    start = initial_parameters(target)
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

    def constrain(parameters: SpectralParameters) -> SpectralParameters:
        return continue_octaves(parameters, first_unmeasured)

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
    # Two draws of one frame, or one draw of a clip's frames (which hold as many pixels again).
    draws = 2 if analysed.shape[0] == 1 else 1
    fitted, left_over = fit_by_resynthesis(
        target, simulator(chosen), start=fits[chosen], iterations=FINAL_ITERATIONS, draws=draws, constrain=constrain
    )
    if target.temporal is None:
        fitted.temporal = torch.zeros(OCTAVES, dtype=torch.float64)
    meta["compression_scores"] = {str(c): round(s, 4) for c, s in scores.items()}
    meta["mismatch"] = round(left_over, 4)
    values = fitted.as_values() | {"compression": torch.tensor([chosen], dtype=torch.float64)}
    return SpectrumEstimate(values=values, meta=meta, warnings=warnings)
