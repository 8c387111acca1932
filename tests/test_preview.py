"""``darksynth preview``: the sheet's layout, its noisy panel against ``apply``, the reference panel and its
brightening, the output policy and bad inputs."""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.estimation.reference import load_reference
from darksynth.io.video import VideoEncoding, VideoWriter
from darksynth.light.darkening import Darkening
from darksynth.models.den import DEN
from darksynth.preview import (
    LABEL_HEIGHT,
    brighten,
    centre_crop,
    darkened_pixels,
    display_pixels,
    mid_grey_gain,
    parse_panel_size,
)
from darksynth.profile import save_profile
from tests.command_line import assert_one_line_error, run_cli
from tests.conftest import build_profile


def _pixels(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image)


def _panel(sheet: np.ndarray, row: int, column: int, width: int, height: int) -> np.ndarray:
    """One panel of a preview sheet (row 0 as is, row 1 brightened; a caption bar lies between them)."""
    top = LABEL_HEIGHT if row == 0 else 2 * LABEL_HEIGHT + height
    return sheet[top : top + height, column * width : (column + 1) * width]


def _save(path: Path, pixels: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path)
    return path


def _dark_reference(path: Path, level: int = 30, size: tuple[int, int] = (48, 64)) -> Path:
    rng = np.random.default_rng(5)
    pixels = np.clip(rng.normal(level, 6, (*size, 3)), 0, 255).astype(np.uint8)
    return _save(path, pixels)


def _estimated_profile(write_profile: Callable[..., Path], source: str, name: str = "profile.json") -> Path:
    """The default profile with the provenance ``estimate`` records: the reference as given and the estimator."""
    return write_profile(name, meta={"source": source, "estimator": "DEN v3 width 8 depth 3"})


def test_layout_and_size(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "sheet.png"
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--out", out, "--seed", "1", "--crop", "32x24")
    assert code == 0, err
    assert "warning" not in err  # the shipped profile names no reference file
    assert "3 panels of 32x24" in err
    sheet = _pixels(out)
    # clean | darkened | darkened + noise, each shown once as is and once brightened, a caption bar between.
    assert sheet.shape == (2 * LABEL_HEIGHT + 2 * 24, 3 * 32, 3)
    clean = _pixels(rgb_image)
    assert np.array_equal(_panel(sheet, 0, 0, 32, 24), centre_crop(clean, 24, 32))
    assert np.array_equal(_panel(sheet, 1, 0, 32, 24), centre_crop(clean, 24, 32))  # clean is not brightened
    darkened = _panel(sheet, 0, 1, 32, 24)
    assert np.array_equal(darkened, centre_crop(darkened_pixels(clean, Darkening(alpha=0.2, gamma=0.7)), 24, 32))


def test_a_large_image_is_shown_by_its_centre_at_most_512(tmp_path: Path, profile_file: Path) -> None:
    image = _save(tmp_path / "big.png", np.random.default_rng(1).integers(0, 256, (600, 700, 3), dtype=np.uint8))
    code, _, err = run_cli("preview", image, "-p", profile_file, "--out", tmp_path / "p.png", "--seed", "0")
    assert code == 0, err
    assert _pixels(tmp_path / "p.png").shape == (2 * LABEL_HEIGHT + 2 * 512, 3 * 512, 3)
    small = _save(tmp_path / "small.png", np.zeros((30, 20, 3), np.uint8))
    code, _, err = run_cli("preview", small, "-p", profile_file, "--out", tmp_path / "q.png", "--crop", "256")
    assert code == 0, err
    assert _pixels(tmp_path / "q.png").shape == (2 * LABEL_HEIGHT + 2 * 30, 3 * 20, 3)


@pytest.mark.parametrize(
    ("darkening", "noisy_column"),
    [((), 2), (("--alpha", "0.3", "--gamma", "0.5"), 2), (("--no-darken",), 1)],
    ids=["profile", "alpha-gamma", "no-darken"],
)
def test_noisy_panel_is_what_apply_writes(
    rgb_image: Path, profile_file: Path, tmp_path: Path, darkening: tuple[str, ...], noisy_column: int
) -> None:
    applied = tmp_path / "applied.png"
    assert run_cli("apply", rgb_image, applied, "-p", profile_file, "--seed", "9", *darkening)[0] == 0
    out = tmp_path / "sheet.png"
    code, _, err = run_cli(
        "preview", rgb_image, "-p", profile_file, "--out", out, "--seed", "9", "--crop", "40x30", *darkening
    )
    assert code == 0, err
    noisy = _panel(_pixels(out), 0, noisy_column, 40, 30)
    assert np.array_equal(noisy, centre_crop(_pixels(applied), 30, 40))
    # The control: another seed gives another panel, so the equality above is the seed's doing.
    run_cli("preview", rgb_image, "-p", profile_file, "--out", out, "--seed", "10", "--crop", "40x30", "--overwrite")
    assert not np.array_equal(_panel(_pixels(out), 0, noisy_column, 40, 30), noisy)


@pytest.mark.parametrize("light", [(), ("--no-blur",), ("--no-flicker",)], ids=["blur", "no-blur", "no-flicker"])
def test_the_light_flags_reach_the_preview_as_they_reach_apply(
    rgb_image: Path, tmp_path: Path, light: tuple[str, ...]
) -> None:
    profile = tmp_path / "shaken.json"
    save_profile(profile, build_profile(read=0.01, shake_length=0.1, shake_angle=30.0, exposure_fraction=1.0))
    applied = tmp_path / "applied.png"
    assert run_cli("apply", rgb_image, applied, "-p", profile, "--seed", "9", "--no-darken", *light)[0] == 0
    out = tmp_path / "sheet.png"
    flags = ("--out", out, "--seed", "9", "--crop", "40x30", "--no-darken")
    assert run_cli("preview", rgb_image, "-p", profile, *flags, *light)[0] == 0
    assert np.array_equal(_panel(_pixels(out), 0, 1, 40, 30), centre_crop(_pixels(applied), 30, 40))
    # The control: the shake is visible, so the equality above is the flag's doing.
    other = ("--blur",) if light == ("--no-blur",) else ("--no-blur",)
    assert run_cli("preview", rgb_image, "-p", profile, *flags, *other, "--overwrite")[0] == 0
    assert not np.array_equal(_panel(_pixels(out), 0, 1, 40, 30), centre_crop(_pixels(applied), 30, 40))


def test_reference_panel_shown_and_brightened_by_the_synthetic_panels_gain(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path]
) -> None:
    # Brighter than the synthetic panel, so that its own mid-grey gain differs from the common one.
    reference = _dark_reference(tmp_path / "refs" / "night.png", level=90)
    profile = _estimated_profile(write_profile, str(reference))
    out = tmp_path / "sheet.png"
    code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", out, "--seed", "2", "--crop", "40x30")
    assert code == 0, err
    assert "4 panels" in err and "warning" not in err
    sheet = _pixels(out)
    assert sheet.shape[1] == 4 * 40
    shown = _panel(sheet, 0, 3, 40, 30)
    assert np.array_equal(shown, centre_crop(_pixels(reference), 30, 40))
    gain = mid_grey_gain(_panel(sheet, 0, 2, 40, 30))
    assert f"x{gain:.1f}" in err
    for column in (1, 2, 3):
        assert np.array_equal(_panel(sheet, 1, column, 40, 30), brighten(_panel(sheet, 0, column, 40, 30), gain))
    assert not np.array_equal(_panel(sheet, 1, 3, 40, 30), brighten(shown))  # not its own gain


def test_relative_reference_is_looked_for_beside_the_profile(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    _dark_reference(tmp_path / "night.png")
    profile = _estimated_profile(write_profile, "night.png")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", tmp_path / "p.png", "--crop", "32")
    assert code == 0, err
    assert "4 panels" in err


def test_video_reference_shows_its_first_frame(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path]
) -> None:
    video = tmp_path / "night.mkv"
    with VideoWriter(video, width=64, height=48, fps=Fraction(10), encoding=VideoEncoding(codec="ffv1")) as writer:
        for level in (40, 200):
            writer.write(np.full((48, 64, 3), level, np.uint8))
    profile = _estimated_profile(write_profile, str(video))
    out = tmp_path / "p.png"
    code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", out, "--crop", "32x24")
    assert code == 0, err
    reference_panel = _panel(_pixels(out), 0, 3, 32, 24)
    assert abs(float(reference_panel.mean()) - 40) < 3  # the first frame, not the second


def test_missing_reference_warns_in_one_line_and_shows_no_panel(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path]
) -> None:
    profile = _estimated_profile(write_profile, str(tmp_path / "gone" / "night.png"))
    out = tmp_path / "p.png"
    code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", out, "--crop", "32x24")
    assert code == 0, err
    warnings = [line for line in err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and warnings[0].startswith("darksynth: warning: ") and "night.png" in warnings[0]
    assert "3 panels" in err
    assert _pixels(out).shape[1] == 3 * 32


def test_unreadable_reference_warns_and_shows_no_panel(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path]
) -> None:
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not a png")
    profile = _estimated_profile(write_profile, str(broken))
    code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", tmp_path / "p.png", "--crop", "32x24")
    assert code == 0, err
    assert "3 panels" in err and "darksynth: warning: " in err and "broken.png" in err


def test_existing_output_is_refused_unless_overwrite(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "preview.png"
    out.write_bytes(b"keep me")
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--out", out, "--crop", "32")
    assert_one_line_error(code, err, "preview.png", "--overwrite")
    assert out.read_bytes() == b"keep me"
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--out", out, "--crop", "32", "--overwrite")
    assert code == 0, err
    assert _pixels(out).shape[1] == 3 * 32
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]


def test_default_output_is_preview_png_in_the_current_folder(
    rgb_image: Path, profile_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--crop", "32")
    assert code == 0, err
    assert (tmp_path / "preview.png").is_file()


def test_inputs_are_never_replaced(
    rgb_image: Path, tmp_path: Path, write_profile: Callable[..., Path], profile_file: Path
) -> None:
    reference = _dark_reference(tmp_path / "night.png")
    profile = _estimated_profile(write_profile, str(reference))
    before = {p: p.read_bytes() for p in (rgb_image, reference)}
    for target in (rgb_image, reference):
        code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", target, "--overwrite")
        assert_one_line_error(code, err, target.name)
    assert {p: p.read_bytes() for p in before} == before


def test_same_seed_same_bytes(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    for name in ("a.png", "b.png"):
        assert run_cli("preview", rgb_image, "-p", profile_file, "--out", tmp_path / name, "--seed", "4")[0] == 0
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_omitted_seed_is_printed_and_reproduces_the_preview(
    rgb_image: Path, profile_file: Path, tmp_path: Path
) -> None:
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--out", tmp_path / "a.png")
    assert code == 0, err
    seed = err.split("seed ")[1].split(",")[0]
    assert run_cli("preview", rgb_image, "-p", profile_file, "--out", tmp_path / "b.png", "--seed", seed)[0] == 0
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_bad_inputs_are_one_line_errors(rgb_image: Path, profile_file: Path, tmp_path: Path) -> None:
    video = tmp_path / "clip.mp4"
    with VideoWriter(video, width=16, height=16, fps=Fraction(10)) as writer:
        writer.write(np.zeros((16, 16, 3), np.uint8))
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"\x00not an image" * 10)
    bad_profile = tmp_path / "bad.json"
    bad_profile.write_text("{not json")
    out = tmp_path / "o.png"
    cases = [
        ((tmp_path / "missing.png", "-p", profile_file), ("missing.png",)),
        ((video, "-p", profile_file), ("clip.mp4", "one image")),
        ((tmp_path, "-p", profile_file), (tmp_path.name, "one image")),
        ((garbage, "-p", profile_file), ("garbage.png",)),
        ((rgb_image, "-p", bad_profile), ("bad.json",)),
        ((rgb_image, "-p", tmp_path / "nope.json"), ("nope.json",)),
        ((rgb_image, "-p", profile_file, "--crop", "big"), ("--crop",)),
        ((rgb_image, "-p", profile_file, "--crop", "8x8"), ("--crop",)),
        ((rgb_image, "-p", profile_file, "--alpha", "0.2"), ("--gamma",)),
        ((rgb_image, "-p", profile_file, "--no-darken", "--gamma", "1"), ("--no-darken",)),
    ]
    for arguments, needles in cases:
        code, _, err = run_cli("preview", *arguments, "--out", out)
        assert_one_line_error(code, err, *needles)
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--out", tmp_path / "o.mp4")
    assert_one_line_error(code, err, "o.mp4", "suffixes")
    code, _, err = run_cli("preview", rgb_image, "-p", profile_file, "--out", tmp_path)
    assert_one_line_error(code, err, tmp_path.name)
    assert not out.exists() and not (tmp_path / "o.mp4").exists()
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]


def test_panel_size_parsing() -> None:
    assert parse_panel_size("640x360") == (640, 360)
    assert parse_panel_size("256") == (256, 256)
    assert parse_panel_size("100X50") == (100, 50)


def test_display_pixels_of_16_bit_and_grey() -> None:
    deep = np.array([[[0], [257 * 7], [65535]]], dtype=np.uint16)
    shown = display_pixels(deep)
    assert shown.dtype == np.uint8 and shown.shape == (1, 3, 3)
    assert shown[0, :, 0].tolist() == [0, 7, 255] and (shown == shown[..., :1]).all()


def test_16_bit_grey_image_previews(profile_file: Path, tmp_path: Path) -> None:
    ramp = (np.linspace(0, 65535, 40 * 48).reshape(40, 48) + 0.5).astype(np.uint16)
    image = tmp_path / "deep.png"
    Image.fromarray(ramp).save(image)
    code, _, err = run_cli("preview", image, "-p", profile_file, "--out", tmp_path / "p.png", "--seed", "0")
    assert code == 0, err
    clean_panel = _panel(_pixels(tmp_path / "p.png"), 0, 0, 48, 40)
    assert np.abs(clean_panel[..., 0].astype(int) - ramp / 257).max() <= 0.5 + 1e-9


def test_a_profile_written_by_estimate_brings_its_reference(
    rgb_image: Path, tmp_path: Path, tiny_model: Callable[..., DEN]
) -> None:
    """What ``estimate`` records in the profile's meta is what the preview reads: no hand-written provenance."""
    reference = _dark_reference(tmp_path / "night.png", size=(64, 64))
    result = estimate(
        load_reference(reference), tiny_model(), source=str(reference), options=NoiseEstimateOptions(refine=False)
    )
    profile = tmp_path / "estimated.json"
    save_profile(profile, result.profile)
    code, _, err = run_cli("preview", rgb_image, "-p", profile, "--out", tmp_path / "p.png", "--crop", "32x24")
    assert code == 0, err
    assert "4 panels" in err
    assert np.array_equal(_panel(_pixels(tmp_path / "p.png"), 0, 3, 32, 24), centre_crop(_pixels(reference), 24, 32))


def test_demo_sheet_keeps_its_layout_and_per_panel_brightening(tmp_path: Path) -> None:
    """The demo builds its sheet from the same code: four panels as is, below them each dark panel to mid-grey."""
    from darksynth.demo import run_demo, sample_path

    run_demo(tmp_path / "demo", seed=0)
    sheet = _pixels(tmp_path / "demo" / "preview.png")
    clean = _pixels(sample_path("clean.png"))
    height, width = clean.shape[:2]
    assert sheet.shape == (LABEL_HEIGHT + 2 * height, 4 * width, 3)

    def panel(row: int, column: int) -> np.ndarray:
        top = LABEL_HEIGHT + row * height
        return sheet[top : top + height, column * width : (column + 1) * width]

    assert np.array_equal(panel(0, 0), clean)
    assert np.array_equal(panel(0, 2), _pixels(tmp_path / "demo" / "clean_lowlight.png"))
    assert np.array_equal(panel(1, 3), brighten(panel(0, 3)))
    assert abs(float(panel(1, 2)[LABEL_HEIGHT:].mean()) / 255 - 0.45) < 0.05
