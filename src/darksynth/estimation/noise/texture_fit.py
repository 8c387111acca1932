"""Fitting ``texture_gain`` and ``texture_scale`` (noise that follows texture, :mod:`darksynth.noise.texture`) with
the clean image: the real noise map's textured-to-flat ratio reproduced by simulations on the clean image.

The statistic: per 32-px block of the clean image its detail (:func:`darksynth.noise.texture.block_detail`) and its
noise power (each channel's variance about the block's mean, averaged over channels) divided by the power the level
curve predicts at the block's pixels; the ratio is the square root of that normalised power over the 30% most
textured blocks against the 30% least textured. The normalisation keeps blocks that are textured because they are
bright from reading as texture's noise.

For each ``texture_scale`` of a fixed grid the gain is read off a grid of gains (the ratio rises with the gain) by
linear interpolation; the scale kept is the one whose simulation follows the real normalised power best across five
detail classes (quantiles of the block detail), not only at the two ends the ratio compares.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

from darksynth.noise.texture import TEXTURE_BLOCK, block_detail, block_mean, textured_and_flat

TEXTURE_SCALES: tuple[float, ...] = (0.002, 0.004, 0.008, 0.016, 0.032)
"""``texture_scale`` values tried: detail levels of 0.5 to 8 8-bit levels, an octave apart."""

TEXTURE_GAINS: tuple[float, ...] = (0.0, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
"""Gains at which each scale's ratio is simulated; the fitted gain is interpolated between them (4 is the
parameter's maximum)."""

DETAIL_CLASSES = 5
"""Quantile classes of block detail over which the scales are compared."""


@dataclass(frozen=True)
class TextureBlocks:
    """What a fit reads of the clean image once: the blocks' detail classes and the level curve's power per block.

    Attributes:
        textured, flat: (T, rows, columns) the 30% most and least textured blocks.
        classes: (T, rows, columns) int64 detail class 0 (flattest) .. DETAIL_CLASSES - 1.
        level_power: (T, rows, columns) mean over the block's pixels and channels of the level curve's variance.
    """

    textured: torch.Tensor
    flat: torch.Tensor
    classes: torch.Tensor
    level_power: torch.Tensor


def texture_blocks(clean: torch.Tensor, level_std: torch.Tensor) -> TextureBlocks:
    """The blocks of ``clean`` (T, C, H, W) with the level curve's std at each pixel ``level_std`` (T, C, H, W)."""
    detail = block_detail(clean.to(torch.float64))
    textured, flat = textured_and_flat(detail)
    order = torch.argsort(torch.argsort(detail.flatten(), stable=True))
    classes = (order * DETAIL_CLASSES // max(detail.numel(), 1)).view(detail.shape)
    level_power = block_mean(level_std.to(torch.float64).square()).mean(dim=1)
    return TextureBlocks(textured, flat, classes, level_power)


def block_power(noise: torch.Tensor) -> torch.Tensor:
    """(T, rows, columns) each :data:`TEXTURE_BLOCK`-px block's noise power of ``noise`` (T, C, H, W): each channel's
    variance about the block's mean, averaged over channels."""
    noise = noise.to(torch.float64)
    return (block_mean(noise.square(), TEXTURE_BLOCK) - block_mean(noise, TEXTURE_BLOCK).square()).mean(dim=1)


def normalised_ratio(power: torch.Tensor, blocks: TextureBlocks) -> float:
    """The textured-to-flat ratio of block noise ``power`` (from :func:`block_power`), each block's power divided by
    the level curve's (nan without flat power)."""
    relative = power / blocks.level_power.clamp_min(1e-12)
    flat = float(relative[blocks.flat].mean())
    return math.sqrt(float(relative[blocks.textured].mean()) / flat) if flat > 0 else math.nan


def class_profile(power: torch.Tensor, blocks: TextureBlocks) -> torch.Tensor:
    """(DETAIL_CLASSES,) log of the mean normalised block power per detail class, relative to the flattest class's
    (nan for an empty class)."""
    relative = power / blocks.level_power.clamp_min(1e-12)
    means = torch.stack([relative[blocks.classes == k].mean() for k in range(DETAIL_CLASSES)])
    logs = means.clamp_min(1e-30).log()
    return logs - logs[0]


@dataclass(frozen=True)
class TextureFit:
    """A fitted texture: the gain, the scale, the real and the simulated ratio (the simulation's at the fit)."""

    gain: float
    scale: float
    real_ratio: float
    simulated_ratio: float


def interpolated_gain(target: float, ratios: list[float]) -> float:
    """The gain of :data:`TEXTURE_GAINS` at which the simulated ``ratios`` (one per gain, rising) reach ``target``:
    linear between the grid's gains, 0 below the first ratio, the last gain beyond the last."""
    if not target > ratios[0]:
        return 0.0
    for (low_gain, high_gain), (low, high) in zip(
        itertools.pairwise(TEXTURE_GAINS), itertools.pairwise(ratios), strict=True
    ):
        if low < target <= high:
            return low_gain + (high_gain - low_gain) * (target - low) / max(high - low, 1e-12)
    return TEXTURE_GAINS[-1]


def fit_texture(
    real_power: torch.Tensor,
    blocks: TextureBlocks,
    simulated_power: Callable[[float, float], torch.Tensor],
    *,
    correction: float = 1.0,
) -> TextureFit:
    """The gain and scale whose simulation reproduces the real noise's textured-to-flat ratio.

    Args:
        real_power: (T, rows, columns) :func:`block_power` of the real noise map.
        blocks: :func:`texture_blocks` of the clean image.
        simulated_power: ``(gain, scale) -> block power`` of a simulation on the clean image (common draws).
        correction: the real ratio is divided by it before the search: what the simulation leaves out and
            multiplies the ratio by (the JPEG stage, when the search runs without it).
    """
    real_ratio = normalised_ratio(real_power, blocks)
    real_profile = class_profile(real_power, blocks)
    target = real_ratio / correction
    best: tuple[float, float, float, float] | None = None
    for scale in TEXTURE_SCALES:
        ratios = [normalised_ratio(simulated_power(gain, scale), blocks) for gain in TEXTURE_GAINS]
        gain = interpolated_gain(target, ratios)
        power = simulated_power(gain, scale)
        gap = (class_profile(power, blocks) - real_profile)[1:]
        error = float(gap[torch.isfinite(gap)].square().mean()) if bool(torch.isfinite(gap).any()) else math.inf
        if best is None or error < best[0]:
            best = (error, gain, scale, normalised_ratio(power, blocks))
    assert best is not None
    return TextureFit(gain=best[1], scale=best[2], real_ratio=real_ratio, simulated_ratio=best[3] * correction)
