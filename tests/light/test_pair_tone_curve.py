"""scripts/light/pair_tone_curve.py: an enhancement pair's exponent, and what a reading of its low image alone gives
when the pair's normal-light image is not an average scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.script_modules import load_script
from tests.tone_scenes import prior_scene

SCRIPT = load_script(Path(__file__).resolve().parents[2] / "scripts" / "light" / "pair_tone_curve.py")


def _pair(high_exponent: float, pair_exponent: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A normal-light image with the average scene's tones raised to ``high_exponent`` (below 1: flatter and
    brighter), and its low-light image ``0.2 * high ** pair_exponent``, both on 8-bit levels, (H, W, 3)."""
    scene = prior_scene(seed, size=256).permute(1, 2, 0).double().numpy()
    high = np.round(scene**high_exponent * 255.0) / 255.0
    low = np.round(0.2 * high**pair_exponent * 255.0) / 255.0
    return low, high


@pytest.mark.parametrize(("high_exponent", "pair_exponent"), [(1.0, 1.8), (0.6, 1.8), (0.6, 1.2)])
def test_the_low_image_reads_the_pair_exponent_times_the_high_image_own(
    high_exponent: float, pair_exponent: float
) -> None:
    low, high = _pair(high_exponent, pair_exponent, seed=3)
    _, p = SCRIPT.tone_curve(low, high)
    low_read, high_read = SCRIPT.read_exponents(low, high)
    assert p == pytest.approx(pair_exponent, rel=0.05)
    assert high_read == pytest.approx(high_exponent, rel=0.12)
    assert low_read == pytest.approx(pair_exponent * high_exponent, rel=0.15)
