from __future__ import annotations

from pathlib import Path

import pytest

from darksynth.errors import DarksynthError, InputFileError
from darksynth.io.discover import FolderListing, check_output_location, classify_input, scan_folder


def _touch(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"x")
    return path


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        *[(name, "image") for name in ("a.png", "a.JPG", "a.jpeg", "a.TiFF", "a.bmp")],
        *[(name, "video") for name in ("a.mp4", "a.MOV", "a.avi", "a.mkv")],
    ],
)
def test_classify_input_by_suffix(tmp_path: Path, name: str, kind: str) -> None:
    assert classify_input(_touch(tmp_path / name)) == kind


def test_classify_input_folder(tmp_path: Path) -> None:
    folder = tmp_path / "looks_like.png"
    folder.mkdir()
    assert classify_input(folder) == "folder"


def test_classify_input_missing(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="no such file or folder") as info:
        classify_input(tmp_path / "nope.png")
    assert info.value.path == tmp_path / "nope.png"


def test_classify_input_unknown_suffix(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match=r"not an image \(.*\.png.*\) or video \(.*\.mp4.*\) file"):
        classify_input(_touch(tmp_path / "notes.txt"))


def test_scan_folder_lists_relative_sorted_and_skips_hidden(tmp_path: Path) -> None:
    for name in ["b.png", "a.JPG", "sub/c.tif", "sub/deep/clip.MP4", "v.mkv", "notes.txt", "sub/data.csv"]:
        _touch(tmp_path / name)
    for hidden in [".DS_Store", ".out.tmp-1234.png", ".cache/x.png", "sub/.hidden/y.mp4"]:
        _touch(tmp_path / hidden)
    listing = scan_folder(tmp_path)
    assert listing == FolderListing(
        images=[Path("a.JPG"), Path("b.png"), Path("sub/c.tif")],
        videos=[Path("sub/deep/clip.MP4"), Path("v.mkv")],
        skipped=[Path("notes.txt"), Path("sub/data.csv")],
    )


def test_scan_folder_does_not_follow_folder_links(tmp_path: Path) -> None:
    _touch(tmp_path / "real" / "a.png")
    (tmp_path / "link").symlink_to(tmp_path / "real", target_is_directory=True)
    listing = scan_folder(tmp_path)
    assert listing.images == [Path("real/a.png")]
    assert listing.skipped == [Path("link")]


def test_scan_folder_empty_raises(tmp_path: Path) -> None:
    _touch(tmp_path / "readme.txt")
    _touch(tmp_path / ".hidden.png")
    with pytest.raises(InputFileError, match="no images or videos found"):
        scan_folder(tmp_path)


def test_scan_folder_not_a_folder(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="no such folder"):
        scan_folder(tmp_path / "missing")
    with pytest.raises(InputFileError, match="not a folder"):
        scan_folder(_touch(tmp_path / "a.png"))


def test_check_output_location_accepts_sensible_pairs(tmp_path: Path) -> None:
    image = _touch(tmp_path / "in" / "a.png")
    check_output_location(image, tmp_path / "out" / "a.png")
    check_output_location(image, tmp_path / "in" / "a_dark.png")
    check_output_location(tmp_path / "in", tmp_path / "out")
    check_output_location(tmp_path / "in", tmp_path / "in_dark")  # a sibling whose name starts the same


def test_check_output_location_refuses_same_path(tmp_path: Path) -> None:
    image = _touch(tmp_path / "a.png")
    with pytest.raises(DarksynthError, match=r"out.*a\.png.*is the input.*a\.png"):
        check_output_location(image, tmp_path / "sub" / ".." / "a.png")


def test_check_output_location_refuses_same_file_through_a_link(tmp_path: Path) -> None:
    image = _touch(tmp_path / "a.png")
    (tmp_path / "link.png").symlink_to(image)
    with pytest.raises(DarksynthError, match="is the input"):
        check_output_location(image, tmp_path / "link.png")


def test_check_output_location_refuses_output_inside_input_folder(tmp_path: Path) -> None:
    _touch(tmp_path / "in" / "a.png")
    with pytest.raises(DarksynthError, match=r"inside the input folder") as info:
        check_output_location(tmp_path / "in", tmp_path / "in" / "dark")
    assert str(tmp_path / "in" / "dark") in str(info.value)
    with pytest.raises(DarksynthError, match="is the input"):
        check_output_location(tmp_path / "in", tmp_path / "in")


def test_check_output_location_refuses_kind_mismatch(tmp_path: Path) -> None:
    image = _touch(tmp_path / "in" / "a.png")
    existing_file = _touch(tmp_path / "out.png")
    existing_folder = tmp_path / "outdir"
    existing_folder.mkdir()
    with pytest.raises(DarksynthError, match=r"existing file, but the input .* is a folder"):
        check_output_location(tmp_path / "in", existing_file)
    with pytest.raises(DarksynthError, match=r"existing folder, but the input .* is a file"):
        check_output_location(image, existing_folder)
