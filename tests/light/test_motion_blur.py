"""Motion blur along the flow: a translation blurred with a known exposure fraction equals the shutter's integral
of the moving scene; still parts, scene cuts and size changes are left alone; camera shake and flicker laws."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import torch

from darksynth.light.flicker import FlickerGains
from darksynth.light.linear_light import LEVEL_OF_LINEAR16, LINEAR16_OF_LEVEL, decode, encode, levels_of_linear16
from darksynth.light.motion_blur import (
    MotionBlurStream,
    Workspace,
    blur_along,
    inverse_flow,
    line_kernel,
    shake_blur,
)

WIDTH, HEIGHT = 256, 160


def _texture(seed: int = 0, height: int = HEIGHT + 40, width: int = WIDTH + 200) -> np.ndarray:
    """A smooth random texture (edges a few pixels wide), 8-bit RGB."""
    rng = np.random.default_rng(seed)
    pixels = rng.random((height, width, 3)).astype(np.float32)
    pixels = cv2.GaussianBlur(pixels, (0, 0), 2.0)
    pixels = (pixels - pixels.min()) / (pixels.max() - pixels.min())
    return np.round(pixels * 255).astype(np.uint8)


def _frame_at(texture: np.ndarray, x: float) -> np.ndarray:
    """The texture seen through a window whose left edge is at ``x`` (sub-pixel, bilinear, in linear light)."""
    linear = decode(texture)
    shift = np.float32([[1, 0, x], [0, 1, 20]])
    window = cv2.warpAffine(linear, shift, (WIDTH, HEIGHT), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    return window


def _moving_clip(speed: float, frames: int = 5) -> list[np.ndarray]:
    texture = _texture()
    return [encode(_frame_at(texture, 60 + speed * t), np.dtype(np.uint8)) for t in range(frames)]


def _shutter_truth(speed: float, fraction: float, t: int, points: int = 64) -> np.ndarray:
    """The exact integral: the mean in linear light of the scene at ``points`` instants of the exposure window."""
    texture = _texture()
    offsets = (np.arange(points) + 0.5) / points - 0.5
    frames = [_frame_at(texture, 60 + speed * (t + fraction * o)) for o in offsets]
    return encode(np.mean(frames, axis=0), np.dtype(np.uint8))


@pytest.mark.parametrize(("speed", "fraction"), [(4.0, 1.0), (8.0, 0.5), (10.0, 1.0)])
def test_a_translation_is_blurred_as_the_shutter_integrates_it(speed: float, fraction: float) -> None:
    clip = _moving_clip(speed)
    blurred = list(MotionBlurStream(fraction).run(iter(clip)))
    assert len(blurred) == len(clip)
    interior = (slice(16, -16), slice(24, -24))
    for t in (1, 2, 3):
        truth = _shutter_truth(speed, fraction, t).astype(np.float64)[interior]
        got = blurred[t].astype(np.float64)[interior]
        sharp = clip[t].astype(np.float64)[interior]
        error = np.abs(got - truth).mean()
        # Against the unblurred frame the truth differs by many levels; ours is within about a level of it.
        assert error < 1.5, error
        assert np.abs(sharp - truth).mean() > 4 * error


def test_the_blur_is_along_the_motion_only() -> None:
    clip = _moving_clip(8.0)
    blurred = list(MotionBlurStream(1.0).run(iter(clip)))[2].astype(np.float64)
    sharp = clip[2].astype(np.float64)
    along = np.abs(np.diff(blurred, axis=1)).mean() / np.abs(np.diff(sharp, axis=1)).mean()
    across = np.abs(np.diff(blurred, axis=0)).mean() / np.abs(np.diff(sharp, axis=0)).mean()
    assert along < 0.6
    assert along < 0.75 * across


def test_still_parts_keep_their_bytes() -> None:
    texture = _texture()[:HEIGHT, :WIDTH]
    still = [texture.copy() for _ in range(4)]
    assert all(np.array_equal(a, b) for a, b in zip(MotionBlurStream(1.0).run(iter(still)), still, strict=True))
    # Half the frame moves: the other half, away from the moving one, keeps every byte.
    moving = _moving_clip(8.0)
    mixed = [np.concatenate([texture[: HEIGHT // 2], frame[HEIGHT // 2 :]]) for frame in moving]
    out = list(MotionBlurStream(1.0).run(iter(mixed)))
    top = slice(0, HEIGHT // 2 - 16)
    assert all(np.array_equal(o[top], m[top]) for o, m in zip(out, mixed, strict=True))
    assert not np.array_equal(out[2][HEIGHT // 2 + 16 :], mixed[2][HEIGHT // 2 + 16 :])


def test_no_blur_across_a_scene_cut_or_a_size_change() -> None:
    first = _texture(1)[:HEIGHT, :WIDTH]
    second = _texture(2)[:HEIGHT, :WIDTH]
    stream = MotionBlurStream(1.0)
    out = list(stream.run(iter([first, first, second, second])))
    assert all(np.array_equal(o, i) for o, i in zip(out, [first, first, second, second], strict=True))
    assert stream.cuts == 1
    small = second[: HEIGHT // 2, : WIDTH // 2]
    stream = MotionBlurStream(1.0)
    out = list(stream.run(iter([first, small, small])))
    assert [o.shape for o in out] == [first.shape, small.shape, small.shape]
    assert stream.cuts == 1


def test_zero_exposure_passes_frames_through_at_once() -> None:
    clip = _moving_clip(8.0)
    stream = MotionBlurStream(0.0)
    assert stream.push(clip[0])[0] is clip[0]
    assert stream.finish() == []


def test_one_frame_and_black_frames_do_not_crash() -> None:
    clip = _moving_clip(8.0)
    (only,) = MotionBlurStream(1.0).run(iter(clip[:1]))
    assert np.array_equal(only, clip[0])
    black = [np.zeros((HEIGHT, WIDTH, 3), np.uint8)] * 3
    assert all(np.array_equal(o, b) for o, b in zip(MotionBlurStream(1.0).run(iter(black)), black, strict=True))


def test_sixteen_bit_and_float_frames_keep_their_type() -> None:
    clip = _moving_clip(8.0)
    wide = [frame.astype(np.uint16) * 257 for frame in clip]
    out = list(MotionBlurStream(1.0).run(iter(wide)))
    assert out[2].dtype == np.uint16
    eight = list(MotionBlurStream(1.0).run(iter(clip)))[2].astype(np.float64)
    assert np.abs(out[2] / 257.0 - eight).mean() < 0.5
    floats = list(MotionBlurStream(1.0).run(iter([f.astype(np.float32) / 255 for f in clip])))
    assert floats[2].dtype == np.float32
    assert np.abs(floats[2] * 255 - eight).mean() < 0.5


def test_grey_frames_blur_as_each_channel_of_a_colour_frame_does() -> None:
    colour = _moving_clip(8.0)
    grey = [np.ascontiguousarray(frame[..., 1]) for frame in colour]
    as_colour = list(MotionBlurStream(1.0).run(iter([np.repeat(g[..., None], 3, axis=2) for g in grey])))[2][..., 0]
    one_channel = list(MotionBlurStream(1.0).run(iter([g[..., None] for g in grey])))[2]
    plane = list(MotionBlurStream(1.0).run(iter(grey)))[2]
    assert one_channel.shape == (HEIGHT, WIDTH, 1) and plane.shape == (HEIGHT, WIDTH)
    assert np.array_equal(one_channel[..., 0], as_colour)
    assert np.abs(plane.astype(int) - as_colour).max() <= 1  # the float path: rounding apart
    assert np.abs(plane.astype(float) - grey[2]).mean() > 2.0


def _ramp_velocity(height: int, width: int) -> np.ndarray:
    """Rightward motion growing down the frame from 0 to 3 px a frame: still rows, rows between
    STILL_LENGTH and FULL_LENGTH (blended) and rows fully blurred, with a vertical part that varies along x."""
    speed = np.linspace(0.0, 3.0, height, dtype=np.float32)[:, None] * np.ones((1, width), np.float32)
    tilt = np.linspace(-0.3, 0.3, width, dtype=np.float32)[None, :] * speed
    return np.ascontiguousarray(np.stack([speed, tilt], axis=-1))


def test_eight_bit_frames_blend_as_the_float_path_does() -> None:
    # 8-bit frames take the 16-bit tables and blend only the pixels between the two lengths; float frames take
    # the plain arithmetic over every pixel. Both integrate the same light: within half a level on average and one
    # level anywhere, and the still rows keep their bytes.
    frame = _texture(3)[:HEIGHT, :WIDTH]
    velocity = _ramp_velocity(HEIGHT, WIDTH)
    eight = blur_along(frame, 1.0, velocity).astype(np.float64)
    floats = blur_along(frame.astype(np.float32) / 255.0, 1.0, velocity).astype(np.float64) * 255.0
    assert np.abs(eight - floats).max() <= 1.0 + 1e-6
    assert np.abs(eight - floats).mean() < 0.5
    still_rows = int(np.searchsorted(np.linspace(0.0, 3.0, HEIGHT), 0.5 / 1.3))  # lengths under 0.5 px everywhere
    assert np.array_equal(eight[:still_rows], frame[:still_rows])
    assert np.abs(eight[-20:] - frame[-20:]).mean() > 2.0  # the fast rows did blur


def test_a_kept_workspace_changes_no_byte() -> None:
    # A stream's buffers are reused from frame to frame and across sizes: the result is what a call without
    # them gives.
    workspace = Workspace()
    for seed, (height, width) in enumerate([(HEIGHT, WIDTH), (HEIGHT // 2, WIDTH + 30), (HEIGHT, WIDTH)]):
        frame = _texture(seed)[:height, :width]
        velocity = _ramp_velocity(height, width) * np.float32(4 + seed)
        assert np.array_equal(blur_along(frame, 0.7, velocity, workspace), blur_along(frame, 0.7, velocity))


def test_the_inverse_flow_leads_back_where_the_flow_started() -> None:
    # A smooth field (a turn of 2 degrees and a zoom of 3 % about the centre, plus a drift: up to 6 px): following
    # the flow and then its inverse from where it lands returns to the start within a few hundredths of a pixel.
    height, width = 120, 160
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    cx, cy, turn, zoom = width / 2, height / 2, math.radians(2.0), 1.03
    moved_x = cx + zoom * (math.cos(turn) * (x - cx) - math.sin(turn) * (y - cy)) + 1.5
    moved_y = cy + zoom * (math.sin(turn) * (x - cx) + math.cos(turn) * (y - cy)) - 0.7
    flow = np.ascontiguousarray(np.stack([moved_x - x, moved_y - y], axis=-1), dtype=np.float32)
    back = inverse_flow(flow)
    back_at_landing = cv2.remap(back, moved_x, moved_y, cv2.INTER_LINEAR)
    inner = (slice(15, -15), slice(15, -15))
    miss = np.hypot(*(flow + back_at_landing)[inner].transpose(2, 0, 1))
    assert np.abs(flow[inner]).max() > 3.0
    assert miss.max() < 0.05, miss.max()
    # The plain negation (no fixed-point step) misses by tenths of a pixel: the steps are what makes it exact.
    naive_at_landing = cv2.remap(inverse_flow(flow, iterations=0), moved_x, moved_y, cv2.INTER_LINEAR)
    assert np.hypot(*(flow + naive_at_landing)[inner].transpose(2, 0, 1)).max() > 0.1


@pytest.mark.parametrize("rows", [1, 63, 64, 201])
def test_the_parallel_table_read_is_the_table(rows: int) -> None:
    linear = np.random.default_rng(rows).integers(0, 65536, (rows, 37, 3), dtype=np.uint16)
    assert np.array_equal(levels_of_linear16(linear), LEVEL_OF_LINEAR16[linear])
    # Every level survives the round trip through 16-bit linear light (what lets still pixels keep their bytes).
    levels = np.arange(256, dtype=np.uint8)
    assert np.array_equal(levels_of_linear16(LINEAR16_OF_LEVEL[levels]), levels)


@pytest.mark.parametrize(("length", "angle"), [(7.0, 0.0), (10.0, 30.0), (5.5, 90.0)])
def test_the_shake_kernel_is_a_centred_path_of_the_given_length(length: float, angle: float) -> None:
    kernel = line_kernel(length, angle).astype(np.float64)
    assert kernel.sum() == pytest.approx(1.0, abs=1e-6)
    radius = kernel.shape[0] // 2
    y, x = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    along = x * math.cos(math.radians(angle)) - y * math.sin(math.radians(angle))
    across = x * math.sin(math.radians(angle)) + y * math.cos(math.radians(angle))
    assert abs((kernel * along).sum()) < 1e-6 and abs((kernel * across).sum()) < 1e-6
    # A box of length L has variance L^2 / 12; bilinear splatting adds at most 1/6 in each direction.
    assert (kernel * along**2).sum() == pytest.approx(length**2 / 12, abs=0.2)
    assert (kernel * across**2).sum() < 0.2


def test_shake_blurs_a_still_image_and_a_short_path_changes_nothing() -> None:
    texture = _texture()[:HEIGHT, :WIDTH]
    assert shake_blur(texture, 0.3, 0.0) is texture
    shaken = shake_blur(texture, 9.0, 0.0).astype(np.float64)
    sharp = texture.astype(np.float64)
    along = np.abs(np.diff(shaken, axis=1)).mean() / np.abs(np.diff(sharp, axis=1)).mean()
    across = np.abs(np.diff(shaken, axis=0)).mean() / np.abs(np.diff(sharp, axis=0)).mean()
    assert along < 0.6
    assert along < 0.75 * across


@pytest.mark.parametrize(("std", "correlation"), [(0.05, 0.0), (0.08, 0.6), (0.03, 0.9)])
def test_flicker_gains_have_their_std_and_lag_one_correlation(std: float, correlation: float) -> None:
    gains = FlickerGains(std, correlation).sequence(20000, torch.Generator().manual_seed(0)).numpy()
    assert gains.mean() == pytest.approx(1.0, abs=4 * std / math.sqrt(20000 * (1 - correlation) / (1 + correlation)))
    assert gains.std() == pytest.approx(std, rel=0.05)
    lag = np.corrcoef(gains[:-1], gains[1:])[0, 1]
    assert lag == pytest.approx(correlation, abs=0.03)


def test_no_flicker_draws_nothing() -> None:
    generator = torch.Generator().manual_seed(0)
    state = generator.get_state()
    assert FlickerGains(0.0, 0.5).sequence(10, generator).tolist() == [1.0] * 10
    assert torch.equal(generator.get_state(), state)


def test_a_flow_does_not_depend_on_the_flows_before_it() -> None:
    """A kept DIS engine carried state from call to call: after a pair of small noise frames, the flow of an
    unrelated pair moved by a third of a pixel. Each flow must be the pair's alone."""
    from darksynth.light.motion_blur import dense_flow

    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur((rng.random((192, 256)) * 255).astype(np.uint8), (0, 0), 2)
    moved = np.roll(texture, 1, axis=1)
    first = dense_flow(texture, moved)
    noise = (rng.random((2, 40, 40)) * 255).astype(np.uint8)
    dense_flow(noise[0], noise[1])
    assert np.array_equal(dense_flow(texture, moved), first)


@pytest.mark.parametrize("shape", [(8, 8, 3), (10, 300, 3), (300, 10, 1)])
def test_frames_too_small_for_a_flow_pass_through(shape: tuple[int, int, int]) -> None:
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 256, shape, dtype=np.uint8) for _ in range(3)]
    stream = MotionBlurStream(1.0)
    out = list(stream.run(iter(frames)))
    assert all(np.array_equal(o, f) for o, f in zip(out, frames, strict=True))
    assert stream.cuts == 2
