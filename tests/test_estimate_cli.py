"""'darksynth estimate' in-process: a valid profile on stdout or in --out; every failure one error line."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import save_file

from darksynth.models.den import DEN, DENConfig
from darksynth.noise.level import mean_noise_variance
from darksynth.profile import load_profile, parse_profile
from darksynth.training.weights import save_weights
from tests.clean_images import smooth_rgb, write_png
from tests.command_line import run_cli


@pytest.fixture
def weights(tmp_path: Path, tiny_model: Callable[..., DEN]) -> Path:
    path = tmp_path / "den.safetensors"
    save_weights(path, tiny_model())
    return path


@pytest.fixture
def dark_image(tmp_path: Path) -> Path:
    return write_png(tmp_path / "dark.png", smooth_rgb(96, 96) // 8)


def _single_error_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("darksynth: error: ")
    return lines[0]


def test_estimate_prints_a_valid_profile_to_stdout(dark_image: Path, weights: Path) -> None:
    code, stdout, stderr = run_cli("estimate", dark_image, "--weights", weights)
    assert code == 0, stderr
    profile = parse_profile(json.loads(stdout), source="stdout")
    assert profile.meta["source"] == str(dark_image)
    assert profile.meta["frames"] == 1
    assert "width 4 depth 1" in str(profile.meta["estimator"])
    assert "darksynth: error" not in stderr


def test_estimate_out_writes_the_same_profile(dark_image: Path, weights: Path, tmp_path: Path) -> None:
    out = tmp_path / "profiles" / "estimated.json"
    out.parent.mkdir()
    code, stdout, stderr = run_cli("estimate", dark_image, "--weights", weights, "--out", out)
    assert code == 0, stderr
    assert stdout == ""
    assert f"wrote {out} from 1 crops" in stderr
    written = load_profile(out)
    _, printed, _ = run_cli("estimate", dark_image, "--weights", weights)
    assert written.noise == parse_profile(json.loads(printed)).noise


def test_estimate_of_a_frame_folder_with_clip(tmp_path: Path, weights: Path) -> None:
    for index in range(5):
        write_png(tmp_path / "frames" / f"{index}.png", smooth_rgb(64, 64, phase=index) // 8)
    code, stdout, stderr = run_cli("estimate", tmp_path / "frames", "--clip", "--weights", weights)
    assert code == 0, stderr
    profile = parse_profile(json.loads(stdout))
    assert profile.meta["frames"] == 5
    assert "note" not in profile.meta


def test_bright_reference_warns_on_stderr_and_still_succeeds(tmp_path: Path, weights: Path) -> None:
    bright = write_png(tmp_path / "bright.png", (200 + smooth_rgb(64, 64) // 8).astype("uint8"))
    code, stdout, stderr = run_cli("estimate", bright, "--weights", weights)
    assert code == 0
    parse_profile(json.loads(stdout))
    assert any(line.startswith("darksynth: warning: ") and "bright" in line for line in stderr.splitlines())


def test_missing_reference_is_one_error_line(tmp_path: Path, weights: Path) -> None:
    missing = tmp_path / "absent.png"
    code, stdout, stderr = run_cli("estimate", missing, "--weights", weights)
    assert code == 1
    assert stdout == ""
    assert _single_error_line(stderr) == f"darksynth: error: {missing}: no such file or folder"


@pytest.mark.parametrize("damage", ["garbage", "truncated", "missing"])
def test_unusable_weights_are_one_error_line(dark_image: Path, weights: Path, tmp_path: Path, damage: str) -> None:
    bad = tmp_path / f"{damage}.safetensors"
    if damage == "garbage":
        bad.write_bytes(b"not weights " * 50)
    elif damage == "truncated":
        bad.write_bytes(weights.read_bytes()[:-64])
    code, stdout, stderr = run_cli("estimate", dark_image, "--weights", bad)
    assert code == 1
    assert stdout == ""
    assert _single_error_line(stderr).startswith(f"darksynth: error: {bad}: ")


def test_weights_of_another_shape_are_one_error_line(
    dark_image: Path, tiny_model: Callable[..., DEN], tmp_path: Path
) -> None:
    bad = tmp_path / "mismatch.safetensors"
    tensors = {name: t.contiguous() for name, t in tiny_model().state_dict().items()}
    config = json.dumps(DENConfig(width=8, depth=1).to_dict())
    save_file(tensors, str(bad), metadata={"model": "darksynth-den", "version": "1", "config": config})
    code, _, stderr = run_cli("estimate", dark_image, "--weights", bad)
    assert code == 1
    _single_error_line(stderr)


def test_folder_without_clip_is_one_error_line(tmp_path: Path, weights: Path) -> None:
    for index in range(2):
        write_png(tmp_path / "frames" / f"{index}.png", smooth_rgb(64, 64))
    code, stdout, stderr = run_cli("estimate", tmp_path / "frames", "--weights", weights)
    assert code == 1
    assert stdout == ""
    assert "add --clip" in _single_error_line(stderr)


def test_too_small_reference_is_one_error_line(tmp_path: Path, weights: Path) -> None:
    small = write_png(tmp_path / "small.png", smooth_rgb(20, 20))
    code, _, stderr = run_cli("estimate", small, "--weights", weights)
    assert code == 1
    assert "smaller than the estimator's minimum" in _single_error_line(stderr)


def test_variant_picks_the_shipped_v2_ablation(dark_image: Path) -> None:
    code, stdout, stderr = run_cli("estimate", dark_image, "--model", "paper", "--variant", "v2")
    assert code == 0, stderr
    assert json.loads(stdout)["meta"]["estimator"].startswith("DEN v2")
    assert json.loads(stdout)["meta"]["noise_model"] == "paper"


def test_paper_model_gives_white_uncompressed_noise(dark_image: Path) -> None:
    code, stdout, stderr = run_cli("estimate", dark_image, "--model", "paper")
    assert code == 0, stderr
    profile = json.loads(stdout)
    assert profile["meta"]["noise_model"] == "paper"
    noise = profile["noise"]
    assert noise["correlation_length"] == 0.0 and noise["compression"] == 0.0
    assert noise["channel_gain"] == [1.0, 1.0]
    # The paper's network estimates its own eight values (a range each) and nothing of the sRGB structure; this
    # smooth image has no column pattern, so the column components are set absent and lose their ranges.
    assert set(profile["ranges"]) == {"shot", "read", "quantization"}
    assert profile["meta"]["columns"]["set_absent"] == ["banding", "temporal_banding", "periodic"]
    assert noise["read"] > 0


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (("--model", "fancy"), "darksynth: error: --model must be paper or srgb, got 'fancy'"),
        (
            ("--model", "srgb", "--variant", "v2"),
            "darksynth: error: no shipped DEN for noise model 'srgb' and variant 'v2'; "
            "shipped: srgb v3, paper v3, paper v2",
        ),
    ],
)
def test_unknown_model_or_unshipped_combination_is_one_error_line(
    dark_image: Path, arguments: tuple[str, ...], message: str
) -> None:
    code, _, stderr = run_cli("estimate", dark_image, *arguments)
    assert code == 1
    assert stderr.strip() == message


def test_unknown_variant_is_one_error_line(dark_image: Path) -> None:
    code, _, stderr = run_cli("estimate", dark_image, "--variant", "v1")
    assert code == 1
    assert stderr.strip() == "darksynth: error: --variant must be v2 or v3, got 'v1'"


def test_refine_brings_the_shipped_networks_level_to_the_reference(tmp_path: Path) -> None:
    """The measured spectrum (the default) runs after the network and says so in the profile's meta; --no-refine
    keeps the network's values; --no-spectrum, the retired version-3 refinement, is gone."""
    clean = smooth_rgb(160, 160).astype(float) / 4
    noisy = clean + np.random.default_rng(0).normal(0, 6, clean.shape)
    path = write_png(tmp_path / "noisy.png", np.clip(noisy, 0, 255).round().astype(np.uint8))
    reference = torch.from_numpy(clean / 255).permute(2, 0, 1)[None, None]
    levels = {}
    records = {("--no-refine",): None, ("--refine",): "spectrum"}
    for flags, record in records.items():
        code, stdout, stderr = run_cli("estimate", path, *flags)
        assert code == 0, stderr
        profile = parse_profile(json.loads(stdout))
        assert [key for key in ("refined", "spectrum") if key in profile.meta] == ([record] if record else [])
        batched = profile.noise.map(lambda t: t[None])
        levels[flags] = float(mean_noise_variance(batched, reference).sqrt()) * 255
    # White noise of std 6 levels: the measured profile adds noise of that std within 15%.
    assert abs(levels[("--refine",)] / 6 - 1) < 0.15, levels
    code, _, stderr = run_cli("estimate", path, "--no-spectrum")
    assert code == 2 and "No such option: --no-spectrum" in stderr
