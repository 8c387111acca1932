"""The estimate checked on its own reference: the profile's noise put back on the reference's denoised version must
show on the flattest blocks the noise the reference shows there.

One statistic serves the estimate (per intensity, to correct a level the reference contradicts) and the judgement
of a change on real data (over the whole reference: ``benchmarks/real_data.py``): the std of 32-px blocks, read on
the blocks whose denoised version is flattest and whose mean lies inside the 8-bit range (a block of crushed black or
of a lamp shows no noise). Real and synthetic hold the same denoised scene, so what the denoiser left of the scene
counts on both sides alike; their ratio is 1 when the profile's noise is as strong as what the denoiser took off.

Pure functions on (3, H, W) frames in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from darksynth.estimation.flat_blocks import FLAT_BLOCK, block_gradient, level_stratum

CHECK_SHARE = 0.1
"""Share of the blocks (the flattest, by the denoised version's gradient) the check reads."""

CHECK_MEAN_RANGE = (8.0 / 255.0, 247.0 / 255.0)
"""Block means (of the denoised version, over channels) the check reads: outside it noise is cut off at 0 or full
scale (a camera's crushed black, a lamp) and the block shows less than the noise."""

CONSISTENT_RANGE = (0.8, 1.25)
"""Synthetic over real std within this range: the profile reproduces what the reference shows."""

MIN_CHECK_BLOCKS = 3
"""Fewest blocks an intensity needs before its ratio is read (one or two blocks are one patch of scene)."""


@dataclass(frozen=True)
class BlockCheck:
    """The check on one set of blocks: the median over its blocks of the real and the synthetic std, and the level
    factor that would make the synthetic match (``supported``: the noise's std times this reproduces the real std,
    nan where the denoised scene alone is already as rough as the reference)."""

    blocks: int
    real_std: float
    synthetic_std: float
    supported: float

    @property
    def ratio(self) -> float:
        """Synthetic over real std (1: the profile shows what the reference shows)."""
        return self.synthetic_std / max(self.real_std, 1e-12)

    @property
    def consistent(self) -> bool:
        return CONSISTENT_RANGE[0] <= self.ratio <= CONSISTENT_RANGE[1]


def _block_std(frame: torch.Tensor) -> torch.Tensor:
    """(rows * cols,) std of each whole 32-px block of ``frame`` (3, H, W), the mean over channels of each
    channel's std about the block's mean."""
    blocks = F.unfold(frame[:, None].to(torch.float64), FLAT_BLOCK, stride=FLAT_BLOCK)
    return blocks.std(dim=1).mean(0)


def _block_means(frame: torch.Tensor) -> torch.Tensor:
    grey = frame.mean(0)[None, None].to(torch.float64)
    return F.avg_pool2d(grey, FLAT_BLOCK)[0, 0].flatten()


def _flattest(candidates: torch.Tensor, gradient: torch.Tensor) -> torch.Tensor:
    """Of the ``candidates`` (n,) bool, the :data:`CHECK_SHARE` with the least ``gradient`` (at least one)."""
    members = candidates.nonzero().flatten()
    if members.numel() == 0:
        return candidates.clone()
    count = max(1, round(CHECK_SHARE * members.numel()))
    chosen = torch.zeros_like(candidates)
    chosen[members[gradient[members].argsort()[:count]]] = True
    return chosen


def checked_blocks(denoised: torch.Tensor) -> torch.Tensor:
    """(rows * cols,) bool: the :data:`CHECK_SHARE` flattest of the blocks of ``denoised`` (3, H, W) whose mean lies in
    :data:`CHECK_MEAN_RANGE`."""
    gradient = block_gradient(denoised).flatten().to(torch.float64)
    means = _block_means(denoised)[: gradient.numel()]
    inside = (means >= CHECK_MEAN_RANGE[0]) & (means <= CHECK_MEAN_RANGE[1])
    return _flattest(inside, gradient)


def checked_blocks_per_intensity(denoised: torch.Tensor) -> dict[int, torch.Tensor]:
    """Per segment of the level curve (:func:`~darksynth.estimation.flat_blocks.level_stratum`) that holds
    :data:`MIN_CHECK_BLOCKS` blocks in :data:`CHECK_MEAN_RANGE`, the flattest :data:`CHECK_SHARE` of them (at least
    :data:`MIN_CHECK_BLOCKS`): flat for the noise at that intensity."""
    gradient = block_gradient(denoised).flatten().to(torch.float64)
    means = _block_means(denoised)[: gradient.numel()]
    inside = (means >= CHECK_MEAN_RANGE[0]) & (means <= CHECK_MEAN_RANGE[1])
    stratum = level_stratum(means)
    chosen: dict[int, torch.Tensor] = {}
    for segment in sorted(set(stratum[inside].tolist())):
        members = (inside & (stratum == segment)).nonzero().flatten()
        if members.numel() < MIN_CHECK_BLOCKS:
            continue
        count = max(MIN_CHECK_BLOCKS, round(CHECK_SHARE * members.numel()))
        picked = torch.zeros_like(inside)
        picked[members[gradient[members].argsort()[:count]]] = True
        chosen[segment] = picked
    return chosen


def block_check(
    reference: torch.Tensor, denoised: torch.Tensor, synthetic: torch.Tensor, blocks: torch.Tensor
) -> BlockCheck:
    """The check on the ``blocks`` (rows * cols,) bool: ``synthetic`` is the profile's noise added to ``denoised``
    (all three (3, H, W), the same size)."""
    real, clean, made = (_block_std(frame)[: blocks.numel()][blocks] for frame in (reference, denoised, synthetic))
    real_std, synthetic_std = float(real.median()), float(made.median())
    # The level factor the check supports: real = scene + noise and synthetic = scene + factor^2 * noise (variances).
    scene_variance = float(clean.square().median())
    noise_variance = synthetic_std**2 - scene_variance
    wanted = real_std**2 - scene_variance
    supported = math.sqrt(wanted / noise_variance) if wanted > 0 and noise_variance > 0 else math.nan
    return BlockCheck(int(blocks.sum()), real_std, synthetic_std, supported)


def self_consistency(reference: torch.Tensor, denoised: torch.Tensor, synthetic: torch.Tensor) -> BlockCheck:
    """The check over the whole reference (3, H, W): on the :data:`CHECK_SHARE` flattest blocks of its denoised
    version whose mean lies in :data:`CHECK_MEAN_RANGE`."""
    return block_check(reference, denoised, synthetic, checked_blocks(denoised))
