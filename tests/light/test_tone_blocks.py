"""The darkening's block statistics from one sort read what median and quantile read."""

from __future__ import annotations

import torch

from darksynth.light.tone_blocks import NOISE_BLOCKS, block_statistics, tiles
from darksynth.light.tones import _block_noise_quantiles, block_medians


def test_one_sort_gives_the_median_and_the_quantiles() -> None:
    frame = (torch.rand(3, 70, 90, generator=torch.Generator().manual_seed(0)) * 255).round() / 255
    for block in (4, 3):
        found = block_statistics(frame, block)
        assert torch.equal(found.medians, block_medians(frame, block))
        centre, upper = torch.quantile(tiles(frame, block), torch.tensor([0.5, 0.75]), dim=-1)
        assert torch.equal(found.centre, centre)
        assert torch.equal(found.upper, upper)
        reference_centre, reference_upper = _block_noise_quantiles(frame, block)
        assert torch.equal(found.noise_quantiles()[0], reference_centre)
        assert torch.equal(found.noise_quantiles()[1], reference_upper)


def test_a_region_on_the_block_grid_reads_the_frames_blocks() -> None:
    frame = torch.rand(3, 64, 80, generator=torch.Generator().manual_seed(1))
    whole = block_statistics(frame, 4)
    region = whole.region(32, 64, 40, 79)
    assert region is not None
    part = block_statistics(frame[:, 32:64, 40:79], 4)
    for name in ("medians", "centre", "upper"):
        assert torch.equal(getattr(region, name), getattr(part, name))
    assert whole.region(30, 64, 40, 80) is None  # off the grid: the caller sorts the part itself


def test_the_noise_quantiles_are_subsampled_as_the_median_noise_reads_them() -> None:
    frame = torch.rand(1, 4 * 8, 4 * (NOISE_BLOCKS // 8 + 3))
    centre, _ = block_statistics(frame, 4).noise_quantiles()
    assert torch.equal(centre, _block_noise_quantiles(frame, 4)[0])
