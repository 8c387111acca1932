"""Training material: folders of stills and of clip frames."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.clean_images import smooth_rgb, write_png


@pytest.fixture
def image_folder(tmp_path: Path) -> Path:
    """Three 96x96 stills."""
    folder = tmp_path / "stills"
    for index in range(3):
        write_png(folder / f"still_{index}.png", smooth_rgb(96, 96, phase=5 * index))
    return folder


@pytest.fixture
def clip_root(tmp_path: Path) -> Path:
    """A folder holding one clip: a sub-folder of four 96x96 frames of a moving disc."""
    root = tmp_path / "clips"
    for index in range(4):
        write_png(root / "walk" / f"frame_{index:03d}.png", smooth_rgb(96, 96, phase=3 * index))
    return root
