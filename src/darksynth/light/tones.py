"""The tone distribution of images: what the darkening x_d = alpha * x ** (1 / gamma) is read from
(:mod:`darksynth.light.tone_fit`), by ``estimate`` on a real low-light reference and by ``apply`` on each clean input.

The tone distribution is the quantile function q(p) of the pooled R, G and B values, taken over the medians of small
blocks (:data:`TONE_BLOCK` pixels square, per channel): a median commutes with any increasing function, so the block
medians of a darkened image are exactly the darkened block medians, while noise in them shrinks by about the block
side and clipping at 0 does not bias them (the median of clip(x + n) is clip(x) for symmetric noise). The noise left
in a block median (:func:`median_noise`) sets the floor below which the fit leaves quantiles out. What a viewer sees
of the exposure (:func:`luminance_quantiles`) and the colour of the light (:func:`colour_cast`) complete the
reference's :class:`ToneTarget`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from darksynth.light.tone_blocks import NOISE_BLOCKS, block_side, tiles
from darksynth.tensors import luminance

TONE_BLOCK = 4
"""Side of the square blocks whose per-channel medians make the tone distribution."""

PROBABILITIES: tuple[float, ...] = tuple(round(0.02 * i, 2) for i in range(1, 50))
"""The quantile levels p fitted: 0.02, 0.04, ..., 0.98."""

_MEDIAN_EFFICIENCY = 1.2533  # std of the median of n normal samples is about 1.2533 sigma / sqrt(n)


@dataclass(frozen=True)
class ToneTarget:
    """The reference's exposure, which ``apply`` and ``synthesize`` match each input's darkening to
    (:func:`~darksynth.exposure.match_darkening`); a profile's ``tone``.

    Attributes:
        quantiles: the reference's :func:`tone_quantiles` at :data:`PROBABILITIES`.
        noise: the noise in one of its block medians (:func:`median_noise`).
    """

    quantiles: tuple[float, ...]
    noise: float
    colour: tuple[float, float, float] | None = None
    """The reference's colour cast (:func:`colour_cast`), or None (grey, or a profile written before it)."""
    luminance: tuple[float, ...] | None = None
    """The reference's :func:`luminance_quantiles` at :data:`PROBABILITIES`: the tones a viewer sees, noise,
    clipping and 8-bit levels included, which ``apply`` fits each output's to; None in profiles written before
    them (the match then stops at the block medians)."""


LUMINANCE_PIXELS = 1 << 20
"""At most about this many pixels are read for a reference's luminance quantiles (every k-th pixel): a million
values fix its 49 quantiles to far below an 8-bit level at a bounded cost on long 4K clips."""


def luminance_quantiles(frames: torch.Tensor, *, probabilities: tuple[float, ...] = PROBABILITIES) -> np.ndarray:
    """Quantiles of the pixel luminance of frames (..., C, H, W) on the [0, 1] scale, pooled over frames, at
    ``probabilities``: what a viewer sees of the exposure, noise and clipping included (block medians leave both
    out). Read on every k-th pixel past :data:`LUMINANCE_PIXELS`."""
    values = luminance(frames).flatten()
    values = values[:: max(1, values.numel() // LUMINANCE_PIXELS)]
    return np.quantile(values.numpy().astype(np.float64), probabilities)


def colour_cast(frames: torch.Tensor, *, block: int = TONE_BLOCK) -> tuple[float, float, float] | None:
    """The colour cast of frames (..., 3, H, W): each channel's share of the light, as the sum of its block medians
    over the mean of the three channels' sums (1, 1, 1 for grey; a sodium-lit street is about 1.4, 0.9, 0.6).

    Block medians, as for the tones, so that noise (symmetric about the level) does not move the cast; sums, so
    that the bright blocks, where the cast is seen, weigh most. None for grey input or frames without light.
    """
    if frames.dim() < 3 or frames.shape[-3] != 3:
        return None
    # On a sample of the blocks of a large frame, as the tones (:func:`sampled_blocks`).
    medians = block_medians(sampled_blocks(frames.to(torch.float32), block=block), block)
    sums = medians.movedim(-3, 0).reshape(3, -1).sum(dim=1).double()
    mean = float(sums.mean())
    if mean <= 0.0:
        return None
    red, green, blue = (float(v) / mean for v in sums)
    return (red, green, blue)


def block_medians(frames: torch.Tensor, block: int = TONE_BLOCK) -> torch.Tensor:
    """Per-channel medians of non-overlapping ``block`` x ``block`` tiles.

    Args:
        frames: (..., C, H, W) values on the [0, 1] scale; rows and columns past a multiple of ``block`` are
            dropped.
        block: tile side; smaller frames use their shorter side.

    Returns:
        (..., C, H // block, W // block) medians (the lower middle value of an even count, so an actual pixel
        value: the medians of a darkened frame are exactly the darkened medians).
    """
    if frames.dim() < 3:
        raise ValueError(f"expected frames shaped (..., C, H, W), got shape {tuple(frames.shape)}")
    medians: torch.Tensor = tiles(frames, block).median(dim=-1).values
    return medians


MATCH_BLOCKS = 1 << 14
"""At most about this many blocks of a clean input are read to match its exposure (every k-th block row and
column): its 49 quantiles are as well determined by 16k blocks as by a 1080p frame's 130k (67 ms, against
about 5)."""


def sampled_blocks(frames: torch.Tensor, *, block: int = TONE_BLOCK, most: int = MATCH_BLOCKS) -> torch.Tensor:
    """Every k-th block row and column of ``frames`` (..., C, H, W), put side by side, k the smallest that leaves
    at most ``most`` blocks per channel and frame (``frames`` itself for small frames)."""
    rows, columns = frames.shape[-2] // block, frames.shape[-1] // block
    step = max(1, math.ceil(math.sqrt(rows * columns / most)))
    if step == 1:
        return frames
    # The first block of every step x step group of blocks.
    rows, columns = rows // step, columns // step
    grouped = frames[..., : rows * step * block, : columns * step * block].reshape(
        *frames.shape[:-2], rows, step * block, columns, step * block
    )
    return grouped[..., :block, :, :block].reshape(*frames.shape[:-2], rows * block, columns * block)


def sampled_tone_quantiles(frames: torch.Tensor, *, block: int = TONE_BLOCK) -> np.ndarray:
    """:func:`tone_quantiles` of :func:`sampled_blocks` of ``frames`` (the same numbers for small frames)."""
    return tone_quantiles(sampled_blocks(frames, block=block), block=block)


def tone_quantiles(
    frames: torch.Tensor, *, block: int = TONE_BLOCK, probabilities: tuple[float, ...] = PROBABILITIES
) -> np.ndarray:
    """Quantiles q(p) of the block medians of all channels and frames.

    Args:
        frames: (..., C, H, W) values on the [0, 1] scale.

    Returns:
        (len(probabilities),) float64 array.
    """
    values = block_medians(frames.to(torch.float32), block).flatten().numpy().astype(np.float64)
    # numpy's quantile selects in linear time and has no size limit (torch.quantile stops at 2**24 values).
    return np.quantile(values, probabilities)


def median_noise(frames: torch.Tensor, block: int = TONE_BLOCK) -> float:
    """Standard deviation of the noise left in one block median, on the [0, 1] scale.

    The noise of a block is read from its upper half, (75th percentile - median) / 0.6745, which clipping at
    0 leaves intact for any block whose median is above 0; the median over blocks with a non-zero 75th
    percentile keeps texture in a few blocks from weighing. The median of ``block ** 2`` pixels has about
    1.25 / ``block`` of that standard deviation.
    """
    frames = frames.to(torch.float32)
    centre, upper = _block_noise_quantiles(frames, block)
    return noise_of_quantiles(centre, upper, block_side(frames, block))


def _block_noise_quantiles(frames: torch.Tensor, block: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Median and 75th percentile of every block of float32 frames, in flat order (frame, channel, row, column)."""
    flat = tiles(frames, block).flatten(0, -2)
    # An even subsample of the blocks reads the same median noise at a bounded cost (4K clips have ~25 M).
    flat = flat[:: max(1, flat.shape[0] // NOISE_BLOCKS)]
    centre, upper = torch.quantile(flat, torch.tensor([0.5, 0.75]), dim=-1)
    return centre, upper


def noise_of_quantiles(centre: torch.Tensor, upper: torch.Tensor, side: int) -> float:
    lit = upper > 0
    if not bool(lit.any()):
        return 0.0
    return float((upper - centre)[lit].median()) / 0.6745 * _MEDIAN_EFFICIENCY / side
