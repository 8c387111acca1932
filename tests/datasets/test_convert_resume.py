"""Resume after SIGKILL, shards and workers: whatever the interruptions and the split, the same bytes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from darksynth.apply_outputs import STATE_FOLDER
from darksynth.datasets import MANIFEST_NAME, ConvertOptions, Shard, convert_dataset, shard_of
from darksynth.profile import load_profile
from darksynth.recipe import ClipRecipe
from tests.datasets.conftest import tree_bytes, write_image

IMAGES = 40


def _dataset(root: Path) -> Path:
    for index in range(IMAGES):
        suffix = "jpg" if index % 2 else "png"
        write_image(root / f"class{index % 4}" / f"{index:03d}.{suffix}", index, size=(128, 96))
    (root / "README").write_text("forty images\n")
    return root


@pytest.mark.slow
def test_killed_run_resumes_to_the_same_bytes(tmp_path: Path, profile_path: Path) -> None:
    """The acceptance test of the issue: SIGKILL mid-way, rerun, compare every byte with an uninterrupted run."""
    dataset = _dataset(tmp_path / "ds")
    resumed, full = tmp_path / "resumed", tmp_path / "full"
    command = [sys.executable, "-m", "darksynth", "convert", str(dataset), str(resumed)]
    command += ["--profile", str(profile_path), "--format", "folder", "--seed", "3", "--jitter", "--workers", "1"]
    records = resumed / STATE_FOLDER / "records"
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=Path.cwd())
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and process.poll() is None:
            if records.is_dir() and len([n for n in os.listdir(records) if not n.startswith(".")]) >= 3:
                break
            time.sleep(0.005)
        process.send_signal(signal.SIGKILL)
    finally:
        process.communicate()
    done_before = len([n for n in os.listdir(records) if not n.startswith(".")])
    assert process.returncode == -signal.SIGKILL
    assert 3 <= done_before < IMAGES, "the run should have been killed mid-way"
    assert not (resumed / MANIFEST_NAME).exists()
    # What a kill in the middle of a write leaves (the kill above may or may not have hit one).
    (resumed / "class1").mkdir(exist_ok=True)
    (resumed / "class1" / ".001.tmp-0123456789ab.jpg").write_bytes(b"half a jpeg")

    rerun = subprocess.run(command, capture_output=True, text=True, check=False)
    assert rerun.returncode == 0, rerun.stderr
    assert f"({IMAGES - done_before} new, {done_before} already done)" in rerun.stderr

    report = convert_dataset(
        ConvertOptions(dataset, full, ClipRecipe(load_profile(profile_path), jitter=True), "folder", seed=3)
    )
    assert report.converted == IMAGES
    resumed_tree, full_tree = tree_bytes(resumed), tree_bytes(full)
    assert not [name for name in resumed_tree if ".tmp-" in name]
    assert sorted(resumed_tree) == sorted(full_tree)
    assert [name for name in full_tree if resumed_tree[name] != full_tree[name]] == []


@pytest.mark.slow
def test_shards_partition_and_together_equal_a_full_run(coco_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    for index in range(3, 8):
        write_image(coco_dataset / "train2017" / f"extra{index}.png", index)
    sharded, full = tmp_path / "sharded", tmp_path / "full"
    first = convert_dataset(
        ConvertOptions(
            coco_dataset, sharded, ClipRecipe(load_profile(profile_path)), "coco", shard=Shard(1, 2), workers=2
        )
    )
    assert first.manifest is None and first.pending > 0 and first.other_shards == first.pending
    second = convert_dataset(
        ConvertOptions(coco_dataset, sharded, ClipRecipe(load_profile(profile_path)), "coco", shard=Shard(2, 2))
    )
    assert second.manifest == (sharded / MANIFEST_NAME).resolve()
    assert first.converted + second.converted == 8 and first.converted > 0 and second.converted > 0
    assert second.already_done == 0  # no item was done twice
    convert_dataset(ConvertOptions(coco_dataset, full, ClipRecipe(load_profile(profile_path)), "coco"))
    assert tree_bytes(sharded) == tree_bytes(full)


def test_rerun_of_a_complete_run_converts_nothing(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    convert_dataset(ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(profile_path)), "folder"))
    before = tree_bytes(output)
    again = convert_dataset(ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(profile_path)), "folder"))
    assert (again.converted, again.already_done, again.carried) == (0, 4, 0)
    assert tree_bytes(output) == before


def test_deleted_output_is_converted_again(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    convert_dataset(ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(profile_path)), "folder"))
    before = tree_bytes(output)
    (output / "dog" / "1.jpg").unlink()
    again = convert_dataset(ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(profile_path)), "folder"))
    assert (again.converted, again.already_done) == (1, 3)
    assert tree_bytes(output) == before


def test_shard_assignment_is_stable_and_balanced() -> None:
    keys = [f"train/{index:06d}.jpg" for index in range(2000)]
    counts = [0, 0, 0, 0]
    for key in keys:
        counts[shard_of(key, 4) - 1] += 1
    assert all(430 <= count <= 570 for count in counts), counts
    # Depends on the key only: the same answer whatever other files exist.
    assert [shard_of(k, 4) for k in keys[:50]] == [shard_of(k, 4) for k in sorted(keys[:50], reverse=True)][::-1]
