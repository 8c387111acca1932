"""What a dataset holds, by format: the media to convert, the files to carry over, and the problems found.

Planning reads the tree and the annotation files, never writes. Every path is relative to the dataset root, in
POSIX form, so that plans, seeds, shards and manifests do not depend on where the dataset lies.

Format rules:

- ``folder``: every image and video is converted; every other file is copied (class-per-folder, ImageNet style).
- ``coco``: as ``folder``, and each JSON file with ``images`` and ``annotations`` lists is checked: every
  ``images[].file_name`` must resolve to a file of the dataset (see :func:`coco_image_roots`). Images under a
  mask folder (:data:`MASK_FOLDER_NAMES`) are copied, not converted.
- ``yolo``: as ``folder``; each label (a ``.txt`` file under a folder named ``labels``, other than
  ``classes.txt``) must have an image at the same path under ``images`` instead of ``labels``; each dataset YAML
  (``*.yaml``/``*.yml`` whose top level has ``path``, ``train`` or ``val``) is rewritten to point at the output.
- ``video-folder``: videos are converted; each folder of images is one clip (its frames share parameters and
  temporal banding), unless it is a mask folder: under a folder named in :data:`MASK_FOLDER_NAMES`
  (DAVIS/YouTube-VOS ``Annotations/``), or its first image is a palette PNG (how those datasets store masks).
  Mask folders are copied unchanged.

In every format, hidden files and folders (name starting with ``.``) are left out, and two paths that differ
only in case are both reported and neither is written: they would overwrite each other on a case-insensitive
file system.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, Final, Literal, get_args

import PIL.Image

from darksynth.apply import Task, TaskKind
from darksynth.errors import DarksynthError, InputFileError
from darksynth.io.images import IMAGE_SUFFIXES
from darksynth.io.video import VIDEO_SUFFIXES

__all__ = [
    "FORMATS",
    "MASK_FOLDER_NAMES",
    "CarriedFile",
    "DatasetFormat",
    "DatasetPlan",
    "MediaItem",
    "Problem",
    "coco_image_roots",
    "plan_dataset",
    "rewrite_yolo_yaml",
]

DatasetFormat = Literal["coco", "yolo", "folder", "video-folder"]
FORMATS: Final[tuple[str, ...]] = get_args(DatasetFormat)

MASK_FOLDER_NAMES: Final[frozenset[str]] = frozenset(
    {"annotations", "annotation", "masks", "mask", "gt", "groundtruth", "ground_truth", "segmentations"}
)
"""Folder names (compared case-insensitively) whose images are annotations, not pictures (coco, video-folder)."""

YAML_SUFFIXES: Final[frozenset[str]] = frozenset({".yaml", ".yml"})
_YOLO_YAML_KEYS: Final[frozenset[str]] = frozenset({"path", "train", "val"})
_YOLO_SPLIT_KEYS: Final[tuple[str, ...]] = ("train", "val", "test")
_TOP_LEVEL_ENTRY = re.compile(r"^(?P<key>[A-Za-z_][\w-]*)\s*:\s*(?P<value>.*?)\s*$")


@dataclass(frozen=True)
class MediaItem:
    """One unit of conversion: an image, a video, or a folder of frames converted as one clip.

    Attributes:
        kind: ``"image"``, ``"video"`` or ``"clip"``.
        key: the item's identity: its relative path (``"folder/"`` for a clip); seeds and shards derive from it.
        inputs: relative paths of its files (a clip's frames in order); each output has the same relative path.
    """

    kind: TaskKind
    key: str
    inputs: tuple[str, ...]

    def task(self, dataset: Path, output: Path) -> Task:
        """The ``apply`` task that converts this item from ``dataset`` into ``output``."""
        return Task(
            self.kind, self.key, tuple(dataset / p for p in self.inputs), tuple(output / p for p in self.inputs)
        )

    def to_row(self) -> dict[str, Any]:
        """A plain dict (one row of a Ray Dataset, one line of JSON)."""
        return {"kind": self.kind, "key": self.key, "inputs": list(self.inputs)}

    @classmethod
    def from_row(cls, row: dict[str, Any]) -> MediaItem:
        """The inverse of :meth:`to_row` (accepts any sequence for ``inputs``)."""
        return cls(kind=row["kind"], key=str(row["key"]), inputs=tuple(str(p) for p in row["inputs"]))


@dataclass(frozen=True)
class CarriedFile:
    """A file carried over to the output: copied byte for byte, or (``"yolo-yaml"``) rewritten."""

    key: str
    action: Literal["copy", "yolo-yaml"] = "copy"


@dataclass(frozen=True)
class Problem:
    """A bad input found while planning: ``key`` is the file it belongs to (for sharding), ``message`` one line."""

    key: str
    message: str


@dataclass(frozen=True)
class DatasetPlan:
    """Everything a conversion will do, each tuple sorted by key."""

    format: DatasetFormat
    items: tuple[MediaItem, ...]
    carried: tuple[CarriedFile, ...]
    problems: tuple[Problem, ...]


def plan_dataset(dataset: Path, format: DatasetFormat, *, images_root: Path | None = None) -> DatasetPlan:
    """List what converting ``dataset`` as ``format`` involves (see the module docstring for the rules).

    Args:
        dataset: the dataset's root folder.
        format: one of :data:`FORMATS`.
        images_root: COCO only: the folder (inside ``dataset``; if relative, relative to ``dataset`` or else to
            the working folder) that ``file_name`` entries are relative to, tried before the usual places.

    Returns:
        The plan; bad inputs that do not stop the run are in ``problems``.

    Raises:
        DarksynthError: the dataset is not a readable folder, the format is unknown, or the dataset holds nothing
            of the format (no media, no COCO annotation file, no YOLO label).
    """
    if format not in FORMATS:
        raise DarksynthError(f"unknown dataset format {format!r}; use one of {', '.join(FORMATS)}")
    all_files = _list_files(dataset)
    problems = _case_collisions(dataset, all_files)
    colliding = {p.key for p in problems}
    files = [f for f in all_files if f not in colliding]
    media = [f for f in files if _suffix(f) in IMAGE_SUFFIXES | VIDEO_SUFFIXES]
    media_set = set(media)
    others = [f for f in files if f not in media_set]

    carried = [CarriedFile(f) for f in others]
    items: list[MediaItem]
    if format == "video-folder":
        items, masks = _video_folder_items(dataset, media)
        carried += [CarriedFile(f) for f in masks]
    else:
        masks = [f for f in media if format == "coco" and _suffix(f) in IMAGE_SUFFIXES and _in_mask_folder(f)]
        mask_set = set(masks)
        carried += [CarriedFile(f) for f in masks]
        items = [
            MediaItem("image" if _suffix(f) in IMAGE_SUFFIXES else "video", f, (f,)) for f in media if f not in mask_set
        ]
    if format == "coco":
        problems += _check_coco(dataset, all_files, images_root)
    elif format == "yolo":
        problems += _check_yolo(dataset, all_files)
        yamls = {f for f in others if _suffix(f) in YAML_SUFFIXES and _is_yolo_yaml(dataset / f)}
        carried = [CarriedFile(c.key, "yolo-yaml") if c.key in yamls else c for c in carried]
    if not items:
        raise InputFileError(dataset, f"no images or videos to convert as a {format} dataset")
    return DatasetPlan(
        format=format,
        items=tuple(sorted(items, key=lambda i: i.key)),
        carried=tuple(sorted(carried, key=lambda c: c.key)),
        problems=tuple(sorted(problems, key=lambda p: (p.key, p.message))),
    )


def _list_files(root: Path) -> list[str]:
    if not root.is_dir():
        raise InputFileError(root, "no such folder" if not root.exists() else "not a folder")
    found: list[str] = []

    def _raise(err: OSError) -> None:
        raise InputFileError(err.filename or root, f"cannot list folder ({err.strerror or err})")

    # Links to folders are not followed (os.walk's default): they could form a cycle.
    for folder, dir_names, file_names in os.walk(root, onerror=_raise):
        dir_names[:] = sorted(n for n in dir_names if not n.startswith("."))
        base = Path(folder)
        found.extend(
            (base / n).relative_to(root).as_posix()
            for n in file_names
            if not n.startswith(".") and (base / n).is_file()
        )
    return sorted(found)


def _case_collisions(dataset: Path, files: list[str]) -> list[Problem]:
    groups: dict[str, list[str]] = {}
    for name in files:
        groups.setdefault(name.casefold(), []).append(name)
    problems = []
    for group in groups.values():
        if len(group) < 2:
            continue
        for name in group:
            others = ", ".join(o for o in group if o != name)
            problems.append(
                Problem(
                    name,
                    f"{dataset / name}: differs only in case from {others}; neither is written (they would "
                    "collide on a case-insensitive file system)",
                )
            )
    return problems


def _suffix(name: str) -> str:
    return PurePosixPath(name).suffix.lower()


def _in_mask_folder(name: str) -> bool:
    return any(part.casefold() in MASK_FOLDER_NAMES for part in PurePosixPath(name).parts[:-1])


def _video_folder_items(dataset: Path, media: list[str]) -> tuple[list[MediaItem], list[str]]:
    items = [MediaItem("video", f, (f,)) for f in media if _suffix(f) in VIDEO_SUFFIXES]
    by_folder: dict[str, list[str]] = {}
    for name in media:
        if _suffix(name) in IMAGE_SUFFIXES:
            by_folder.setdefault(PurePosixPath(name).parent.as_posix(), []).append(name)
    masks: list[str] = []
    for folder, frames in sorted(by_folder.items()):
        frames.sort()
        if _in_mask_folder(frames[0]) or _is_palette_png(dataset / frames[0]):
            masks.extend(frames)
        else:
            items.append(MediaItem("clip", folder + "/", tuple(frames)))
    return items, masks


def _is_palette_png(path: Path) -> bool:
    try:
        with PIL.Image.open(path) as image:
            return image.format == "PNG" and image.mode == "P"
    except (OSError, SyntaxError, ValueError):
        return False  # an unreadable frame is reported when its clip is converted


def coco_image_roots(json_key: str, folders: Iterable[str], images_root: str | None = None) -> list[str]:
    """The folders, in order of preference, that a COCO file's ``file_name`` entries may be relative to.

    COCO lays out ``annotations/instances_train2017.json`` beside ``train2017/``: after ``images_root``, sibling
    folders of the JSON's folder whose name is a word of the JSON's name (split at ``_``, ``-``, ...) come first,
    then the dataset root, the JSON's own folder, its other siblings and its sub-folders.

    Args:
        json_key: the JSON file's relative path.
        folders: every folder of the dataset that holds files, relative (``"."`` for the root).
        images_root: the user's explicit root, relative to the dataset.

    Returns:
        Relative folders (``"."`` for the dataset root), without repeats.
    """
    json_path = PurePosixPath(json_key)
    home = json_path.parent
    words = set(re.split(r"[^0-9a-z]+", json_path.stem.casefold()))
    folder_set = {PurePosixPath(f) for f in folders}
    known = {p for f in folder_set for p in (f, *f.parents)}
    siblings = sorted(f for f in known if f.parent == home.parent and f != home and f != PurePosixPath("."))
    children = sorted(f for f in known if f.parent == home and f != home)
    named = [s for s in siblings if s.name.casefold() in words]
    ordered = [PurePosixPath(images_root)] if images_root is not None else []
    ordered += [*named, PurePosixPath("."), home, *siblings, *children]
    return list(dict.fromkeys(folder.as_posix() for folder in ordered))


def _check_coco(dataset: Path, files: list[str], images_root: Path | None) -> list[Problem]:
    root_key: str | None = None
    if images_root is not None:
        # A relative root is taken relative to the dataset, else (as typed in a shell) to the working folder.
        absolute = images_root
        if not images_root.is_absolute() and (dataset / images_root).is_dir():
            absolute = dataset / images_root
        try:
            root_key = absolute.resolve().relative_to(dataset.resolve()).as_posix()
        except ValueError:
            raise DarksynthError(f"--images-root {images_root} is not inside the dataset {dataset}") from None
        if not absolute.is_dir():
            raise InputFileError(images_root, "--images-root is not a folder")
    file_set = set(files)
    folders = {PurePosixPath(f).parent.as_posix() for f in files}
    problems: list[Problem] = []
    annotation_files = 0
    for key in files:
        if _suffix(key) != ".json":
            continue
        try:
            document = json.loads((dataset / key).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
            problems.append(Problem(key, f"{dataset / key}: not readable as JSON ({error}); copied unchanged"))
            continue
        if not (isinstance(document, dict) and isinstance(document.get("images"), list)):
            continue
        if not isinstance(document.get("annotations"), list):
            continue
        annotation_files += 1
        roots = coco_image_roots(key, folders, root_key)
        for index, entry in enumerate(document["images"]):
            name = entry.get("file_name") if isinstance(entry, dict) else None
            if not isinstance(name, str) or not name:
                problems.append(Problem(key, f"{dataset / key}: images[{index}] has no file_name"))
                continue
            candidates = (PurePosixPath(r, name).as_posix() for r in roots)
            if not any(c in file_set for c in candidates):
                problems.append(
                    Problem(key, f"{dataset / key}: images[{index}] file_name {name!r}: no such file in the dataset")
                )
    if annotation_files == 0:
        raise InputFileError(dataset, "no COCO annotation file (a .json with images and annotations lists) found")
    return problems


def _check_yolo(dataset: Path, files: list[str]) -> list[Problem]:
    stems = {str(PurePosixPath(f).with_suffix("")) for f in files if _suffix(f) in IMAGE_SUFFIXES}
    problems: list[Problem] = []
    labels = 0
    for key in files:
        path = PurePosixPath(key)
        if path.suffix.lower() != ".txt" or path.name.casefold() == "classes.txt" or "labels" not in path.parts[:-1]:
            continue
        labels += 1
        parts = list(path.with_suffix("").parts)
        # The last "labels" folder pairs with "images" (both images/train/x and train/images/x layouts).
        position = len(parts) - 2 - parts[-2::-1].index("labels")
        parts[position] = "images"
        if str(PurePosixPath(*parts)) not in stems:
            image = PurePosixPath(*parts).as_posix()
            problems.append(Problem(key, f"{dataset / key}: label without an image ({image}.* not found)"))
    if labels == 0:
        raise InputFileError(dataset, "no YOLO labels (.txt files under a labels/ folder) found")
    return problems


def _load_yaml(text: str) -> Any:
    try:
        import yaml
    except ImportError:  # pragma: no cover - PyYAML is a dependency of the datasets feature
        raise DarksynthError("rewriting YOLO dataset files needs PyYAML (pip install pyyaml)") from None
    return yaml.safe_load(text)


def _is_yolo_yaml(path: Path) -> bool:
    try:
        document = _load_yaml(path.read_text(encoding="utf-8"))
    except Exception:  # unreadable, or a YAML syntax error: not a dataset file we can rewrite, so it is copied as is
        return False
    return isinstance(document, dict) and bool(_YOLO_YAML_KEYS & set(document))


def rewrite_yolo_yaml(text: str, dataset: Path, output: Path) -> str:
    """A YOLO dataset YAML for the converted copy: ``path`` set to ``output``, absolute split paths remapped.

    Only top-level lines change; comments, order and relative entries stay as they were, since relative entries
    resolve against ``path`` (or, without it, against the YAML's folder, which is mirrored).

    Args:
        text: the original YAML.
        dataset: the dataset root (absolute split entries inside it are moved under ``output``).
        output: the output root; written as an absolute path.

    Returns:
        The new YAML text.

    Raises:
        DarksynthError: the text is not a YAML mapping.
    """
    if not isinstance(_load_yaml(text), dict):
        raise DarksynthError("not a YAML mapping")
    source, target = dataset.resolve(), output.resolve()
    lines = text.splitlines(keepends=True)
    for index, line in enumerate(lines):
        match = _TOP_LEVEL_ENTRY.match(line.rstrip("\r\n"))
        if match is None:
            continue
        ending = line[len(line.rstrip("\r\n")) :]
        key = match["key"]
        comment = _inline_comment(match["value"])
        if key == "path":
            lines[index] = f"path: {json.dumps(str(target))}{comment}{ending}"
        elif key in _YOLO_SPLIT_KEYS:
            value = _load_yaml(match["value"]) if match["value"] else None
            if isinstance(value, str) and Path(value).is_absolute() and Path(value).is_relative_to(source):
                moved = target / Path(value).relative_to(source)
                lines[index] = f"{key}: {json.dumps(str(moved))}{comment}{ending}"
    return "".join(lines)


def _inline_comment(value: str) -> str:
    """The trailing ``  # comment`` of a YAML value, with the blanks before it, or "" when there is none.

    A ``#`` starts a comment only after a blank and outside quotes; rather than re-implement YAML's quoting, the
    first such ``#`` whose cut leaves a value that YAML reads the same as the whole is the comment's start."""
    whole = _safe_scalar(value)
    for found in re.finditer(r"[ \t]+#", value):
        if _safe_scalar(value[: found.start()]) == whole:
            return value[found.start() :]
    return ""


def _safe_scalar(text: str) -> Any:
    import yaml  # _load_yaml has checked that it is there

    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:  # a cut inside a quoted string is not YAML: that # is not a comment
        return _NOT_YAML


_NOT_YAML = object()
