"""Images the example tests draw and write: smooth colour scenes saved as 8-bit PNG."""

from pathlib import Path

import numpy as np
from PIL import Image


def smooth_scene(generator: np.random.Generator, side: int) -> np.ndarray:
    """A smooth colour scene (H, W, 3) float in [0.15, 0.75]."""
    y, x = np.mgrid[0:side, 0:side] / side
    phase = generator.uniform(0, 6.28, 3)
    return np.stack([0.45 + 0.3 * np.sin(3 * x + 2 * y + p) for p in phase], axis=-1)


def write_png(path: Path, pixels: np.ndarray) -> None:
    """``pixels`` in [0, 1] (clipped) as an 8-bit PNG, its folder made."""
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((np.clip(pixels, 0, 1) * 255).round().astype(np.uint8)).save(path)
