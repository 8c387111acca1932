"""``darksynth apply`` end to end: outputs, manifests, reproducibility and every kind of bad input."""

from __future__ import annotations

import json
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from darksynth.io.images import Image as ImageData
from darksynth.io.images import read_image, write_image
from darksynth.io.video import VideoWriter, iter_video_frames, probe_video
from darksynth.profile import save_profile
from tests.command_line import run_cli
from tests.conftest import measured_profile


def _pixels(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image)


def test_image_output_and_manifest(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.png"
    code, _, err = run_cli("apply", rgb_image, out, "--profile", profile_file, "--seed", "7")
    assert code == 0, err
    noisy = _pixels(out)
    clean = _pixels(rgb_image)
    assert noisy.shape == clean.shape and noisy.dtype == np.uint8
    # The default profile darkens with alpha 0.2: the output mean is far below the input mean.
    assert noisy.mean() < 0.4 * clean.mean()
    manifest = json.loads((tmp_path / "out.png.manifest.json").read_text())
    assert manifest["seed"] == 7
    (record,) = manifest["files"]
    assert record["parameters"]["darkening"] == {"alpha": 0.2, "gamma": 0.7}
    assert record["parameters"]["noise"]["periodic"] == [0.002, 0.002, 0.002]
    assert isinstance(record["seed"], int)


def test_a_drawn_camera_is_in_the_manifest_with_its_values(rgb_image: Path, tmp_path: Path) -> None:
    outputs = {}
    for name, seed in (("a.png", "5"), ("b.png", "5"), ("c.png", "6")):
        code, _, err = run_cli("apply", rgb_image, tmp_path / name, "--camera", "prior", "--seed", seed)
        assert code == 0, err
        outputs[name] = (tmp_path / name).read_bytes()
    assert outputs["a.png"] == outputs["b.png"] != outputs["c.png"]
    manifest = json.loads((tmp_path / "a.png.manifest.json").read_text())
    assert manifest["camera"] == "prior"
    (record,) = manifest["files"]
    assert record["parameters"]["camera"] == {"source": "prior", "given_profile": False}
    noise = record["parameters"]["noise"]
    assert noise["shot"] == 0.0 and noise["read"] == 0.0 and min(noise["level_curve"]) > 0.0
    # The default profile's darkening and column noise stay.
    assert record["parameters"]["darkening"] == {"alpha": 0.2, "gamma": 0.7}
    assert noise["periodic"] == [0.002, 0.002, 0.002]
    other = json.loads((tmp_path / "c.png.manifest.json").read_text())["files"][0]["parameters"]["noise"]
    assert other["level_curve"] != noise["level_curve"]


def test_a_measured_profile_conditions_the_drawn_camera(rgb_image: Path, tmp_path: Path) -> None:
    profile = measured_profile()
    save_profile(tmp_path / "measured.json", profile)
    code, _, err = run_cli(
        "apply", rgb_image, tmp_path / "out.png", "-p", tmp_path / "measured.json", "--camera", "phone", "--seed", "1"
    )
    assert code == 0, err
    (record,) = json.loads((tmp_path / "out.png.manifest.json").read_text())["files"]
    assert record["parameters"]["camera"] == {"source": "phone", "given_profile": True}
    assert record["parameters"]["noise"]["level_curve"] == profile.noise["level_curve"].tolist()


def test_same_seed_same_bytes_other_seed_differs(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    outputs = []
    for name, seed in (("a.png", "3"), ("b.png", "3"), ("c.png", "4")):
        assert run_cli("apply", rgb_image, tmp_path / name, "-p", profile_file, "--seed", seed)[0] == 0
        outputs.append((tmp_path / name).read_bytes())
    assert outputs[0] == outputs[1]
    assert outputs[0] != outputs[2]


def test_no_darken_keeps_brightness(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.png"
    assert run_cli("apply", rgb_image, out, "-p", profile_file, "--seed", "1", "--no-darken")[0] == 0
    difference = _pixels(out).astype(float) - _pixels(rgb_image).astype(float)
    # Only noise: the mean shift is small next to the 0..255 range (quantization adds q/2 = 0.5 levels).
    assert abs(difference.mean()) < 3.0
    assert difference.std() > 1.0


def test_explicit_alpha_gamma(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.png"
    code, _, err = run_cli("apply", rgb_image, out, "-p", profile_file, "--alpha", "0.5", "--gamma", "1")
    assert code == 0, err
    manifest = json.loads((tmp_path / "out.png.manifest.json").read_text())
    assert manifest["files"][0]["parameters"]["darkening"] == {"alpha": 0.5, "gamma": 1.0}
    ratio = _pixels(out).mean() / _pixels(rgb_image).mean()
    assert 0.45 < ratio < 0.56


def test_ranges_are_sampled_per_file_with_jitter_and_recorded(
    tmp_path: Path, write_profile: Callable[..., Path]
) -> None:
    profile = write_profile(ranges={"shot": [0.01, 0.05], "alpha": [0.1, 0.2]})
    folder = tmp_path / "frames"
    folder.mkdir()
    for index in range(4):
        Image.fromarray(np.full((8, 8, 3), 120, np.uint8)).save(folder / f"{index}.png")
    assert run_cli("apply", folder, tmp_path / "out", "-p", profile, "--seed", "0", "--jitter")[0] == 0
    records = json.loads((tmp_path / "out" / "darksynth-manifest.json").read_text())["files"]
    shots = {r["parameters"]["noise"]["shot"] for r in records}
    alphas = {r["parameters"]["darkening"]["alpha"] for r in records}
    assert len(shots) == 4 and all(0.01 <= s <= 0.05 for s in shots)
    assert len(alphas) == 4 and all(0.1 <= a <= 0.2 for a in alphas)
    # Without --jitter, as in convert: the profile's values for every file, ranges ignored.
    assert run_cli("apply", folder, tmp_path / "fixed", "-p", profile, "--seed", "0")[0] == 0
    fixed = json.loads((tmp_path / "fixed" / "darksynth-manifest.json").read_text())["files"]
    assert {r["parameters"]["noise"]["shot"] for r in fixed} == {0.06}
    assert {r["parameters"]["darkening"]["alpha"] for r in fixed} == {0.2}


def _folder(tmp_path: Path) -> Path:
    root = tmp_path / "dataset"
    rng = np.random.default_rng(1)
    for relative in ("a.png", "sub/b.jpg", "sub/deeper/c.bmp"):
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)).save(path)
    (root / "notes.txt").write_text("not an image")
    return root


def test_folder_mirrors_tree_lists_skipped(tmp_path: Path, profile_file: Path) -> None:
    root = _folder(tmp_path)
    code, _, err = run_cli("apply", root, tmp_path / "out", "-p", profile_file, "--seed", "5")
    assert code == 0, err
    assert "notes.txt" in err
    for relative in ("a.png", "sub/b.jpg", "sub/deeper/c.bmp"):
        assert (tmp_path / "out" / relative).is_file()
    assert not (tmp_path / "out" / "notes.txt").exists()
    manifest = json.loads((tmp_path / "out" / "darksynth-manifest.json").read_text())
    assert manifest["skipped"] == ["notes.txt"]
    assert [r["input"] for r in manifest["files"]] == ["a.png", "sub/b.jpg", "sub/deeper/c.bmp"]


def test_workers_do_not_change_outputs(tmp_path: Path, profile_file: Path) -> None:
    root = _folder(tmp_path)
    assert run_cli("apply", root, tmp_path / "one", "-p", profile_file, "--seed", "9")[0] == 0
    assert run_cli("apply", root, tmp_path / "two", "-p", profile_file, "--seed", "9", "--workers", "2")[0] == 0
    for relative in ("a.png", "sub/b.jpg", "sub/deeper/c.bmp"):
        assert (tmp_path / "one" / relative).read_bytes() == (tmp_path / "two" / relative).read_bytes()


def test_file_seed_does_not_depend_on_folder_neighbours(tmp_path: Path, profile_file: Path) -> None:
    root = _folder(tmp_path)
    assert run_cli("apply", root, tmp_path / "all", "-p", profile_file, "--seed", "2")[0] == 0
    (root / "sub" / "b.jpg").unlink()
    assert run_cli("apply", root, tmp_path / "fewer", "-p", profile_file, "--seed", "2")[0] == 0
    assert (tmp_path / "all" / "a.png").read_bytes() == (tmp_path / "fewer" / "a.png").read_bytes()


def test_clip_shares_temporal_banding(tmp_path: Path, write_profile: Callable[..., Path]) -> None:
    zero = {"shot": 0, "read": 0, "quantization": 0, "banding": 0, "periodic": [0, 0, 0]}
    profile = write_profile(noise={**zero, "temporal_banding": 0.05}, darkening=None)
    frames = tmp_path / "clip"
    frames.mkdir()
    for index in range(5):
        Image.fromarray(np.full((6, 40, 3), 128, np.uint8)).save(frames / f"{index:02d}.png")
    assert run_cli("apply", frames, tmp_path / "shared", "-p", profile, "--no-darken", "--clip")[0] == 0
    shared = [_pixels(tmp_path / "shared" / f"{i:02d}.png") for i in range(5)]
    assert all(np.array_equal(shared[0], frame) for frame in shared[1:])
    assert shared[0].std() > 3  # the banding is there: sigma 0.05 is about 13 levels
    assert run_cli("apply", frames, tmp_path / "separate", "-p", profile, "--no-darken")[0] == 0
    separate = [_pixels(tmp_path / "separate" / f"{i:02d}.png") for i in range(5)]
    assert not np.array_equal(separate[0], separate[1])


def test_a_clip_whose_frames_change_size_goes_on_with_one_warning(
    tmp_path: Path, write_profile: Callable[..., Path], caplog: pytest.LogCaptureFixture
) -> None:
    zero = {"shot": 0, "read": 0, "quantization": 0, "banding": 0, "periodic": [0, 0, 0]}
    profile = write_profile(noise={**zero, "temporal_banding": 0.05}, darkening=None)
    frames = tmp_path / "clip"
    frames.mkdir()
    for index, width in enumerate((40, 40, 56, 56)):
        Image.fromarray(np.full((6, width, 3), 128, np.uint8)).save(frames / f"{index:02d}.png")
    code, _, err = run_cli("apply", frames, tmp_path / "out", "-p", profile, "--no-darken", "--clip")
    assert code == 0, err
    out = [_pixels(tmp_path / "out" / f"{i:02d}.png") for i in range(4)]
    assert [frame.shape[1] for frame in out] == [40, 40, 56, 56]
    # Each size keeps one held pattern: equal frames within a size, banding present at both.
    assert np.array_equal(out[0], out[1]) and np.array_equal(out[2], out[3])
    assert out[0].std() > 3 and out[2].std() > 3
    # The warning is logged, and the command line prints it as its own warning line.
    warnings = [r.getMessage() for r in caplog.records if "frame size changed" in r.getMessage()]
    assert len(warnings) == 1 and "3x6x40 to 3x6x56 at frame 2" in warnings[0]
    assert warnings[0].startswith(f"{frames}: ")
    assert f"darksynth: warning: {warnings[0]}" in err.splitlines()


def test_video_keeps_frames_and_rate(tmp_path: Path, profile_file: Path) -> None:
    source = tmp_path / "clean.mp4"
    with VideoWriter(source, width=48, height=32, fps=Fraction(30000, 1001)) as writer:
        for index in range(6):
            writer.write(np.full((32, 48, 3), 40 * index, np.uint8))
    out = tmp_path / "dark.mkv"
    code, _, err = run_cli("apply", source, out, "-p", profile_file, "--seed", "0", "--codec", "ffv1")
    assert code == 0, err
    info = probe_video(out)
    assert (info.width, info.height, info.fps) == (48, 32, Fraction(30000, 1001))
    frames = list(iter_video_frames(out))
    assert len(frames) == 6
    assert frames[-1].mean() < 0.4 * 200  # darkened


def test_image_kinds(tmp_path: Path, profile_file: Path) -> None:
    folder = tmp_path / "kinds"
    folder.mkdir()
    Image.fromarray(np.full((5, 7), 30000, np.uint16)).save(folder / "deep.png")
    Image.fromarray(np.zeros((1, 1, 3), np.uint8)).save(folder / "tiny.png")
    rgba = np.dstack([np.full((4, 4, 3), 200, np.uint8), np.arange(16, dtype=np.uint8).reshape(4, 4) * 15])
    Image.fromarray(rgba, "RGBA").save(folder / "alpha.png")
    Image.fromarray(np.full((4, 4, 3), 90, np.uint8)).convert("P").save(folder / "palette.png")
    code, _, err = run_cli("apply", folder, tmp_path / "out", "-p", profile_file, "--seed", "0")
    assert code == 0, err
    with Image.open(tmp_path / "out" / "deep.png") as deep:
        assert deep.mode.startswith("I") and np.asarray(deep).max() > 255  # still 16 bit, darkened
    assert _pixels(tmp_path / "out" / "tiny.png").shape == (1, 1, 3)
    alpha_out = _pixels(tmp_path / "out" / "alpha.png")
    assert np.array_equal(alpha_out[..., 3], rgba[..., 3])
    assert _pixels(tmp_path / "out" / "palette.png").shape == (4, 4, 3)


def _assert_one_line_error(code: int, err: str, *needles: str, only_line: bool = True) -> None:
    assert code == 1
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert lines and lines[-1].startswith("darksynth: error:"), err
    if only_line:
        assert len(lines) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, (needle, err)


def test_bad_image_inputs(tmp_path: Path, profile_file: Path) -> None:
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"\x00not an image at all" * 10)
    text = tmp_path / "text.jpg"
    text.write_text("hello")
    valid = tmp_path / "valid.png"
    Image.fromarray(np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)).save(valid)
    truncated = tmp_path / "truncated.png"
    truncated.write_bytes(valid.read_bytes()[: valid.stat().st_size // 2])
    for source in (garbage, text, truncated):
        out = tmp_path / f"out-{source.name}"
        code, _, err = run_cli("apply", source, out, "-p", profile_file)
        _assert_one_line_error(code, err, source.name)
        assert not out.exists()
        assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name or p.name.endswith(".manifest.json")]


def test_bad_folder_entry_is_reported_and_rest_converted(tmp_path: Path, profile_file: Path) -> None:
    root = _folder(tmp_path)
    (root / "broken.png").write_bytes(b"broken")
    code, _, err = run_cli("apply", root, tmp_path / "out", "-p", profile_file)
    _assert_one_line_error(code, err, "broken.png", only_line=False)
    assert next(line for line in err.splitlines() if "broken.png" in line).startswith("darksynth: error:")
    assert (tmp_path / "out" / "a.png").is_file()
    assert not (tmp_path / "out" / "broken.png").exists()
    manifest = json.loads((tmp_path / "out" / "darksynth-manifest.json").read_text())
    assert len(manifest["failures"]) == 1 and "broken.png" in manifest["failures"][0]


def test_bad_paths(tmp_path: Path, profile_file: Path, rgb_image: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    unreadable_video = tmp_path / "movie.mp4"
    unreadable_video.write_bytes(b"\x00" * 1000)
    cases = [
        (("apply", tmp_path / "missing.png", tmp_path / "o.png", "-p", profile_file), "missing.png"),
        (("apply", empty, tmp_path / "o", "-p", profile_file), "empty"),
        (("apply", unreadable_video, tmp_path / "o.mp4", "-p", profile_file), "movie.mp4"),
        (("apply", rgb_image, rgb_image, "-p", profile_file), "photo.png"),
        (("apply", rgb_image.parent, rgb_image.parent / "sub", "-p", profile_file), "sub"),
        (("apply", rgb_image, tmp_path / "o.png", "-p", tmp_path / "nope.json"), "nope.json"),
        (("apply", rgb_image, tmp_path / "o.png", "-p", profile_file, "--alpha", "0.2"), "--gamma"),
        (("apply", rgb_image, tmp_path / "o.png", "-p", profile_file, "--alpha", "2", "--gamma", "1"), "--alpha"),
        (("apply", rgb_image, tmp_path / "o.png", "-p", profile_file, "--no-darken", "--alpha", "0.2"), "--no-darken"),
        (("apply", rgb_image, tmp_path / "o.mp4", "-p", profile_file), "o.mp4"),
        (("apply", rgb_image, tmp_path / "o", "-p", profile_file), "suffixes"),
        (("apply", unreadable_video.with_name("empty.mp4"), tmp_path / "o.mkv", "-p", profile_file), "empty.mp4"),
    ]
    (tmp_path / "empty.mp4").write_bytes(b"")
    before = sorted(p.name for p in rgb_image.parent.iterdir())
    for arguments, needle in cases:
        code, _, err = run_cli(*arguments)
        _assert_one_line_error(code, err, needle)
    assert sorted(p.name for p in rgb_image.parent.iterdir()) == before  # nothing written into the input
    assert not [p for p in tmp_path.iterdir() if p.name.startswith("o.") or p.name == "o"]


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"noise": {"read": None}}, "noise.read"),
        ({"noise": {"shot": -0.1}}, "noise.shot"),
        ({"version": 7}, "version"),
        ({"noise": {"periodic": [0.1, 0.1]}}, "noise.periodic"),
    ],
)
def test_bad_profiles(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path], change: dict[str, object], needle: str
) -> None:
    noise = change.pop("noise", None)
    path = write_profile(noise=noise, **change)  # type: ignore[arg-type]
    if noise and None in noise.values():
        document = json.loads(path.read_text())
        document["noise"] = {k: v for k, v in document["noise"].items() if v is not None}
        path.write_text(json.dumps(document))
    code, _, err = run_cli("apply", rgb_image, tmp_path / "o.png", "-p", path)
    _assert_one_line_error(code, err, needle, path.name)
    assert not (tmp_path / "o.png").exists()


def test_nan_profile(rgb_image: Path, tmp_path: Path) -> None:
    path = tmp_path / "nan.json"
    path.write_text(
        '{"format": "darksynth-profile", "version": 1, "noise": {"shot": NaN, "read": 0, "quantization": 0,'
        ' "banding": 0, "temporal_banding": 0, "periodic": [0, 0, 0]}}'
    )
    code, _, err = run_cli("apply", rgb_image, tmp_path / "o.png", "-p", path)
    _assert_one_line_error(code, err, "noise.shot", "nan.json")


@pytest.mark.slow
def test_compiled_and_eager_runs_write_the_same_bytes(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    for name, flag in (("eager.png", "--no-compile"), ("compiled.png", "--compile")):
        code, _, err = run_cli("apply", rgb_image, tmp_path / name, "-p", profile_file, "--seed", "11", flag)
        assert code == 0, err
    assert (tmp_path / "eager.png").read_bytes() == (tmp_path / "compiled.png").read_bytes()


def test_srgb_profile_applies_to_every_image_kind(tmp_path: Path, write_profile: Callable[..., Path]) -> None:
    """A version-2 profile with the sRGB structure and JPEG works on 8/16-bit, grey, RGBA, palette and 1x1."""
    profile = write_profile(
        noise={
            "read": 0.03,
            "channel_gain": [1.4, 1.2],
            "correlation_length": 1.0,
            "channel_correlation": [0.5, 0.4, 0.6],
            "compression": 0.4,
        },
        version=2,
    )
    folder = tmp_path / "kinds"
    folder.mkdir()
    Image.fromarray(np.full((40, 48), 30000, np.uint16)).save(folder / "deep.png")
    deep_rgb = np.random.default_rng(0).integers(0, 65536, (40, 48, 3)).astype(np.uint16)
    for name in ("deep_rgb.png", "deep_rgb.tif"):
        write_image(folder / name, ImageData(deep_rgb, None, 16, "RGB"))
    Image.fromarray(np.full((40, 48), 120, np.uint8)).save(folder / "grey.png")
    Image.fromarray(np.zeros((1, 1, 3), np.uint8)).save(folder / "tiny.png")
    rgba = np.dstack([np.full((32, 32, 3), 200, np.uint8), np.arange(1024, dtype=np.uint8).reshape(32, 32)])
    Image.fromarray(rgba, "RGBA").save(folder / "alpha.png")
    Image.fromarray(np.full((32, 32, 3), 90, np.uint8)).convert("P").save(folder / "palette.png")
    Image.fromarray(np.full((64, 64, 3), 128, np.uint8)).save(folder / "colour.png")
    code, _, err = run_cli("apply", folder, tmp_path / "out", "-p", profile, "--seed", "0")
    assert code == 0, err
    with Image.open(tmp_path / "out" / "deep.png") as deep:
        values = np.asarray(deep)
        # Still 16 bit; the JPEG stage leaves it on 8-bit levels scaled to 16 bits.
        assert deep.mode.startswith("I") and values.max() > 255
        assert np.all(values % 257 == 0)
    for name in ("deep_rgb.png", "deep_rgb.tif"):
        written = read_image(tmp_path / "out" / name)
        assert written.bit_depth == 16 and written.pixels.shape == (40, 48, 3), name
        assert np.all(written.pixels % 257 == 0), name
    assert _pixels(tmp_path / "out" / "grey.png").ndim == 2
    assert _pixels(tmp_path / "out" / "tiny.png").shape == (1, 1, 3)
    assert np.array_equal(_pixels(tmp_path / "out" / "alpha.png")[..., 3], rgba[..., 3])
    colour = _pixels(tmp_path / "out" / "colour.png").astype(np.float64)
    residual = colour - colour.mean(axis=(0, 1))
    # Correlated across channels, as the profile asks (JPEG's chroma subsampling only adds to it).
    assert np.corrcoef(residual.reshape(-1, 3).T)[0, 1] > 0.3


def test_existing_outputs_are_refused_unless_overwrite(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    """apply's policy is convert's: nothing that exists before the run is replaced without --overwrite."""
    out = tmp_path / "out.png"
    assert run_cli("apply", rgb_image, out, "-p", profile_file, "--seed", "1")[0] == 0
    first = out.read_bytes()
    code, _, err = run_cli("apply", rgb_image, out, "-p", profile_file, "--seed", "2")
    _assert_one_line_error(code, err, "out.png: exists", "--overwrite")
    assert out.read_bytes() == first
    assert run_cli("apply", rgb_image, out, "-p", profile_file, "--seed", "2", "--overwrite")[0] == 0
    assert out.read_bytes() != first

    root = _folder(tmp_path)
    assert run_cli("apply", root, tmp_path / "tree", "-p", profile_file, "--seed", "1")[0] == 0
    (tmp_path / "tree" / "sub" / "b.jpg").unlink()  # one output missing, two and the manifest still there
    before = {p: p.read_bytes() for p in (tmp_path / "tree").rglob("*") if p.is_file()}
    code, _, err = run_cli("apply", root, tmp_path / "tree", "-p", profile_file, "--seed", "2")
    # The folder holds an earlier run's state: the rerun with another seed is refused, naming it.
    _assert_one_line_error(code, err, "holds an apply run made with other options (seed)", "--overwrite")
    assert {p: p.read_bytes() for p in (tmp_path / "tree").rglob("*") if p.is_file()} == before
    # Files that no darksynth run wrote are refused as before.
    (tmp_path / "other" / "sub").mkdir(parents=True)
    (tmp_path / "other" / "a.png").write_bytes(b"someone else's file")
    code, _, err = run_cli("apply", root, tmp_path / "other", "-p", profile_file, "--seed", "2")
    _assert_one_line_error(code, err, "a.png: exists", "--overwrite")
    assert (tmp_path / "other" / "a.png").read_bytes() == b"someone else's file"


def _tree(root: Path) -> dict[str, bytes]:
    return {
        p.relative_to(root).as_posix(): p.read_bytes()
        for p in root.rglob("*")
        if p.is_file() and ".darksynth" not in p.parts and p.name != "darksynth-manifest.json"
    }


def test_a_killed_folder_run_resumes_to_the_same_bytes(tmp_path: Path, profile_file: Path) -> None:
    """What a kill leaves: finished files with their records, one file written without its record, one not
    written, no manifest. The rerun keeps the finished ones, redoes the rest, and equals an uninterrupted run."""
    root = _folder(tmp_path)
    full, resumed = tmp_path / "full", tmp_path / "resumed"
    assert run_cli("apply", root, full, "-p", profile_file, "--seed", "5")[0] == 0
    assert run_cli("apply", root, resumed, "-p", profile_file, "--seed", "5")[0] == 0
    records = sorted((resumed / ".darksynth" / "apply-records").iterdir())
    assert len(records) == 3
    (resumed / "darksynth-manifest.json").unlink()
    # Which record is whose does not matter here: drop one record and one other task's output with its record.
    manifest = json.loads((full / "darksynth-manifest.json").read_text())
    by_key = {r["input"]: r for r in manifest["files"]}
    assert len(by_key) == 3
    (resumed / "sub" / "b.jpg").write_bytes(b"stale bytes of a killed run")
    for record in records:
        if json.loads(record.read_text())["input"] in ("sub/b.jpg", "sub/deeper/c.bmp"):
            record.unlink()
    (resumed / "sub" / "deeper" / "c.bmp").unlink()
    code, _, err = run_cli("apply", root, resumed, "-p", profile_file, "--seed", "5")
    assert code == 0, err
    assert "wrote 3 file(s) (2 new, 1 already done)" in err
    assert _tree(resumed) == _tree(full)
    again = json.loads((resumed / "darksynth-manifest.json").read_text())
    assert sorted(r["input"] for r in again["files"]) == sorted(by_key)
    # Finished: a rerun has nothing to do; with workers (no byte changes) too.
    code, _, err = run_cli("apply", root, resumed, "-p", profile_file, "--seed", "5", "--workers", "2")
    assert code == 0 and "(0 new, 3 already done)" in err, err


def test_an_unwritable_output_is_refused_once_before_any_work(tmp_path: Path, profile_file: Path) -> None:
    root = _folder(tmp_path)
    blocker = tmp_path / "a-file"
    blocker.write_text("a file where the output folder should go")
    code, _, err = run_cli("apply", root, blocker / "out", "-p", profile_file)
    _assert_one_line_error(code, err, "a-file", "cannot write the output here")
    assert blocker.read_text() == "a file where the output folder should go"


def test_a_killed_runs_temporary_file_is_removed_by_the_next_run(tmp_path: Path, profile_file: Path) -> None:
    source = tmp_path / "clean.mp4"
    with VideoWriter(source, width=48, height=32, fps=Fraction(25)) as writer:
        for index in range(3):
            writer.write(np.full((32, 48, 3), 60 * index, np.uint8))
    out = tmp_path / "out"
    out.mkdir()
    left = out / ".dark.tmp-0123456789ab.mp4"  # what a SIGKILL in the middle of the video leaves
    left.write_bytes(b"half a video")
    other = out / ".other.tmp-0123456789ab.mp4"  # another output's: perhaps a run still going
    other.write_bytes(b"someone else's")
    code, _, err = run_cli("apply", source, out / "dark.mp4", "-p", profile_file, "--seed", "0")
    assert code == 0, err
    assert not left.exists() and other.exists()
    assert sorted(p.name for p in out.iterdir()) == [
        ".other.tmp-0123456789ab.mp4",
        "dark.mp4",
        "dark.mp4.manifest.json",
    ]
