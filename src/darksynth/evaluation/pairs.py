"""Sets of real noisy/clean pairs: `noisy/NAME` beside `clean/NAME`, optionally `cameras.csv` (name, camera, iso).

The clean image of a pair is the mean of many frames of a static scene, so noisy - clean is the real noise.
Loading a set never stops at a bad pair: each problem is recorded with the file and the reason, and the set
goes on with the pairs that are usable.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.io.images import IMAGE_SUFFIXES, read_image

UNKNOWN_CAMERA = "unknown"


@dataclass(frozen=True)
class Pair:
    """One real pair; ``camera`` is UNKNOWN_CAMERA where cameras.csv does not name it."""

    name: str
    noisy_path: Path
    clean_path: Path
    camera: str = UNKNOWN_CAMERA
    iso: str = ""


@dataclass
class PairSet:
    """A set of pairs named after its folder, and the problems met while listing it."""

    name: str
    root: Path
    pairs: list[Pair] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class LoadedPair:
    """A pair's images as float64 tensors (3, H, W) on the [0, 1] scale, still on their 8-bit levels."""

    pair: Pair
    noisy: torch.Tensor
    clean: torch.Tensor

    @property
    def noise(self) -> torch.Tensor:
        return self.noisy - self.clean


def _cameras(root: Path, problems: list[str]) -> dict[str, tuple[str, str]]:
    table = root / "cameras.csv"
    if not table.is_file():
        return {}
    try:
        with table.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        problems.append(f"{table}: unreadable ({error}); cameras are unknown")
        return {}
    if rows and "name" not in rows[0]:
        problems.append(f"{table}: no 'name' column; cameras are unknown")
        return {}
    return {
        row["name"]: ((row.get("camera") or UNKNOWN_CAMERA).strip(), (row.get("iso") or "").strip()) for row in rows
    }


def _images(folder: Path, problems: list[str]) -> dict[str, Path]:
    found: dict[str, Path] = {}
    for path in sorted(folder.iterdir()):
        if path.name.startswith("."):
            continue
        if path.is_dir():
            problems.append(f"{path}: a folder inside {folder.name}/, skipped")
        elif path.suffix.lower() in IMAGE_SUFFIXES:
            found[path.name] = path
        else:
            problems.append(f"{path}: not an image file, skipped")
    return found


def list_pair_set(root: Path) -> PairSet:
    """List the pairs of a set folder.

    Raises:
        DarksynthError: the folder does not exist or has no noisy/ and clean/ sub-folders (nothing to evaluate).
    """
    if not root.is_dir():
        raise DarksynthError(f"{root}: no such folder of pairs")
    noisy_folder, clean_folder = root / "noisy", root / "clean"
    if not noisy_folder.is_dir() or not clean_folder.is_dir():
        raise DarksynthError(f"{root}: a folder of pairs needs noisy/ and clean/ sub-folders")
    result = PairSet(name=root.resolve().name, root=root)
    noisy = _images(noisy_folder, result.problems)
    clean = _images(clean_folder, result.problems)
    cameras = _cameras(root, result.problems)
    for name, path in noisy.items():
        if name not in clean:
            result.problems.append(f"{path}: no clean partner clean/{name}, skipped")
            continue
        camera, iso = cameras.get(name, (UNKNOWN_CAMERA, ""))
        result.pairs.append(Pair(name=name, noisy_path=path, clean_path=clean[name], camera=camera, iso=iso))
    for name, path in clean.items():
        if name not in noisy:
            result.problems.append(f"{path}: no noisy partner noisy/{name}, skipped")
    return result


def list_pair_sets(roots: Sequence[Path]) -> tuple[list[PairSet], list[str]]:
    """List several sets; a folder that cannot be listed is a problem, not an error, while another can.

    Raises:
        DarksynthError: none of the folders could be listed.
    """
    sets: list[PairSet] = []
    problems: list[str] = []
    for root in roots:
        try:
            sets.append(list_pair_set(root))
        except DarksynthError as error:
            problems.append(str(error))
    if not sets:
        raise DarksynthError("no set of pairs could be read: " + "; ".join(problems))
    return sets, problems


def _as_rgb_unit(path: Path) -> torch.Tensor:
    image = read_image(path)
    scale = 65535.0 if image.pixels.dtype == np.uint16 else 255.0
    pixels = image.pixels.astype(np.float64) / scale
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return torch.from_numpy(np.ascontiguousarray(pixels.transpose(2, 0, 1)))


def load_pair(pair: Pair) -> LoadedPair:
    """Read both images of a pair.

    Raises:
        DarksynthError: an unreadable image, or images of different sizes (named in the message).
    """
    noisy = _as_rgb_unit(pair.noisy_path)
    clean = _as_rgb_unit(pair.clean_path)
    if noisy.shape != clean.shape:
        raise DarksynthError(
            f"{pair.noisy_path}: size {noisy.shape[2]}x{noisy.shape[1]} differs from its clean partner's "
            f"{clean.shape[2]}x{clean.shape[1]}"
        )
    return LoadedPair(pair=pair, noisy=noisy, clean=clean)
