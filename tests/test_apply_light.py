"""``apply`` with a profile's light: a video's and a clip's frames are blurred along their motion before the noise,
in order, one frame held; ``--no-blur`` and ``--no-flicker`` switch them off; single images take the camera shake;
the manifest records the values; flicker moves a clip's brightness frame to frame."""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from PIL import Image

from darksynth.io.video import VideoEncoding, VideoWriter, iter_video_frames
from darksynth.light.darkening import Darkening
from darksynth.light.motion_blur import MotionBlurStream, shake_blur
from darksynth.profile import Profile, load_profile, save_profile
from darksynth.recipe import ClipParameters, ClipRecipe
from darksynth.synthesize import ClipSynthesizer
from tests.command_line import run_cli
from tests.conftest import build_profile

HEIGHT, WIDTH = 96, 128


def _moving_frames(count: int = 6, speed: int = 6) -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur((rng.random((HEIGHT, WIDTH + speed * count, 3)) * 255).astype(np.uint8), (0, 0), 1.5)
    texture = cv2.normalize(texture, None, 0, 255, cv2.NORM_MINMAX)
    return [np.ascontiguousarray(texture[:, speed * t : speed * t + WIDTH]) for t in range(count)]


def _light_profile(path: Path, **light: float) -> Path:
    """No noise, so that the output is the clean input through the light stage alone."""
    save_profile(path, build_profile(**light))
    return path


def test_a_video_is_blurred_along_its_motion_in_order(tmp_path: Path) -> None:
    frames = _moving_frames()
    source = tmp_path / "in.mkv"
    with VideoWriter(
        source, width=WIDTH, height=HEIGHT, fps=Fraction(25), encoding=VideoEncoding(codec="ffv1")
    ) as writer:
        for frame in frames:
            writer.write(frame)
    decoded = list(iter_video_frames(source))
    profile = _light_profile(tmp_path / "light.json", exposure_fraction=1.0)
    out = tmp_path / "out.mkv"
    code, _, err = run_cli("apply", source, out, "--profile", profile, "--no-darken", "--codec", "ffv1", "--seed", "1")
    assert code == 0, err
    written = list(iter_video_frames(out))
    expected = list(MotionBlurStream(1.0).run(iter(decoded)))
    assert len(written) == len(decoded)
    for got, want, sharp in zip(written, expected, decoded, strict=True):
        error = np.abs(got.astype(float) - want.astype(float)).mean()
        assert error < 1.0  # the codec's colour conversion, nothing else
        assert np.abs(got.astype(float) - sharp.astype(float)).mean() > 3 * error
    manifest = json.loads((tmp_path / "out.mkv.manifest.json").read_text())
    assert manifest["files"][0]["parameters"]["light"]["exposure_fraction"] == 1.0
    off = tmp_path / "off.mkv"
    code, _, err = run_cli(
        "apply", source, off, "--profile", profile, "--no-darken", "--codec", "ffv1", "--no-blur", "--seed", "1"
    )
    assert code == 0, err
    unblurred = list(iter_video_frames(off))
    assert all(np.abs(a.astype(float) - b.astype(float)).mean() < 1.0 for a, b in zip(unblurred, decoded, strict=True))
    manifest = json.loads((tmp_path / "off.mkv.manifest.json").read_text())
    assert manifest["files"][0]["parameters"]["light"]["exposure_fraction"] == 0.0


def test_a_clip_folder_writes_each_blurred_frame_to_its_own_name(tmp_path: Path) -> None:
    frames = _moving_frames()
    folder = tmp_path / "in" / "shot"
    folder.mkdir(parents=True)
    for index, frame in enumerate(frames):
        Image.fromarray(frame).save(folder / f"{index:03d}.png")
    profile = _light_profile(tmp_path / "light.json", exposure_fraction=0.5)
    code, _, err = run_cli("apply", tmp_path / "in", tmp_path / "out", "--profile", profile, "--no-darken", "--clip")
    assert code == 0, err
    expected = list(MotionBlurStream(0.5).run(iter(frames)))
    for index, want in enumerate(expected):
        got = np.asarray(Image.open(tmp_path / "out" / "shot" / f"{index:03d}.png"))
        assert np.array_equal(got, want)


def test_an_image_takes_the_camera_shake(tmp_path: Path) -> None:
    image = _moving_frames(1)[0]
    Image.fromarray(image).save(tmp_path / "photo.png")
    profile = _light_profile(tmp_path / "light.json", shake_length=0.05, shake_angle=30.0, exposure_fraction=1.0)
    code, _, err = run_cli("apply", tmp_path / "photo.png", tmp_path / "out.png", "--profile", profile, "--no-darken")
    assert code == 0, err
    got = np.asarray(Image.open(tmp_path / "out.png")).astype(int)
    # Within the rounding of the 8-bit path (a level on a thousandth of the pixels).
    difference = np.abs(got - shake_blur(image, 0.05 * WIDTH, 30.0).astype(int))
    assert difference.max() <= 1 and difference.mean() < 0.01
    assert np.abs(got - image.astype(int)).mean() > 3
    code, _, err = run_cli(
        "apply", tmp_path / "photo.png", tmp_path / "still.png", "--profile", profile, "--no-darken", "--no-blur"
    )
    assert code == 0, err
    assert np.array_equal(np.asarray(Image.open(tmp_path / "still.png")), image)


@pytest.mark.parametrize(("flicker", "correlation"), [(0.1, 0.0), (0.06, 0.8)])
def test_flicker_moves_each_frames_brightness_by_its_gain(flicker: float, correlation: float) -> None:
    grey = torch.full((3, 64, 64), 200, dtype=torch.uint8)
    profile = build_profile(flicker=flicker, flicker_correlation=correlation)
    parameters = ClipParameters(profile.noise, Darkening(alpha=0.5, gamma=1.0))
    synthesizer = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(0))
    means = np.array([float(synthesizer(grey).double().mean()) for _ in range(400)])
    gains = means / (0.5 * 200)
    assert gains.std() == pytest.approx(flicker, rel=0.15)
    assert np.corrcoef(gains[:-1], gains[1:])[0, 1] == pytest.approx(correlation, abs=0.12)
    # A single image has none.
    assert float(ClipSynthesizer(parameters, generator=torch.Generator()).image(grey).double().mean()) == 100.0


def test_no_flicker_and_no_blur_leave_the_profile_without_light(tmp_path: Path) -> None:
    from darksynth.apply import ApplyOptions

    profile = build_profile(exposure_fraction=0.5, flicker=0.05, ranges={"flicker": [(0.0, 0.1)]})
    options = ApplyOptions(recipe=ClipRecipe(profile, blur=False, flicker=False, jitter=True), seed=0)
    drawn, _ = options.recipe.drawn_from()
    assert drawn.noise.scalar("exposure_fraction") == 0.0 and drawn.noise.scalar("flicker") == 0.0
    assert "flicker" not in drawn.ranges
    kept, _ = dataclasses.replace(options.recipe, blur=True, flicker=True).drawn_from()
    assert kept.noise.scalar("exposure_fraction") == 0.5 and "flicker" in kept.ranges
    assert isinstance(load_profile(_light_profile(tmp_path / "p.json", flicker=0.05)), Profile)


def test_the_training_transform_blurs_a_float_clip_and_shakes_an_image() -> None:
    from darksynth.transforms import LowLight

    frames = _moving_frames()
    clip = torch.from_numpy(np.stack(frames)).permute(0, 3, 1, 2).float() / 255
    transform = LowLight(build_profile(exposure_fraction=1.0), darkening=None, round_to_8bit=False)
    out = transform(clip)
    expected = list(MotionBlurStream(1.0).run(iter([f.astype(np.float32) / 255 for f in frames])))
    got = out.permute(0, 2, 3, 1).numpy()
    for t, want in enumerate(expected):
        assert np.abs(got[t] - want).max() < 1e-5
    assert np.abs(got[2] - frames[2] / 255).mean() > 0.01
    shaken = LowLight(build_profile(shake_length=0.05), darkening=None, round_to_8bit=False)(clip[0])
    want = shake_blur(frames[0].astype(np.float32) / 255, 0.05 * WIDTH, 0.0)
    assert np.abs(shaken.permute(1, 2, 0).numpy() - want).max() < 1e-5


def test_a_one_frame_video_with_blur_is_written_unblurred(tmp_path: Path) -> None:
    frame = _moving_frames(1)[0]
    source = tmp_path / "one.mkv"
    with VideoWriter(
        source, width=WIDTH, height=HEIGHT, fps=Fraction(25), encoding=VideoEncoding(codec="ffv1")
    ) as writer:
        writer.write(frame)
    profile = _light_profile(tmp_path / "light.json", exposure_fraction=1.0)
    out = tmp_path / "out.mkv"
    code, _, err = run_cli("apply", source, out, "--profile", profile, "--no-darken", "--codec", "ffv1")
    assert code == 0, err
    (written,) = iter_video_frames(out)
    (decoded,) = iter_video_frames(source)
    # No neighbour to take a motion from: the frame stays as it was.
    assert np.abs(written.astype(float) - decoded.astype(float)).mean() < 0.5
