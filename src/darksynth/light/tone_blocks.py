"""The order statistics of a frame's small blocks that the darkening estimate reads, from one sort.

The tone quantiles take each block's median, the noise left in a median its 50th and 75th percentiles
(:mod:`darksynth.light.tones`). Sorting each block's values once gives all three, the same numbers as ``median`` and
``quantile`` (which sort again each); and a region of the frame on the block grid reads its blocks' statistics
from the frame's instead of sorting them again (a 12 MP photo's four regions are the photo).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

NOISE_BLOCKS = 1 << 18
"""At most about this many blocks are read to measure the noise left in a block median."""


def tiles(frames: torch.Tensor, block: int) -> torch.Tensor:
    """(..., C, H, W) -> (..., C, H // s, W // s, s * s), s = ``block`` or the shorter side if smaller."""
    side = block_side(frames, block)
    rows, columns = frames.shape[-2] // side, frames.shape[-1] // side
    lead = frames.shape[:-2]
    grid = frames[..., : rows * side, : columns * side].reshape(*lead, rows, side, columns, side)
    return grid.transpose(-3, -2).reshape(*lead, rows, columns, side * side)


def block_side(frames: torch.Tensor, block: int) -> int:
    """The side of the blocks of ``frames`` (..., H, W): ``block``, or the shorter side if smaller."""
    return max(1, min(block, frames.shape[-2], frames.shape[-1]))


def _quantile_of_sorted(ordered: torch.Tensor, probability: float) -> torch.Tensor:
    # torch.quantile's linear interpolation, on values already sorted along the last axis.
    rank = probability * (ordered.shape[-1] - 1)
    below = int(rank)
    above = min(below + 1, ordered.shape[-1] - 1)
    low = ordered[..., below]
    return torch.lerp(low, ordered[..., above], torch.full_like(low, rank - below))


@dataclass(frozen=True)
class BlockStatistics:
    """Per channel and block of one frame (C, rows, cols): the median (the lower middle value of an even count, an
    actual pixel value), the 50th and the 75th percentile (linearly interpolated, as ``torch.quantile``).

    Attributes:
        side: the blocks' side (the frame's shorter side when it is smaller than the block asked for).
    """

    medians: torch.Tensor
    centre: torch.Tensor
    upper: torch.Tensor
    side: int

    def noise_quantiles(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The 50th and 75th percentiles in flat order (channel, row, column), an even subsample of at most about
        :data:`NOISE_BLOCKS` blocks: the median noise read at a bounded cost (4K clips have ~25 M blocks)."""
        centre, upper = self.centre.flatten(), self.upper.flatten()
        step = max(1, centre.shape[0] // NOISE_BLOCKS)
        return centre[::step], upper[::step]

    def region(self, top: int, bottom: int, left: int, right: int) -> BlockStatistics | None:
        """The statistics of the frame's part ``[top:bottom, left:right]`` (pixels), when its blocks are the
        frame's (its corner on the block grid, at least a block a side); None otherwise."""
        side = self.side
        if top % side or left % side or min(bottom - top, right - left) < side:
            return None
        rows = slice(top // side, top // side + (bottom - top) // side)
        columns = slice(left // side, left // side + (right - left) // side)
        return BlockStatistics(
            self.medians[:, rows, columns], self.centre[:, rows, columns], self.upper[:, rows, columns], side
        )


def block_statistics(frame: torch.Tensor, block: int) -> BlockStatistics:
    """The :class:`BlockStatistics` of ``frame`` (C, H, W) (cast to float32) in ``block`` x ``block`` blocks; rows
    and columns past a multiple of the side are dropped."""
    ordered = tiles(frame.to(torch.float32), block).sort(dim=-1).values
    middle = (ordered.shape[-1] - 1) // 2
    return BlockStatistics(
        medians=ordered[..., middle].clone(),  # not a view that keeps the sorted blocks
        centre=_quantile_of_sorted(ordered, 0.5),
        upper=_quantile_of_sorted(ordered, 0.75),
        side=block_side(frame, block),
    )
