"""scripts/noise/jpeg_grid_check.py: an in-camera JPEG's 8-px grid is seen, noise and a 4-px period are not."""

from __future__ import annotations

from pathlib import Path

import torch

from darksynth.noise.compression import jpeg_compress
from tests.script_modules import load_script

SCRIPT = load_script(Path(__file__).resolve().parents[2] / "scripts" / "noise" / "jpeg_grid_check.py")


def _noisy(seed: int) -> torch.Tensor:
    """A smooth dark scene (no period of its own) with white noise of 3 levels, on 8-bit levels."""
    generator = torch.Generator().manual_seed(seed)
    coarse = torch.rand(1, 3, 16, 16, generator=generator)
    scene = torch.nn.functional.interpolate(coarse, size=(256, 256), mode="bicubic", align_corners=False)[0]
    image = (0.05 + 0.2 * scene.clamp(0, 1) + 0.012 * torch.randn(3, 256, 256, generator=generator)).clamp(0, 1)
    return (image * 255.0).round() / 255.0


def test_jpeg_shows_the_grid_and_noise_alone_does_not() -> None:
    for seed in range(3):
        noisy = _noisy(seed)
        assert not SCRIPT.shows_grid(noisy)[0]
        grid, score = SCRIPT.shows_grid(jpeg_compress(noisy, 60))
        assert grid and score > 1.3, score
        # Cropped off the grid by 3 px, the grid is still one phase in 8.
        assert SCRIPT.shows_grid(jpeg_compress(noisy, 60)[:, 3:, 5:])[0]


def test_a_four_pixel_period_is_not_a_jpeg_grid() -> None:
    noisy = _noisy(0)
    steps = torch.zeros(256)
    steps[::4] = 4.0 / 255.0  # a step every 4 px, on both axes
    patterned = ((noisy + steps[None, :, None] + steps[None, None, :]) * 255.0).round().clamp(0, 255) / 255.0
    assert not SCRIPT.shows_grid(patterned)[0]
