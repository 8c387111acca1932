"""'darksynth train' in-process: a tiny run writes weights, summary and checkpoint; bad input is one error line."""

from __future__ import annotations

import json
from pathlib import Path

from darksynth.models.den import DENConfig
from darksynth.training.loop import vector_names
from darksynth.training.weights import load_weights
from tests.command_line import run_cli

TINY_FLAGS = ["--steps", "2", "--batch", "2", "--frames", "2", "--crop", "32", "--width", "4", "--depth", "1"]


def test_train_on_a_folder_writes_weights_summary_and_checkpoint(image_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "model" / "den.safetensors"
    out.parent.mkdir()
    code, _, stderr = run_cli("train", image_folder, "--out", out, *TINY_FLAGS, "--validate-every", "1")
    assert code == 0, stderr
    assert f"wrote {out} and {out.with_suffix('.json')} after 2 steps" in stderr
    assert "training on 3 images and 0 clips" in stderr
    assert sorted(p.name for p in out.parent.iterdir()) == ["den.checkpoint.safetensors", "den.json", "den.safetensors"]
    assert load_weights(out).config == DENConfig(width=4, depth=1)
    summary = json.loads(out.with_suffix(".json").read_text())
    assert [entry["step"] for entry in summary["history"]] == [1, 2]
    assert set(summary["final_validation"]["r2"]) == set(vector_names())
    assert summary["config"]["crop"] == 32 and summary["config"]["frames"] == 2


def test_train_resume_continues_to_more_steps(image_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "den.safetensors"
    assert run_cli("train", image_folder, "--out", out, *TINY_FLAGS)[0] == 0
    flags = [*TINY_FLAGS]
    flags[1] = "3"
    code, _, stderr = run_cli("train", image_folder, "--out", out, *flags, "--resume")
    assert code == 0, stderr
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["steps"] == 3
    assert [entry["step"] for entry in summary["history"]] == [2, 3]


def _single_error_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("darksynth: error: ")
    return lines[0]


def test_train_on_images_smaller_than_the_crop_is_one_error_line(image_folder: Path, tmp_path: Path) -> None:
    flags = [*TINY_FLAGS]
    flags[flags.index("--crop") + 1] = "128"
    code, _, stderr = run_cli("train", image_folder, "--out", tmp_path / "den.safetensors", *flags)
    assert code == 1
    assert "no training images or clips" in _single_error_line(stderr)
    assert not (tmp_path / "den.safetensors").exists()


def test_train_resume_without_checkpoint_ends_with_one_error_line(image_folder: Path, tmp_path: Path) -> None:
    code, _, stderr = run_cli("train", image_folder, "--out", tmp_path / "den.safetensors", *TINY_FLAGS, "--resume")
    assert code == 1
    # The corpus is read (and announced) before the checkpoint: the error is the one error line, and the last.
    errors = [line for line in stderr.splitlines() if line.startswith("darksynth: error: ")]
    assert len(errors) == 1
    assert stderr.strip().splitlines()[-1] == errors[0]
    assert errors[0].endswith("den.checkpoint.safetensors: no checkpoint to resume from")


def test_train_with_unknown_variant_is_one_error_line(image_folder: Path, tmp_path: Path) -> None:
    code, _, stderr = run_cli(
        "train", image_folder, "--out", tmp_path / "d.safetensors", *TINY_FLAGS, "--variant", "v9"
    )
    assert code == 1
    assert "--variant must be v2 or v3" in _single_error_line(stderr)
