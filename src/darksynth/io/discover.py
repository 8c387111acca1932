"""Deciding what an input path is, listing the media in a folder, and refusing outputs that would clobber inputs."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from darksynth.errors import DarksynthError, InputFileError
from darksynth.io.images import IMAGE_SUFFIXES
from darksynth.io.video import VIDEO_SUFFIXES

__all__ = ["FolderListing", "InputKind", "check_output_location", "classify_input", "scan_folder"]

InputKind = Literal["image", "video", "folder"]


@dataclass(frozen=True)
class FolderListing:
    """The files found under a folder, as paths relative to it, each list sorted.

    Attributes:
        images: Files with an image suffix (see ``IMAGE_SUFFIXES``).
        videos: Files with a video suffix (see ``VIDEO_SUFFIXES``).
        skipped: Other files, and links to folders (which are not followed), for the user to be told about.
            Hidden files and folders (name starting with ``.``) are left out of every list.
    """

    images: list[Path]
    videos: list[Path]
    skipped: list[Path]


def classify_input(path: Path) -> InputKind:
    """Tell whether a path is an image, a video or a folder, by its suffix (case-insensitive) or by being a folder.

    The file's content is not read; :func:`~darksynth.io.images.read_image` and
    :func:`~darksynth.io.video.probe_video` report a file whose content does not match its suffix.

    Args:
        path: The input path given by the user.

    Returns:
        ``"folder"``, ``"image"`` or ``"video"``.

    Raises:
        InputFileError: If nothing exists at the path, or the suffix is neither an image nor a video suffix.
    """
    if path.is_dir():
        return "folder"
    if not path.exists():
        raise InputFileError(path, "no such file or folder")
    kind = _kind_of(path)
    if kind is None:
        raise InputFileError(
            path, f"not an image ({_listed(IMAGE_SUFFIXES)}) or video ({_listed(VIDEO_SUFFIXES)}) file"
        )
    return kind


def scan_folder(root: Path) -> FolderListing:
    """List the images and videos under a folder, recursively.

    Hidden files and folders are skipped silently: they include the temporary files of interrupted runs. Links to
    files are listed like files; links to folders are not followed (they could form a cycle) and go to
    ``skipped``.

    Args:
        root: The folder to scan.

    Returns:
        The files found, relative to ``root``, sorted.

    Raises:
        InputFileError: If ``root`` is not a folder, or holds no images and no videos.
    """
    if not root.is_dir():
        raise InputFileError(root, "no such folder" if not root.exists() else "not a folder")
    images: list[Path] = []
    videos: list[Path] = []
    skipped: list[Path] = []
    buckets = {"image": images, "video": videos}

    def _raise(err: OSError) -> None:
        raise InputFileError(err.filename or root, f"cannot list folder ({err.strerror or err})")

    for folder, dir_names, file_names in os.walk(root, onerror=_raise):
        base = Path(folder)
        dir_names[:] = [name for name in dir_names if not name.startswith(".")]
        for name in dir_names:
            if (base / name).is_symlink():
                skipped.append((base / name).relative_to(root))
        for name in file_names:
            if name.startswith("."):
                continue
            path = base / name
            kind = _kind_of(path)
            bucket = skipped if kind is None or not path.is_file() else buckets[kind]
            bucket.append(path.relative_to(root))
    if not images and not videos:
        raise InputFileError(root, "no images or videos found")
    return FolderListing(images=sorted(images), videos=sorted(videos), skipped=sorted(skipped))


def check_output_location(input_path: Path, output_path: Path) -> None:
    """Refuse an output location that would overwrite or mix with the input, or does not fit its kind.

    Both paths are resolved (symbolic links followed) before they are compared. Refused:

    - output and input are the same file or folder;
    - input is a folder and output is inside it (a later run would read the outputs as inputs);
    - input is a folder and output is an existing file;
    - input is a file and output is an existing folder.

    Args:
        input_path: The input file or folder.
        output_path: The output file or folder (it need not exist yet).

    Raises:
        DarksynthError: Naming both paths, if the output location is refused.
    """
    source = input_path.resolve()
    target = output_path.resolve()
    if target == source:
        raise DarksynthError(f"output {output_path} is the input {input_path} itself; choose another output path")
    if source.is_dir():
        if target.is_relative_to(source):
            raise DarksynthError(f"output {output_path} is inside the input folder {input_path}; choose one outside it")
        if target.is_file():
            raise DarksynthError(
                f"output {output_path} is an existing file, but the input {input_path} is a folder; give a folder"
            )
    elif target.is_dir():
        raise DarksynthError(
            f"output {output_path} is an existing folder, but the input {input_path} is a file; give a file path"
        )


def _kind_of(path: Path) -> Literal["image", "video"] | None:
    suffix = path.suffix.lower()
    if suffix in IMAGE_SUFFIXES:
        return "image"
    if suffix in VIDEO_SUFFIXES:
        return "video"
    return None


def _listed(suffixes: frozenset[str]) -> str:
    return " ".join(sorted(suffixes))
