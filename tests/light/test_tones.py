"""The tone distribution of images: block medians and their quantiles."""

from __future__ import annotations

import pytest
import torch

from darksynth.light.darkening import darken
from darksynth.light.tones import block_medians, tone_quantiles


def test_block_medians_commute_with_darkening() -> None:
    clean = torch.rand(2, 3, 17, 22, generator=torch.Generator().manual_seed(0))
    medians = block_medians(clean, 4)
    assert medians.shape == (2, 3, 4, 5)
    torch.testing.assert_close(block_medians(darken(clean, 0.2, 0.4), 4), darken(medians, 0.2, 0.4))


def test_tone_quantiles_pool_frames_and_channels() -> None:
    frames = torch.stack([torch.full((3, 8, 8), 0.2), torch.full((3, 8, 8), 0.6)])
    quantiles = tone_quantiles(frames)
    assert quantiles[0] == pytest.approx(0.2) and quantiles[-1] == pytest.approx(0.6)
