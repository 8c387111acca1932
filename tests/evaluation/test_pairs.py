"""Listing and reading sets of real pairs; every bad pair is reported and skipped, never fatal."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from darksynth.errors import DarksynthError
from darksynth.evaluation.pairs import UNKNOWN_CAMERA, list_pair_set, load_pair
from tests.evaluation.conftest import MakeSet


def test_a_set_lists_its_pairs_with_cameras(make_pair_set: MakeSet) -> None:
    pair_set = list_pair_set(make_pair_set("polyu-like", count=3))
    assert pair_set.name == "polyu-like"
    assert [p.name for p in pair_set.pairs] == ["pair_0.png", "pair_1.png", "pair_2.png"]
    assert [p.camera for p in pair_set.pairs] == ["camA", "camB", "camA"]
    assert pair_set.pairs[1].iso == "1600"
    assert pair_set.problems == []


def test_loaded_pair_gives_the_real_noise(make_pair_set: MakeSet) -> None:
    loaded = load_pair(list_pair_set(make_pair_set(sigma=8.0, size=128)).pairs[0])
    assert loaded.noisy.shape == loaded.clean.shape == (3, 128, 160)
    assert float(loaded.noise.std()) * 255 == pytest.approx(8.0, rel=0.05)


def test_missing_partners_and_stray_files_are_reported_and_skipped(make_pair_set: MakeSet) -> None:
    root = make_pair_set(count=3)
    (root / "clean" / "pair_1.png").unlink()
    (root / "noisy" / "pair_2.png").unlink()
    (root / "noisy" / "notes.txt").write_text("not an image")
    (root / "noisy" / "sub").mkdir()
    pair_set = list_pair_set(root)
    assert [p.name for p in pair_set.pairs] == ["pair_0.png"]
    problems = "\n".join(pair_set.problems)
    assert "pair_1.png: no clean partner" in problems
    assert "pair_2.png: no noisy partner" in problems
    assert "notes.txt: not an image file" in problems
    assert "sub: a folder" in problems


def test_without_cameras_csv_the_camera_is_unknown(make_pair_set: MakeSet) -> None:
    root = make_pair_set(count=1)
    (root / "cameras.csv").unlink()
    assert list_pair_set(root).pairs[0].camera == UNKNOWN_CAMERA


def test_mismatched_sizes_name_the_file(make_pair_set: MakeSet) -> None:
    root = make_pair_set(count=1)
    Image.fromarray(np.zeros((10, 12, 3), np.uint8)).save(root / "clean" / "pair_0.png")
    with pytest.raises(DarksynthError, match=r"pair_0\.png: size 128x96 differs from its clean partner's 12x10"):
        load_pair(list_pair_set(root).pairs[0])


def test_a_corrupt_image_names_the_file(make_pair_set: MakeSet) -> None:
    root = make_pair_set(count=1)
    (root / "noisy" / "pair_0.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(DarksynthError, match=r"noisy/pair_0\.png"):
        load_pair(list_pair_set(root).pairs[0])


def test_a_folder_without_noisy_and_clean_is_refused(tmp_path: Path) -> None:
    with pytest.raises(DarksynthError, match="needs noisy/ and clean/"):
        list_pair_set(tmp_path)
    with pytest.raises(DarksynthError, match="no such folder"):
        list_pair_set(tmp_path / "absent")
