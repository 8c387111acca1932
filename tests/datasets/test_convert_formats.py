"""``convert_dataset`` per format: media converted in place of the originals, annotations carried over and valid."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from darksynth.apply import task_seed
from darksynth.datasets import (
    MANIFEST_NAME,
    ConvertOptions,
    MediaItem,
    convert_dataset,
    convert_item,
    plan_dataset,
    record_path,
)
from darksynth.datasets.formats import coco_image_roots, rewrite_yolo_yaml
from darksynth.io.video import VideoWriter, probe_video
from darksynth.profile import load_profile
from darksynth.recipe import ClipRecipe
from tests.datasets.conftest import HEIGHT, WIDTH, write_image


def _manifest(output: Path) -> dict[str, object]:
    return json.loads((output / MANIFEST_NAME).read_text())


def _mean(path: Path) -> float:
    with Image.open(path) as image:
        return float(np.asarray(image.convert("RGB"), dtype=float).mean())


def test_coco_images_converted_annotations_still_valid(coco_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    report = convert_dataset(
        ConvertOptions(coco_dataset, output, ClipRecipe(load_profile(profile_path)), "coco", seed=1)
    )
    assert report.failures == [] and report.converted == 3 and report.carried == 2
    annotations = "annotations/instances_train2017.json"
    assert (output / annotations).read_bytes() == (coco_dataset / annotations).read_bytes()
    assert (output / "LICENSE").read_bytes() == (coco_dataset / "LICENSE").read_bytes()
    for entry in json.loads((output / annotations).read_text())["images"]:
        converted, original = output / "train2017" / entry["file_name"], coco_dataset / "train2017" / entry["file_name"]
        with Image.open(converted) as image:
            assert image.format == "JPEG"
            assert image.size == (entry["width"], entry["height"])
        # The default profile darkens with alpha 0.2.
        assert _mean(converted) < 0.5 * _mean(original)
    manifest = _manifest(output)
    assert [f["input"] for f in manifest["files"]] == [f"train2017/{i:012d}.jpg" for i in range(3)]
    assert manifest["problems"] == [] and manifest["failures"] == []
    # Seeds come from the run seed and the relative path, as in apply.
    assert manifest["files"][0]["seed"] == task_seed(1, "train2017/000000000000.jpg")


def test_yolo_labels_copied_and_yaml_points_at_output(yolo_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    report = convert_dataset(ConvertOptions(yolo_dataset, output, ClipRecipe(load_profile(profile_path)), "yolo"))
    assert report.failures == [] and report.converted == 4
    for label in (yolo_dataset / "labels").rglob("*.txt"):
        assert (output / label.relative_to(yolo_dataset)).read_bytes() == label.read_bytes()
    for image in (yolo_dataset / "images").rglob("*.jpg"):
        with Image.open(image) as before, Image.open(output / image.relative_to(yolo_dataset)) as after:
            assert (after.format, after.size) == (before.format, before.size)
    rewritten = (output / "data.yaml").read_text()
    document = yaml.safe_load(rewritten)
    assert document["path"] == str(output.resolve())
    assert (document["train"], document["val"], document["names"]) == ("images/train", "images/val", {0: "thing"})
    assert rewritten.startswith("# a YOLO dataset\n")
    assert {"file": "data.yaml", "action": "yolo-yaml"} in _manifest(output)["carried"]


def test_rewrite_yolo_yaml_remaps_absolute_splits_only(tmp_path: Path) -> None:
    dataset, output = tmp_path / "ds", tmp_path / "out"
    text = f"train: {dataset / 'images/train'}\nval: images/val\ntest: /elsewhere/x\n"
    document = yaml.safe_load(rewrite_yolo_yaml(text, dataset, output))
    assert document == {"train": str(output / "images/train"), "val": "images/val", "test": "/elsewhere/x"}


def test_rewrite_yolo_yaml_keeps_inline_comments(tmp_path: Path) -> None:
    dataset, output = tmp_path / "ds", tmp_path / "out"
    text = (
        "path: ../coco  # dataset root dir\n"
        f"train: {dataset / 'images/train'} # 118k images\n"
        "val: 'images/val # not a comment'  # quoted\n"
        "names: {0: person}\n"
    )
    lines = rewrite_yolo_yaml(text, dataset, output).splitlines()
    assert lines[0] == f"path: {json.dumps(str(output.resolve()))}  # dataset root dir"
    assert lines[1] == f"train: {json.dumps(str(output.resolve() / 'images/train'))} # 118k images"
    assert lines[2] == "val: 'images/val # not a comment'  # quoted"
    assert yaml.safe_load("\n".join(lines))["val"] == "images/val # not a comment"


def test_folder_mirrors_tree(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    report = convert_dataset(ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(profile_path)), "folder"))
    assert report.converted == 4 and report.failures == []
    visible = sorted(p.relative_to(output).as_posix() for p in output.rglob("*") if p.is_file())
    visible = [p for p in visible if not p.startswith(".darksynth/")]
    assert visible == sorted(["README.md", "cat/0.png", "cat/1.png", "dog/0.jpg", "dog/1.jpg", MANIFEST_NAME])
    with Image.open(output / "cat/0.png") as image:
        assert (image.format, image.size, image.mode) == ("PNG", (WIDTH, HEIGHT), "RGB")


def test_video_folder_videos_and_clips_converted_masks_copied(
    video_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    output = tmp_path / "out"
    report = convert_dataset(
        ConvertOptions(video_dataset, output, ClipRecipe(load_profile(profile_path)), "video-folder")
    )
    assert report.failures == [] and report.converted == 2
    before, after = probe_video(video_dataset / "videos/walk.mp4"), probe_video(output / "videos/walk.mp4")
    assert (after.width, after.height, after.frame_count, after.fps) == (WIDTH, HEIGHT, 6, Fraction(25))
    assert before.frame_count == after.frame_count
    for mask in (video_dataset / "Annotations").rglob("*.png"):
        assert (output / mask.relative_to(video_dataset)).read_bytes() == mask.read_bytes()
    files = {f["input"]: f for f in _manifest(output)["files"]}
    assert set(files) == {"JPEGImages/bear/", "videos/walk.mp4"}
    assert files["JPEGImages/bear/"]["kind"] == "clip" and files["JPEGImages/bear/"]["frames"] == 3
    for frame in (video_dataset / "JPEGImages").rglob("*.jpg"):
        assert _mean(output / frame.relative_to(video_dataset)) < 0.5 * _mean(frame)


def test_palette_frames_are_masks_wherever_they_lie(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    write_image(root / "clips" / "a" / "0.png", 0)
    labels = np.zeros(WIDTH * HEIGHT, dtype=np.uint8)
    (root / "segs" / "a").mkdir(parents=True)
    Image.frombytes("P", (WIDTH, HEIGHT), labels.tobytes()).save(root / "segs" / "a" / "0.png")
    plan = plan_dataset(root, "video-folder")
    assert [i.key for i in plan.items] == ["clips/a/"]
    assert [c.key for c in plan.carried] == ["segs/a/0.png"]


def test_video_encoding_is_deterministic(tmp_path: Path) -> None:
    """Byte-identical resumes need an encoder that gives the same bytes for the same frames."""
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 256, (HEIGHT, WIDTH, 3), dtype=np.uint8) for _ in range(12)]
    encoded = []
    for name in ("a.mp4", "b.mp4"):
        with VideoWriter(tmp_path / name, width=WIDTH, height=HEIGHT, fps=Fraction(25)) as writer:
            for frame in frames:
                writer.write(frame)
        encoded.append((tmp_path / name).read_bytes())
    assert encoded[0] == encoded[1]


def test_without_jitter_every_file_gets_the_profile_values(
    folder_dataset: Path, ranged_profile: Path, tmp_path: Path
) -> None:
    output = tmp_path / "out"
    convert_dataset(ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(ranged_profile)), "folder"))
    parameters = [f["parameters"] for f in _manifest(output)["files"]]
    assert all(p == parameters[0] for p in parameters)
    profile = load_profile(ranged_profile)
    assert parameters[0]["noise"]["shot"] == profile.noise["shot"][0]
    assert parameters[0]["darkening"] == {"alpha": 0.2, "gamma": 0.7}


def test_jitter_draws_per_file_within_ranges(folder_dataset: Path, ranged_profile: Path, tmp_path: Path) -> None:
    output = tmp_path / "out"
    convert_dataset(
        ConvertOptions(folder_dataset, output, ClipRecipe(load_profile(ranged_profile), jitter=True), "folder", seed=5)
    )
    manifest = _manifest(output)
    assert manifest["jitter"] is True
    shots = [f["parameters"]["noise"]["shot"] for f in manifest["files"]]
    alphas = [f["parameters"]["darkening"]["alpha"] for f in manifest["files"]]
    assert len(set(shots)) == len(shots) == 4 and len(set(alphas)) == 4
    assert all(0.03 <= s <= 0.09 for s in shots) and all(0.1 <= a <= 0.3 for a in alphas)
    # Parameters without a range stay at the profile's value.
    assert {f["parameters"]["noise"]["read"] for f in manifest["files"]} == {0.012}


def test_convert_item_on_a_row_writes_its_record(folder_dataset: Path, profile_path: Path, tmp_path: Path) -> None:
    """The per-row function another scheduler (Ray Data) maps over the plan's items."""
    output = (tmp_path / "out").resolve()
    plan = plan_dataset(folder_dataset, "folder")
    options = ConvertOptions(
        recipe=ClipRecipe(load_profile(profile_path)), dataset=folder_dataset.resolve(), output=output, format="folder"
    )
    options = pickle.loads(pickle.dumps(options))
    row = plan.items[0].to_row()
    assert MediaItem.from_row(row) == plan.items[0]
    record = convert_item(row, options)
    assert record["status"] == "done" and record["outputs"] == ["cat/0.png"]
    assert json.loads(record_path(output, "cat/0.png").read_text()) == record
    assert (output / "cat/0.png").is_file()
    # The same bytes as the whole-dataset run.
    full = tmp_path / "full"
    convert_dataset(ConvertOptions(folder_dataset, full, ClipRecipe(load_profile(profile_path)), "folder"))
    assert (full / "cat/0.png").read_bytes() == (output / "cat/0.png").read_bytes()


def test_convert_item_reports_a_bad_file_as_a_failed_record(tmp_path: Path, profile_path: Path) -> None:
    dataset = tmp_path / "ds"
    dataset.mkdir()
    (dataset / "broken.png").write_bytes(b"not a png")
    options = ConvertOptions(
        recipe=ClipRecipe(load_profile(profile_path)),
        dataset=dataset.resolve(),
        output=(tmp_path / "out").resolve(),
        format="folder",
    )
    record = convert_item(MediaItem("image", "broken.png", ("broken.png",)), options)
    assert record["status"] == "failed" and "broken.png" in record["error"]
    assert not (tmp_path / "out" / "broken.png").exists()


@pytest.mark.parametrize(
    ("json_key", "expected_first"),
    [("annotations/instances_val2017.json", "val2017"), ("labels.json", "."), ("a/b/c.json", ".")],
)
def test_coco_image_roots_prefer_the_named_sibling(json_key: str, expected_first: str) -> None:
    folders = ["train2017", "val2017", "annotations", "a/b", "images"]
    roots = coco_image_roots(json_key, folders)
    assert roots[0] == expected_first
    assert len(roots) == len(set(roots))
    assert coco_image_roots(json_key, folders, "images")[0] == "images"


def test_coco_images_root_resolves_flat_file_names(tmp_path: Path, profile_path: Path) -> None:
    root = tmp_path / "ds"
    write_image(root / "pictures" / "deep" / "a.png", 0)
    document = {"images": [{"id": 1, "file_name": "a.png", "width": WIDTH, "height": HEIGHT}], "annotations": []}
    (root / "meta").mkdir()
    (root / "meta" / "set.json").write_text(json.dumps(document))
    assert len(plan_dataset(root, "coco").problems) == 1
    assert plan_dataset(root, "coco", images_root=Path("pictures/deep")).problems == ()
    assert plan_dataset(root, "coco", images_root=root / "pictures" / "deep").problems == ()


def test_library_imports_without_the_command_line_stack() -> None:
    """Workers of other schedulers (Ray) import darksynth.datasets without rich or typer."""
    code = "import sys, darksynth.datasets; print(sorted({'rich', 'typer'} & set(sys.modules)))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
