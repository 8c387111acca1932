"""``scripts/noise/spectral_temporal_check.lag1_response``: whether a clip's lag-1 can show its noise's persistence
(the real-data benchmark compares a clip's lag-1 only where it can)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest
import torch
import torch.nn.functional as F

from darksynth.noise.values import NoiseValues
from tests.script_modules import load_script

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "noise" / "spectral_temporal_check.py"


@pytest.fixture(scope="module")
def temporal_check() -> ModuleType:
    return load_script(SCRIPT)


def _scene(seed: int, size: int = 160, texture: float = 0.25) -> torch.Tensor:
    """(3, size, size) in [0, 1]: smooth shading (flat for the measure) with blobs of ``texture`` over it."""
    generator = torch.Generator().manual_seed(seed)
    coarse = F.interpolate(torch.rand(1, 3, 6, 6, generator=generator), size=(size, size), mode="bicubic")[0]
    fine = F.avg_pool2d(torch.rand(1, 3, size, size, generator=generator), 3, 1, 1)[0]
    return (0.25 + 0.3 * coarse + texture * (fine - 0.5) * (coarse > 0.5)).clamp(0.0, 1.0)


def _noise(level_8bit: float) -> NoiseValues:
    """Spectral noise (the model whose frames persist) of one level everywhere, equal power in every octave."""
    return NoiseValues.from_values({"level_curve": [level_8bit / 255.0] * 24}, dtype=torch.float32)


def _noisy(frames: torch.Tensor, level_8bit: float, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    noisy = frames + torch.randn(frames.shape, generator=generator) * level_8bit / 255.0
    return torch.round(noisy.clamp(0.0, 1.0) * 255.0) / 255.0


def test_a_still_clip_shows_persistence_a_panning_one_less_and_under_weak_noise_nothing(
    temporal_check: ModuleType,
) -> None:
    scene = _scene(2, 220)
    panning = torch.stack([scene[:, 20:180, 20 + 3 * t : 180 + 3 * t] for t in range(4)])
    still = panning[:1].expand(4, -1, -1, -1)
    still_response = temporal_check.lag1_response(_noisy(still, 2.0, 3), _noise(2.0), strength=3.0)
    panning_response = temporal_check.lag1_response(_noisy(panning, 2.0, 3), _noise(2.0), strength=3.0)
    weak_panning = temporal_check.lag1_response(_noisy(panning, 0.4, 3), _noise(0.4), strength=3.0)
    # Measured: 0.53, 0.39, 0.04.
    assert still_response > 0.45
    assert panning_response < still_response - 0.1
    assert weak_panning < 0.1


def test_aligned_lag1_reads_noise_that_moves_with_a_panning_scene(temporal_check: ModuleType) -> None:
    # Without fine texture: texture finer than the measure's blur passes as flat and reads as persistence.
    scene = _scene(4, 240, texture=0.0)
    # Noise drawn on the scene itself (it moves with it, as a codec's motion compensation carries it), then each
    # frame a window 3 px further right; against fresh noise in every frame.
    carried = _noisy(scene[None], 3.0, 5)[0]
    fresh = _noisy(scene[None].expand(4, -1, -1, -1), 3.0, 6)

    def window(frames: list[torch.Tensor]) -> torch.Tensor:
        return torch.stack([frame[:, 30:190, 30 + 3 * t : 190 + 3 * t] for t, frame in enumerate(frames)])

    moving_noise = window([carried] * 4)
    independent = window(list(fresh))
    assert temporal_check.aligned_lag1_correlation(moving_noise) > 0.9
    assert temporal_check.lag1_correlation(moving_noise) < 0.5
    assert abs(temporal_check.aligned_lag1_correlation(independent)) < 0.1
