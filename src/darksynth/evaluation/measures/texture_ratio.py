"""Whether noise follows texture: its std on the most textured blocks of the clean image over its std on the flattest.

Real in-camera processing (denoising, JPEG) flattens noise in flat regions and keeps it on texture; noise drawn
from the signal's brightness alone has a ratio near 1. The blocks and their detail are those of the spectral
model's texture (:mod:`darksynth.noise.texture`), so the measure and the model read texture the same way.
"""

from __future__ import annotations

import math

import torch

from darksynth.noise.texture import TEXTURE_BLOCK, TEXTURE_SHARE, block_detail, block_mean, textured_and_flat


def textured_flat_ratio(noise: torch.Tensor, clean: torch.Tensor, share: float = TEXTURE_SHARE) -> float:
    """The noise's std over the ``share`` (30%) most textured :data:`TEXTURE_BLOCK`-px (32) blocks of ``clean``
    over its std over the ``share`` least textured.

    Each block's noise power is each channel's variance about the block's mean (a slow drift between a noisy image
    and its clean partner is no noise), averaged over channels; the ratio is the square root of the mean power over
    the textured blocks over that over the flat ones. Block detail: :func:`darksynth.noise.texture.block_detail` of
    ``clean`` (the RMS of its luminance minus a 1.5-px blur).

    Args:
        noise: (C, H, W) or (T, C, H, W) noise map (noisy - clean), [0, 1] scale.
        clean: the clean image, shaped like ``noise``.

    Returns:
        The ratio (1: the noise ignores texture); nan for an image under one block or without flat power.
    """
    flat, textured = flat_and_textured_std(noise, clean, share)
    return textured / flat if flat > 0 else math.nan


def flat_and_textured_std(
    noise: torch.Tensor, clean: torch.Tensor, share: float = TEXTURE_SHARE
) -> tuple[float, float]:
    """The two stds :func:`textured_flat_ratio` divides: the noise's over the ``share`` least textured blocks of
    ``clean`` and over the ``share`` most textured (nan for an image under one block)."""
    if noise.dim() == 3:
        noise, clean = noise[None], clean[None]
    detail = block_detail(clean.to(torch.float64), TEXTURE_BLOCK)
    if detail.numel() == 0:
        return math.nan, math.nan
    noise = noise.to(torch.float64)
    power = (block_mean(noise.square()) - block_mean(noise).square()).mean(dim=1)
    textured, flat = textured_and_flat(detail, share)
    return math.sqrt(float(power[flat].mean())), math.sqrt(float(power[textured].mean()))
