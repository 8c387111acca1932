"""Bad inputs: each reported in one line naming the file, the rest converted, the summary counting it, exit 1."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path
from typing import Any

import av
import pytest

from darksynth.apply_outputs import STATE_FOLDER
from darksynth.datasets import MANIFEST_NAME, ConvertOptions, convert_dataset
from darksynth.errors import DarksynthError
from darksynth.profile import load_profile
from darksynth.recipe import ClipRecipe
from tests.command_line import run_cli
from tests.datasets.conftest import tree_bytes, write_image, write_video


def _convert(dataset: Path, output: Path, profile: Path, fmt: str, *extra: str) -> tuple[int, str]:
    code, _, err = run_cli("convert", dataset, output, "--profile", profile, "--format", fmt, *extra)
    assert "Traceback" not in err
    return code, err


def _error_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("darksynth: error:")]


def _no_temp_files(root: Path) -> bool:
    return not [p for p in root.rglob("*") if ".tmp-" in p.name]


def test_coco_entry_without_its_file(coco_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    annotations = coco_dataset / "annotations" / "instances_train2017.json"
    document = json.loads(annotations.read_text())
    document["images"].append({"id": 9, "file_name": "missing.jpg", "width": 64, "height": 48})
    annotations.write_text(json.dumps(document))
    output = tmp_path / "out"
    code, err = _convert(coco_dataset, output, profile_path, "coco")
    assert code == 1
    assert any(str(annotations) in line and "'missing.jpg'" in line for line in _error_lines(err))
    assert "converted 3 file(s)" in err and "1 failure(s)" in err
    assert len(list((output / "train2017").iterdir())) == 3
    manifest = json.loads((output / MANIFEST_NAME).read_text())
    assert [p["file"] for p in manifest["problems"]] == ["annotations/instances_train2017.json"]
    # The annotation file itself is carried over unchanged.
    assert (output / "annotations" / "instances_train2017.json").read_bytes() == annotations.read_bytes()


def test_coco_without_annotation_file_is_refused(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    code, err = _convert(folder_dataset, tmp_path / "out", profile_path, "coco")
    assert code == 1 and len(_error_lines(err)) == 1 and "no COCO annotation file" in err
    assert not (tmp_path / "out").exists()


def test_yolo_label_without_image(yolo_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    ghost = yolo_dataset / "labels" / "train" / "ghost.txt"
    ghost.write_text("0 0.5 0.5 0.1 0.1\n")
    code, err = _convert(yolo_dataset, tmp_path / "out", profile_path, "yolo")
    assert code == 1
    (line,) = _error_lines(err)[:1]
    assert str(ghost) in line and "label without an image" in line
    assert "converted 4 file(s)" in err and "1 failure(s)" in err


def test_names_differing_only_in_case(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    write_image(folder_dataset / "cat" / "Pic.png", 1)
    write_image(folder_dataset / "cat" / "pic.png", 2)
    output = tmp_path / "out"
    code, err = _convert(folder_dataset, output, profile_path, "folder")
    assert code == 1
    lines = _error_lines(err)
    assert any("cat/Pic.png" in line and "differs only in case" in line for line in lines)
    assert any("cat/pic.png" in line and "differs only in case" in line for line in lines)
    assert not (output / "cat" / "Pic.png").exists() and not (output / "cat" / "pic.png").exists()
    assert (output / "cat" / "0.png").is_file() and "converted 4 file(s)" in err and "2 failure(s)" in err


def test_output_under_a_file_is_one_line_before_any_work(
    folder_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    code, err = _convert(folder_dataset, blocker / "out", profile_path, "folder")
    assert code == 1
    (line,) = _error_lines(err)
    assert "cannot write the output folder" in line and str(blocker) in line


def test_read_only_output_folder(
    folder_dataset: Path, profile_path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    real_mkdir = Path.mkdir

    def refusing_mkdir(self: Path, *args: Any, **kwargs: Any) -> None:
        # Root (as on CI) ignores the mode bits: refuse as the kernel does for everyone else.
        if self.is_relative_to(locked):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))
        real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", refusing_mkdir)
    try:
        code, err = _convert(folder_dataset, locked / "out", profile_path, "folder")
    finally:
        locked.chmod(0o700)
    assert code == 1
    (line,) = _error_lines(err)
    assert "cannot write the output folder" in line and str(locked / "out") in line


def test_video_failing_half_way_leaves_no_file(
    video_dataset: Path, profile_path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Frames 0-2 decode, frame 3 does not (as a damaged stream): the conversion of that video stops cleanly."""
    broken = write_video(video_dataset / "videos" / "broken.mp4", seed=1)
    real_decode = av.container.InputContainer.decode

    def failing_decode(self: av.container.InputContainer, *args: object, **kwargs: object) -> object:
        for index, frame in enumerate(real_decode(self, *args, **kwargs)):  # type: ignore[arg-type]
            if self.name == str(broken) and index == 3:
                raise av.InvalidDataError(1094995529, "Invalid data found when processing input")
            yield frame

    monkeypatch.setattr(av.container.InputContainer, "decode", failing_decode)
    output = tmp_path / "out"
    code, err = _convert(video_dataset, output, profile_path, "video-folder")
    assert code == 1
    (line,) = _error_lines(err)[:1]
    assert str(broken) in line and "frame 3" in line
    assert not (output / "videos" / "broken.mp4").exists()
    assert (output / "videos" / "walk.mp4").is_file() and (output / "JPEGImages" / "bear" / "00000.jpg").is_file()
    assert _no_temp_files(output)
    manifest = json.loads((output / MANIFEST_NAME).read_text())
    assert [f["input"] for f in manifest["failures"]] == ["videos/broken.mp4"]


def test_unreadable_image_reported_rest_converted(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    (folder_dataset / "dog" / "bad.jpg").write_bytes(b"\xff\xd8 truncated")
    output = tmp_path / "out"
    code, err = _convert(folder_dataset, output, profile_path, "folder")
    assert code == 1 and "dog/bad.jpg" in _error_lines(err)[0]
    assert not (output / "dog" / "bad.jpg").exists() and (output / "dog" / "0.jpg").is_file()


def test_rerun_with_other_options_is_refused_unless_overwrite(
    folder_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    output = tmp_path / "out"
    assert _convert(folder_dataset, output, profile_path, "folder")[0] == 0
    before = (output / "cat" / "0.png").read_bytes()
    code, err = _convert(folder_dataset, output, profile_path, "folder", "--seed", "9")
    assert code == 1 and "other options (seed)" in err and len(_error_lines(err)) == 1
    assert (output / "cat" / "0.png").read_bytes() == before
    code, err = _convert(folder_dataset, output, profile_path, "folder", "--seed", "9", "--overwrite")
    assert code == 0, err
    assert "4 new" in err and (output / "cat" / "0.png").read_bytes() != before


def test_foreign_non_empty_output_is_refused(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    output.mkdir()
    (output / "mine.txt").write_text("keep me")
    code, err = _convert(folder_dataset, output, profile_path, "folder")
    assert code == 1 and "not empty" in err
    assert (output / "mine.txt").read_text() == "keep me"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--shard", "3/2"), "--shard must be K/N"),
        (("--shard", "x"), "--shard must be K/N"),
        (("--format", "voc"), "--format must be one of"),
    ],
)
def test_bad_options(
    folder_dataset: Path, profile_path: Path, tmp_path: Path, extra: tuple[str, ...], message: str
) -> None:
    args = ("convert", folder_dataset, tmp_path / "out", "-p", profile_path)
    args += extra if "--format" in extra else ("--format", "folder", *extra)
    code, _, err = run_cli(*args)
    assert code == 1 and message in err and "Traceback" not in err


def test_output_inside_dataset_is_refused(folder_dataset: Path, profile_path: Path) -> None:
    with pytest.raises(DarksynthError, match="inside the input folder"):
        convert_dataset(
            ConvertOptions(folder_dataset, folder_dataset / "out", ClipRecipe(load_profile(profile_path)), "folder")
        )


def test_video_options_do_not_block_the_resume_of_an_image_dataset(
    folder_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    output = tmp_path / "out"
    assert _convert(folder_dataset, output, profile_path, "folder", "--pix-fmt", "yuv444p", "--crf", "4")[0] == 0

    def media(root: Path) -> dict[str, bytes]:
        return {k: v for k, v in tree_bytes(root).items() if k != MANIFEST_NAME and not k.startswith(STATE_FOLDER)}

    before = media(output)
    # Other video options cannot change an image: the same conversion, resumed with nothing to do.
    code, err = _convert(folder_dataset, output, profile_path, "folder", "--codec", "ffv1")
    assert code == 0, err
    assert "0 new" in err and media(output) == before


def test_a_conversion_recorded_before_an_option_existed_resumes_at_its_default(
    folder_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    output = tmp_path / "out"
    assert _convert(folder_dataset, output, profile_path, "folder", "--seed", "4")[0] == 0
    state_path = output / STATE_FOLDER / "convert-state.json"
    state = json.loads(state_path.read_text())
    # As an earlier version wrote it: without the newer options, and hashed over what it had.
    del state["options"]["images_root"]
    state["hash"] = "written-by-an-earlier-version"
    state_path.write_text(json.dumps(state))
    code, err = _convert(folder_dataset, output, profile_path, "folder", "--seed", "4")
    assert code == 0 and "0 new" in err, err
    assert json.loads(state_path.read_text())["options"]["images_root"] is None  # rewritten in this version's form
    code, err = _convert(folder_dataset, output, profile_path, "folder", "--seed", "5")
    assert code == 1 and "other options (seed)" in err


def test_video_options_still_decide_a_video_datasets_resume(
    video_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    output = tmp_path / "out"
    assert _convert(video_dataset, output, profile_path, "video-folder", "--crf", "10")[0] == 0
    code, err = _convert(video_dataset, output, profile_path, "video-folder", "--crf", "20")
    assert code == 1 and "other options (crf)" in err and len(_error_lines(err)) == 1
