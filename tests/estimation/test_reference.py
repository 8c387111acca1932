"""load_reference and crop_grid: what a reference becomes, and where its crops come from."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from darksynth.errors import DarksynthError
from darksynth.estimation.reference import MAX_FRAMES, MIN_SIDE, crop_grid, load_reference
from darksynth.io.video import VideoWriter
from tests.clean_images import smooth_rgb, write_png


def test_image_becomes_one_frame_of_its_pixels(tmp_path: Path) -> None:
    pixels = smooth_rgb(48, 70)
    reference = load_reference(write_png(tmp_path / "ref.png", pixels))
    assert reference.shape == (1, 3, 48, 70)
    assert reference.dtype == torch.float32
    expected = torch.from_numpy(pixels).permute(2, 0, 1).float() / 255.0
    torch.testing.assert_close(reference[0], expected)


def test_grey_image_is_repeated_to_three_channels(tmp_path: Path) -> None:
    grey = smooth_rgb(40, 50)[..., 1]
    path = tmp_path / "grey.png"
    Image.fromarray(grey, mode="L").save(path)
    reference = load_reference(path)
    assert reference.shape == (1, 3, 40, 50)
    for channel in range(3):
        torch.testing.assert_close(reference[0, channel], torch.from_numpy(grey).float() / 255.0)


def test_sixteen_bit_image_is_scaled_by_65535(tmp_path: Path) -> None:
    values = (np.arange(40 * 40, dtype=np.uint16).reshape(40, 40) * 40).astype(np.uint16)
    path = tmp_path / "deep.png"
    Image.fromarray(values).save(path)
    reference = load_reference(path)
    torch.testing.assert_close(reference[0, 0], torch.from_numpy(values.astype(np.float32)) / 65535.0)


def _frame_folder(root: Path, count: int, size: tuple[int, int] = (40, 52)) -> Path:
    """Frames whose red channel holds the frame's index, written in an order unlike their names."""
    for index in reversed(range(count)):
        pixels = smooth_rgb(*size, phase=index)
        pixels[..., 0] = index
        write_png(root / f"f{index:03d}.png", pixels)
    return root


def test_frame_folder_is_a_reference_only_with_clip(tmp_path: Path) -> None:
    folder = _frame_folder(tmp_path / "frames", 3)
    with pytest.raises(DarksynthError, match="--clip") as raised:
        load_reference(folder)
    assert str(folder) in str(raised.value)
    reference = load_reference(folder, clip=True)
    assert reference.shape == (3, 3, 40, 52)
    assert (reference[:, 0, 0, 0] * 255).round().tolist() == [0, 1, 2]


def test_frame_folder_reads_at_most_max_frames_in_name_order(tmp_path: Path) -> None:
    folder = _frame_folder(tmp_path / "frames", MAX_FRAMES + 3)
    reference = load_reference(folder, clip=True)
    assert reference.shape[0] == MAX_FRAMES
    assert (reference[:, 0, 0, 0] * 255).round().tolist() == list(range(MAX_FRAMES))
    assert load_reference(folder, clip=True, max_frames=2).shape[0] == 2


def test_frames_of_different_sizes_raise_naming_the_file(tmp_path: Path) -> None:
    folder = _frame_folder(tmp_path / "frames", 3)
    odd = write_png(folder / "f001b.png", smooth_rgb(40, 56))
    with pytest.raises(DarksynthError) as raised:
        load_reference(folder, clip=True)
    assert str(raised.value).startswith(f"{odd}: ")
    assert "differs" in str(raised.value)


@pytest.mark.parametrize("size", [(20, 20), (MIN_SIDE - 1, 100), (100, MIN_SIDE - 1)])
def test_too_small_references_are_refused(tmp_path: Path, size: tuple[int, int]) -> None:
    path = write_png(tmp_path / "small.png", smooth_rgb(*size))
    with pytest.raises(DarksynthError, match="smaller than the estimator's minimum") as raised:
        load_reference(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_smallest_accepted_reference(tmp_path: Path) -> None:
    assert load_reference(write_png(tmp_path / "ok.png", smooth_rgb(MIN_SIDE, MIN_SIDE))).shape == (
        1,
        3,
        MIN_SIDE,
        MIN_SIDE,
    )


def test_missing_reference_is_refused(tmp_path: Path) -> None:
    with pytest.raises(DarksynthError, match="no such file"):
        load_reference(tmp_path / "absent.png")


def _video(path: Path, frames: int) -> Path:
    with VideoWriter(path, width=64, height=48, fps=Fraction(10)) as writer:
        for index in range(frames):
            pixels = np.full((48, 64, 3), 20 + 10 * index, dtype=np.uint8)
            writer.write(pixels)
    return path


def test_video_gives_its_first_frames_up_to_max_frames(tmp_path: Path) -> None:
    long = load_reference(_video(tmp_path / "long.mp4", MAX_FRAMES + 4))
    assert long.shape == (MAX_FRAMES, 3, 48, 64)
    levels = (long.mean(dim=(1, 2, 3)) * 255).tolist()
    assert levels == pytest.approx([20 + 10 * i for i in range(MAX_FRAMES)], abs=2)
    short = load_reference(_video(tmp_path / "short.mp4", 3))
    assert short.shape == (3, 3, 48, 64)


def _encoded(frames: int, height: int, width: int) -> torch.Tensor:
    """A reference whose channels hold the frame, row and column of each pixel (exact in float32)."""
    t = torch.arange(frames, dtype=torch.float32)[:, None, None].expand(frames, height, width)
    y = torch.arange(height, dtype=torch.float32)[None, :, None].expand(frames, height, width)
    x = torch.arange(width, dtype=torch.float32)[None, None, :].expand(frames, height, width)
    return torch.stack([t, y, x], dim=1).contiguous()


@pytest.mark.parametrize(
    ("frames", "height", "width", "crop"),
    [(1, 300, 410, 128), (1, 37, 53, 128), (9, 90, 130, 64), (3, 64, 64, 128), (16, 200, 203, 48)],
)
def test_crops_are_equal_squares_inside_the_frame_with_left_edges_at_multiples_of_four(
    frames: int, height: int, width: int, crop: int
) -> None:
    crops = crop_grid(_encoded(frames, height, width), crop=crop, max_crops=1000)
    side = crops.shape[-1]
    assert crops.shape[-2] == side
    assert side == min(crop, height, width - width % 4)
    assert crops.shape[1] == min(4, frames)
    for clip in crops:
        first_frame, top, left = (int(v) for v in clip[0, :, 0, 0])
        assert left % 4 == 0
        assert 0 <= top <= height - side and 0 <= left <= width - side
        # The crop is a contiguous block of consecutive frames.
        torch.testing.assert_close(
            clip,
            _encoded(frames, height, width)[
                first_frame : first_frame + clip.shape[0], :, top : top + side, left : left + side
            ],
        )
    # The grid reaches the bottom edge and, to within the 4-column alignment, the right edge.
    tops = {int(clip[0, 1, 0, 0]) for clip in crops}
    lefts = {int(clip[0, 2, 0, 0]) for clip in crops}
    assert min(tops) == 0 and max(tops) == height - side
    assert min(lefts) == 0 and width - side - max(lefts) < 4


def test_windows_cover_the_clip_without_overlap() -> None:
    crops = crop_grid(_encoded(9, 64, 64), crop=64, clip_frames=4, max_crops=1000)
    assert [int(clip[0, 0, 0, 0]) for clip in crops] == [0, 4]
    assert all(
        clip[:, 0, 0, 0].tolist() == [start, start + 1, start + 2, start + 3]
        for clip, start in zip(crops, [0, 4], strict=True)
    )


@pytest.mark.parametrize("max_crops", [1, 5, 10])
def test_number_of_crops_is_bounded_and_spread_over_the_grid(max_crops: int) -> None:
    reference = _encoded(8, 160, 160)
    everything = crop_grid(reference, crop=32, max_crops=1000)
    assert len(everything) == 2 * 5 * 5  # two windows of four frames, a 5 x 5 grid
    kept = crop_grid(reference, crop=32, max_crops=max_crops)
    assert len(kept) == max_crops
    assert all(any(torch.equal(crop, other) for other in everything) for crop in kept)
    if max_crops > 1:
        # The first and the last crop of the full grid are kept: the selection spans the whole grid.
        assert torch.equal(kept[0], everything[0]) and torch.equal(kept[-1], everything[-1])


def test_crop_grid_has_no_duplicate_crops_when_the_frame_barely_exceeds_the_crop() -> None:
    from darksynth.estimation.reference import crop_grid

    rows = torch.arange(131, dtype=torch.float32).view(131, 1)
    columns = torch.arange(130, dtype=torch.float32).view(1, 130)
    # Each pixel holds row * 1000 + column, so a crop's first pixel names its top-left corner.
    reference = (rows * 1000 + columns).expand(1, 3, 131, 130).contiguous()
    crops = crop_grid(reference, crop=128)
    corners = [divmod(int(c[0, 0, 0, 0]), 1000) for c in crops]
    assert len(set(corners)) == len(corners) == 2  # tops 0 and 3; the only left edge that is a multiple of 4 is 0
