"""The 32-px blocks a reference's noise is measured on: their flatness, their clipping, the analysis window, and
their variance about a plane.

Pure functions on (3, H, W) frames in [0, 1]; the blind spectral measurement
(:mod:`darksynth.estimation.noise.spectrum`) and the coarse anchor (:mod:`darksynth.estimation.noise.coarse_anchor`)
choose and read blocks through them.
"""

from __future__ import annotations

import math
from typing import Any

import torch
import torch.nn.functional as F

from darksynth.noise.spectral import LEVEL_KNOTS, OPPONENT_BASIS

FLAT_BLOCK = 32
"""Side of the blocks whose flatness is judged."""

FLAT_SHARE = 0.3
"""Share of the blocks (the flattest) the statistics are read on."""

CLIPPED_LEVEL = 0.5 / 255
"""A pixel whose channel lies within this of 0 or of full scale is clipped: an 8-bit value of 0 or 255."""

CLIPPED_SHARE = 0.5
"""A block with more than this share of clipped pixels does not measure the level: its noise was mostly cut off
at 0 or at full scale (crushed blacks, a lamp) and its residual hardly moves with the noise's strength. Blocks
clipped less are measured, and the re-synthesis clips as the camera did (on the signal the clipped mean came
from: :func:`darksynth.estimation.noise.spectral_fit.uncensored_signal`)."""

STRENGTH_CLIPPED_SHARE = 0.01
"""The denoiser's strength is read on blocks clipped at most this much when there are :data:`MIN_LEVEL_BLOCKS`
of them (for Gaussian noise a block mean about 2.3 std from the limit, where clipping takes under 2 % of the
variance), else on the least clipped quarter of the blocks: crushed black reads as no noise, and a dark
reference's denoiser set from it was 10x too weak and left its noise in place."""

MIN_LEVEL_BLOCKS = 3
"""Fewer unclipped blocks than this in the analysis window: the level cannot be measured and the network's level
curve stands, with a warning (a black frame, a reference that is crushed black but for a few lamps)."""


def block_gradient(image: torch.Tensor) -> torch.Tensor:
    """Mean gradient magnitude (over channels) of each FLAT_BLOCK x FLAT_BLOCK block of ``image`` (3, H, W):
    (H // FLAT_BLOCK, W // FLAT_BLOCK)."""
    grey = image.mean(0, keepdim=True)[None]
    dx = (grey[..., :, 1:] - grey[..., :, :-1]).abs()[..., :-1, :]
    dy = (grey[..., 1:, :] - grey[..., :-1, :]).abs()[..., :, :-1]
    magnitude = F.pad(dx + dy, (0, 1, 0, 1))
    return F.avg_pool2d(magnitude, FLAT_BLOCK)[0, 0]


def clipped_share(frames: torch.Tensor) -> torch.Tensor:
    """Share (H // FLAT_BLOCK, W // FLAT_BLOCK) of the pixels of each block whose channel is clipped (within
    :data:`CLIPPED_LEVEL` of 0 or 1) in any of the frames (T, 3, H, W) or in the frame (3, H, W)."""
    frames = frames if frames.dim() == 4 else frames[None]
    clipped = ((frames <= CLIPPED_LEVEL) | (frames >= 1.0 - CLIPPED_LEVEL)).any(dim=1).any(dim=0)
    return F.avg_pool2d(clipped.to(torch.float32)[None, None], FLAT_BLOCK)[0, 0]


def blocks_to_mask(blocks: torch.Tensor, height: int, width: int) -> torch.Tensor:
    mask = blocks.to(torch.float32).repeat_interleave(FLAT_BLOCK, 0).repeat_interleave(FLAT_BLOCK, 1)
    return F.pad(mask, (0, width - mask.shape[1], 0, height - mask.shape[0]))


def level_stratum(intensity: torch.Tensor) -> torch.Tensor:
    """The level curve's segment (0-6, int64) each intensity in [0, 1] falls in: the knots are (j / 7)^2."""
    return (intensity.clamp(0.0, 1.0) * 49.0).sqrt().floor().long().clamp(0, len(LEVEL_KNOTS) - 2)


def flat_blocks(denoised: torch.Tensor, usable: torch.Tensor) -> torch.Tensor:
    """The measured blocks (H // FLAT_BLOCK, W // FLAT_BLOCK) bool of a denoised frame (3, H, W): among the ``usable``
    blocks, the :data:`FLAT_SHARE` with the least gradient within each segment of the level curve, so that flat
    means flat for the noise at that intensity (noise left by the denoiser grows with the level: the flattest blocks
    in absolute terms are the darkest) and every intensity the reference shows reaches its knots."""
    gradient = block_gradient(denoised)
    usable = usable[: gradient.shape[0], : gradient.shape[1]]
    stratum = level_stratum(F.avg_pool2d(denoised.mean(0)[None, None], FLAT_BLOCK)[0, 0])[: gradient.shape[0]]
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
    return blocks_to_mask(chosen, *denoised.shape[-2:]), float(flattest.mean())


def _plane_projection(side: int) -> torch.Tensor:
    """(side^2, side^2) least-squares projection of a side x side block onto planes a + b x + c y."""
    y, x = torch.meshgrid(torch.linspace(-1, 1, side), torch.linspace(-1, 1, side), indexing="ij")
    basis = torch.stack([torch.ones(side * side), x.flatten(), y.flatten()], dim=1)
    projection: torch.Tensor = basis @ torch.linalg.pinv(basis)
    return projection


def block_grid(frame: torch.Tensor) -> torch.Tensor:
    """(3, FLAT_BLOCK^2, rows * cols) the FLAT_BLOCK x FLAT_BLOCK blocks of ``frame`` (3, H, W), row by row."""
    return F.unfold(frame[:, None], FLAT_BLOCK, stride=FLAT_BLOCK)


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
    blocks = F.unfold(frame[:, None], FLAT_BLOCK, stride=FLAT_BLOCK)  # (3, FLAT_BLOCK^2, blocks)
    detrended = blocks - torch.einsum("ij,cjn->cin", _plane_projection(FLAT_BLOCK).to(blocks), blocks)
    std = (detrended.square().sum(dim=1) / (FLAT_BLOCK * FLAT_BLOCK - 3)).sqrt().mean(0)  # (blocks,)
    smooth = F.avg_pool2d(frame[None], 5, stride=1, padding=2)[0]
    gradient = block_gradient(smooth).flatten()[: std.numel()]
    stratum = level_stratum(F.avg_pool2d(frame.mean(0)[None, None], FLAT_BLOCK)[0, 0]).flatten()[: std.numel()]
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


NLM_STRENGTH = 1.0
"""Non-local means strength ``h`` in 8-bit levels per 8-bit level of the flat blocks' noise std (the pilot reads
the noisiest intensity: :func:`flat_block_std`). With ``h`` under the noise, non-local means finds no patch like a
pixel's own and returns the noise: its residual shrinks as the noise grows (at 0.7x it keeps 75 % of white noise's
std, at 1x 95 %), and a fit by re-synthesis can settle on a level far too weak. 1.25 was tried: the round trip's
first 15 cases read the same (median |std ratio - 1| 0.097), but the stronger smoothing flattened a coarse
texture so that a panning clip looked still."""

DENOISER_STRENGTH_RANGE = (1.0, 40.0)
"""Bounds of the non-local means strength in 8-bit levels: a rule's strength outside them is clamped to them."""


def denoiser_strength(frames: torch.Tensor) -> float:
    """The non-local means strength, in 8-bit levels, the blind measurement denoises frames (T, 3, H, W) with:
    :data:`NLM_STRENGTH` times their :func:`flat_block_std`, within :data:`DENOISER_STRENGTH_RANGE`."""
    low, high = DENOISER_STRENGTH_RANGE
    return min(max(NLM_STRENGTH * flat_block_std(frames), low), high)


def stated_denoiser_strength(meta: dict[str, Any], frames: torch.Tensor) -> float:
    """The strength (8-bit levels) an estimate denoised ``frames`` (T, 3, H, W) with, as its profile's ``meta``
    states it, else :func:`denoiser_strength` on the first frame (profiles written before the strength was stated):
    what a check that denoises the reference again must use."""
    stated = meta.get("spectrum", {}).get("denoiser_strength_8bit")
    return float(stated) if stated is not None else denoiser_strength(frames[:1])


def detrended_blocks(frame: torch.Tensor, blocks: torch.Tensor) -> torch.Tensor:
    """The brightness and the two colour components (:data:`~darksynth.noise.spectral.OPPONENT_BASIS`) of the chosen
    blocks of ``frame`` (3, H, W) about each block's least-squares plane: (3, FLAT_BLOCK, FLAT_BLOCK, n) for the
    ``blocks`` (rows, cols) bool. Every scale of noise under the block size is in them."""
    components = torch.einsum("ij,jhw->ihw", OPPONENT_BASIS.to(frame), frame)
    grid = block_grid(components)[
        ..., blocks[: frame.shape[-2] // FLAT_BLOCK, : frame.shape[-1] // FLAT_BLOCK].flatten()
    ]
    detrended = grid - torch.einsum("ij,cjn->cin", _plane_projection(FLAT_BLOCK).to(grid), grid)
    return detrended.reshape(3, FLAT_BLOCK, FLAT_BLOCK, -1)


def block_planes(frame: torch.Tensor) -> torch.Tensor:
    """``frame`` (3, H, W) with each whole FLAT_BLOCK x FLAT_BLOCK block replaced by its least-squares plane (the rest
    kept): a flat block's scene without the noise at any scale under the block size."""
    height, width = frame.shape[-2:]
    rows, cols = height // FLAT_BLOCK, width // FLAT_BLOCK
    grid = block_grid(frame)
    planes = torch.einsum("ij,cjn->cin", _plane_projection(FLAT_BLOCK).to(grid), grid)
    folded = F.fold(planes, (rows * FLAT_BLOCK, cols * FLAT_BLOCK), FLAT_BLOCK, stride=FLAT_BLOCK)[:, 0]
    result = frame.clone()
    result[:, : rows * FLAT_BLOCK, : cols * FLAT_BLOCK] = folded
    return result


WINDOW = 384
"""Side of the analysis window: enough frequencies in the coarsest band (1/128-1/64 cycles/px: about 80 per
frame), and a few seconds of denoising for all the simulations of the fit."""


def analysis_window(frame: torch.Tensor, side: int = WINDOW) -> tuple[int, int, int, int]:
    """(top, left, height, width) of the window of ``frame`` (3, H, W) at most ``side`` px a side whose flattest
    unclipped blocks are flattest: candidates on a grid of half-window steps, judged on a lightly blurred copy.
    A window holding fewer unclipped blocks than the measurement reads loses to any that holds them (crushed
    black is the flattest thing in a night photo and measures no noise)."""
    height, width = frame.shape[-2:]
    window_height, window_width = min(side, height), min(side, width)
    # The gradient is judged on the channels' mean: blurred after averaging, a third of the work on a 12 MP photo.
    smooth = F.avg_pool2d(frame.mean(0, keepdim=True)[None], 3, stride=1, padding=1)[0]
    gradient = block_gradient(smooth)
    unclipped = clipped_share(frame)[: gradient.shape[0], : gradient.shape[1]] <= CLIPPED_SHARE
    rows_per, cols_per = max(window_height // FLAT_BLOCK, 1), max(window_width // FLAT_BLOCK, 1)
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
                best, best_score = (top * FLAT_BLOCK, left * FLAT_BLOCK), score
    return best[0], best[1], window_height, window_width
