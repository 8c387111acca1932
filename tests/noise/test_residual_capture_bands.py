"""``scripts/noise/residual_capture_check.band_powers``: the band powers the residual-capture check compares, in
brightness and colour or per channel (``--channels``)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
import torch

from tests.script_modules import load_script

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "noise" / "residual_capture_check.py"


@pytest.fixture(scope="module")
def capture_check() -> ModuleType:
    return load_script(SCRIPT)


def _white(stds: tuple[float, float, float], size: int = 256, seed: int = 0) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    return torch.randn(3, size, size, generator=generator, dtype=torch.float64) * torch.tensor(stds)[:, None, None]


def test_per_channel_powers_follow_each_channels_variance(capture_check: ModuleType) -> None:
    stds = (1.0, 2.0, 3.0)
    mask = np.ones((256, 256), dtype=bool)
    powers = capture_check.band_powers(_white(stds), mask, channels=True)
    assert powers.shape == (3, capture_check.FINE_BANDS)
    # White noise puts a band's share of the frequency square in each band: the same share in every channel, so
    # each band's powers stand as the variances 1 : 4 : 9 (sampling error of 256 px bands: a few percent).
    relative = powers / powers[0]
    np.testing.assert_allclose(relative, np.array([1.0, 4.0, 9.0])[:, None] * np.ones_like(relative), rtol=0.08)


def test_brightness_and_colour_split_grey_texture_from_independent_noise(capture_check: ModuleType) -> None:
    mask = np.ones((256, 256), dtype=bool)
    independent = capture_check.band_powers(_white((1.0, 1.0, 1.0)), mask)
    grey = _white((1.0, 1.0, 1.0))[:1].expand(3, -1, -1)  # the same field in every channel: brightness only
    alike = capture_check.band_powers(grey, mask)
    assert independent.shape == (2, capture_check.FINE_BANDS)
    np.testing.assert_allclose(independent[0] / independent[1], 1.0, rtol=0.1)  # white: as much in each component
    assert np.all(alike[1] < 1e-20 * alike[0])  # a field alike in the channels has no colour at all
    by_channel = capture_check.band_powers(grey, mask, channels=True)
    np.testing.assert_allclose(by_channel.sum(axis=0), alike[0], rtol=1e-9)  # brightness power = the channels' sum
