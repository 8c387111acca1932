"""Sets of real-like pairs made on the spot: smooth clean images and noisy partners with a known law."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from PIL import Image


def smooth_clean(height: int, width: int, phase: int) -> np.ndarray:
    """(H, W, 3) uint8 with gradients and a disc: smooth enough for the blind estimators."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    base = np.stack([40 + 150 * x / width, 60 + 120 * y / height, 90 + 60 * np.sin((x + phase) / 40)], axis=-1)
    disc = ((x - width / 2) ** 2 + (y - height / 2) ** 2) < (min(height, width) / 4) ** 2
    base[disc] += 30
    return base.clip(0, 255).round().astype(np.uint8)


MakeSet = Callable[..., Path]


@pytest.fixture
def make_pair_set(tmp_path: Path) -> MakeSet:
    """Write a set folder: ``count`` pairs with Gaussian noise of ``sigma`` (8-bit units) and a cameras.csv."""

    def make(name: str = "pairs", count: int = 3, sigma: float = 8.0, size: int = 96, seed: int = 0) -> Path:
        root = tmp_path / name
        (root / "noisy").mkdir(parents=True)
        (root / "clean").mkdir()
        rng = np.random.default_rng(seed)
        rows = ["name,camera,iso"]
        for index in range(count):
            clean = smooth_clean(size, size + 32, index * 7)
            noisy = (clean + rng.normal(0.0, sigma, clean.shape)).clip(0, 255).round().astype(np.uint8)
            file = f"pair_{index}.png"
            Image.fromarray(clean).save(root / "clean" / file)
            Image.fromarray(noisy).save(root / "noisy" / file)
            rows.append(f"{file},{'camA' if index % 2 == 0 else 'camB'},{800 * (index + 1)}")
        (root / "cameras.csv").write_text("\n".join(rows) + "\n")
        return root

    return make
