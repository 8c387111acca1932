"""Tiny synthetic datasets of every format, written in tmp_path, and helpers to compare output trees."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from darksynth.io.video import VideoWriter
from darksynth.profile import default_profile_path

WIDTH, HEIGHT = 64, 48


def write_image(path: Path, seed: int, *, size: tuple[int, int] = (WIDTH, HEIGHT)) -> Path:
    """A smooth random-coloured picture (noise-free, so darkening and noise are visible), format by suffix."""
    rng = np.random.default_rng(seed)
    width, height = size
    ramp = np.linspace(0.3, 1.0, width)[None, :, None] * np.ones((height, 1, 1))
    pixels = (ramp * rng.uniform(100, 250, 3)).astype(np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path)
    return path


def write_video(path: Path, frames: int = 6, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    with VideoWriter(path, width=WIDTH, height=HEIGHT, fps=Fraction(25)) as writer:
        for _ in range(frames):
            writer.write(rng.integers(60, 200, (HEIGHT, WIDTH, 3), dtype=np.uint8))
    return path


def tree_bytes(root: Path) -> dict[str, bytes]:
    """Every file under root (hidden ones included) by relative path."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture
def profile_path() -> Path:
    return default_profile_path()


@pytest.fixture
def ranged_profile(tmp_path: Path) -> Path:
    """The default profile with ranges for shot noise and alpha, so that --jitter has something to draw."""
    document = json.loads(default_profile_path().read_text())
    document["ranges"] = {"shot": [0.03, 0.09], "alpha": [0.1, 0.3]}
    path = tmp_path / "ranged.json"
    path.write_text(json.dumps(document))
    return path


@pytest.fixture
def coco_dataset(tmp_path: Path) -> Path:
    """COCO layout: annotations/instances_train2017.json beside train2017/, plus a licence file."""
    root = tmp_path / "coco"
    images = []
    for index in range(3):
        name = f"{index:012d}.jpg"
        write_image(root / "train2017" / name, index)
        images.append({"id": index, "file_name": name, "width": WIDTH, "height": HEIGHT})
    document = {
        "images": images,
        "annotations": [{"id": 1, "image_id": 0, "bbox": [1, 2, 10, 20], "category_id": 1}],
        "categories": [{"id": 1, "name": "thing"}],
    }
    (root / "annotations").mkdir()
    (root / "annotations" / "instances_train2017.json").write_text(json.dumps(document))
    (root / "LICENSE").write_text("CC BY 4.0\n")
    return root


@pytest.fixture
def yolo_dataset(tmp_path: Path) -> Path:
    """YOLO layout: images/{train,val}, labels/{train,val}, classes.txt and data.yaml."""
    root = tmp_path / "yolo"
    for split, count in (("train", 3), ("val", 1)):
        for index in range(count):
            write_image(root / "images" / split / f"{split}{index}.jpg", index)
            (root / "labels" / split).mkdir(parents=True, exist_ok=True)
            (root / "labels" / split / f"{split}{index}.txt").write_text(f"0 0.5 0.5 0.2 0.{index + 1}\n")
    (root / "labels" / "classes.txt").write_text("thing\n")
    (root / "data.yaml").write_text(
        "# a YOLO dataset\npath: ../datasets/yolo  # root\ntrain: images/train\nval: images/val\nnames:\n  0: thing\n"
    )
    return root


@pytest.fixture
def folder_dataset(tmp_path: Path) -> Path:
    """Class per folder: cat/*.png, dog/*.jpg and a README."""
    root = tmp_path / "folder"
    for index in range(2):
        write_image(root / "cat" / f"{index}.png", index)
        write_image(root / "dog" / f"{index}.jpg", 10 + index)
    (root / "README.md").write_text("two classes\n")
    return root


@pytest.fixture
def video_dataset(tmp_path: Path) -> Path:
    """A video, DAVIS-style frames (JPEGImages/bear/) and their palette masks (Annotations/bear/)."""
    root = tmp_path / "videos"
    write_video(root / "videos" / "walk.mp4")
    for index in range(3):
        write_image(root / "JPEGImages" / "bear" / f"{index:05d}.jpg", index)
        labels = (np.arange(WIDTH * HEIGHT) % 3).astype(np.uint8)
        mask = Image.frombytes("P", (WIDTH, HEIGHT), labels.tobytes())
        mask.putpalette([0, 0, 0, 200, 0, 0, 0, 200, 0])
        (root / "Annotations" / "bear").mkdir(parents=True, exist_ok=True)
        mask.save(root / "Annotations" / "bear" / f"{index:05d}.png")
    return root
