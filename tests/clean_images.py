"""Clean test material made on the spot: smooth gradients and shapes saved as PNGs, a tiny training corpus."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image


def smooth_rgb(height: int, width: int, phase: int = 0) -> np.ndarray:
    """(H, W, 3) uint8: a gradient per channel and a bright disc, shifted by ``phase``."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    red = 30 + 180 * x / max(width - 1, 1)
    green = 40 + 150 * y / max(height - 1, 1)
    blue = 120 + 80 * np.sin((x + y + 7 * phase) / 11.0)
    disc = ((x - width / 2 - phase) ** 2 + (y - height / 2) ** 2) < (min(height, width) / 4) ** 2
    pixels = np.stack([red, green, blue], axis=-1) + 40 * disc[..., None]
    return np.clip(pixels, 0, 255).round().astype(np.uint8)


def write_png(path: Path, pixels: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path)
    return path


def write_tiny_corpus(root: Path) -> Path:
    """The training tests' corpus: two 96x96 stills in ``stills/`` and a 3-frame clip in ``clips/pan/``."""
    for index in range(2):
        write_png(root / "stills" / f"still_{index}.png", smooth_rgb(96, 96, phase=7 * index))
    for index in range(3):
        write_png(root / "clips" / "pan" / f"{index:02d}.png", smooth_rgb(96, 96, phase=2 * index))
    return root
