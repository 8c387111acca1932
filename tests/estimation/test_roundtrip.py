"""Round trip through the shipped DEN: apply known noise to a clean image, estimate it back, compare.

The clean images are drawn here (smooth shapes and gradients), not taken from the training data. Tolerances
follow the held-out figures in docs/den.md: read noise is the best-determined parameter (R^2 about 0.9),
banding and temporal banding are measured on clips.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.estimation.assemble import estimate
from darksynth.light.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer
from darksynth.training.weights import default_weights_path, load_weights

NAMES = ("shot", "read", "quantization", "banding", "temporal_banding")


def _clean_scene(seed: int, height: int = 256, width: int = 384) -> torch.Tensor:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    scene = np.stack(
        [0.5 + 0.4 * np.sin(x / rng.uniform(30, 90) + c) * np.cos(y / rng.uniform(30, 90)) for c in range(3)]
    )
    for _ in range(6):
        cy, cx, r = rng.uniform(0, height), rng.uniform(0, width), rng.uniform(15, 60)
        scene[:, (y - cy) ** 2 + (x - cx) ** 2 < r**2] = rng.uniform(0.1, 0.95, (3, 1))
    return torch.from_numpy((np.clip(scene, 0, 1) * 255).round().astype(np.uint8))


def _reference(noise: dict[str, float], frames: int, seed: int) -> torch.Tensor:
    values = NoiseValues.from_values(noise)
    synthesizer = ClipSynthesizer(
        ClipParameters(noise=values, darkening=Darkening(0.25, 0.8)), generator=torch.Generator().manual_seed(seed)
    )
    clean = _clean_scene(seed)
    return torch.stack([synthesizer(clean) for _ in range(frames)]).float() / 255.0


@pytest.fixture(scope="module")
def model() -> torch.nn.Module:
    return load_weights(default_weights_path("v3", "paper"))


def test_read_noise_is_recovered_from_single_images(model: torch.nn.Module) -> None:
    truths = [0.01, 0.03, 0.05, 0.07, 0.09]
    estimates = [
        estimate(_reference({"read": read, "shot": 0.05}, 1, seed), model).profile.noise.scalar("read")
        for seed, read in enumerate(truths)
    ]
    assert np.all(np.diff(estimates) > 0), estimates
    assert np.allclose(estimates, truths, rtol=0.35, atol=0.01), estimates


def test_temporal_banding_is_told_from_banding_on_clips(model: torch.nn.Module) -> None:
    held = estimate(_reference({"temporal_banding": 0.02, "read": 0.02}, 8, 11), model).profile.noise
    per_frame = estimate(_reference({"banding": 0.02, "read": 0.02}, 8, 12), model).profile.noise
    assert held["temporal_banding"][0] > 2 * held["banding"][0], held
    assert per_frame["banding"][0] > 2 * per_frame["temporal_banding"][0], per_frame
