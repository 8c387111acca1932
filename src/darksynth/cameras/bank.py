"""The bank of real cameras shipped in the package: one record per real pair, the spectral model fitted with its
clean image (``scripts/noise/camera_bank.py`` makes it; docs/camera-prior.md)."""

from __future__ import annotations

import functools
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from darksynth.errors import DarksynthError

BANK_PATH = Path(__file__).resolve().parent.parent / "data" / "camera_bank.json"
BANK_FORMAT = "darksynth-camera-bank"
BANK_VERSION = 1


@dataclass(frozen=True)
class CameraRecord:
    """One real pair's fitted noise: the set and camera it comes from and the spectral values by name."""

    set: str
    name: str
    camera: str
    iso: str
    values: Mapping[str, tuple[float, ...]]


def read_bank(path: Path = BANK_PATH) -> tuple[CameraRecord, ...]:
    """The records of a bank file.

    Raises:
        DarksynthError: the file is missing, unreadable or not a camera bank (named in the message).
    """
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise DarksynthError(f"{path}: cannot read the camera bank ({error})") from None
    if not isinstance(document, dict) or document.get("format") != BANK_FORMAT:
        raise DarksynthError(f"{path}: not a camera bank (format is not {BANK_FORMAT!r})")
    if document.get("version") != BANK_VERSION:
        raise DarksynthError(
            f"{path}: camera bank version {document.get('version')!r}, this darksynth reads {BANK_VERSION}"
        )
    try:
        return tuple(
            CameraRecord(
                set=str(record["set"]),
                name=str(record["name"]),
                camera=str(record["camera"]),
                iso=str(record["iso"]),
                values={key: tuple(float(v) for v in value) for key, value in record["values"].items()},
            )
            for record in document["records"]
        )
    except (KeyError, TypeError, ValueError) as error:
        raise DarksynthError(f"{path}: a camera bank record is malformed ({error})") from None


@functools.cache
def shipped_bank() -> tuple[CameraRecord, ...]:
    """The bank shipped in the package (read once)."""
    return read_bank(BANK_PATH)


def without_sets(records: Iterable[CameraRecord], excluded: Iterable[str]) -> tuple[CameraRecord, ...]:
    """The records of every set but ``excluded``."""
    left_out = frozenset(excluded)
    return tuple(record for record in records if record.set not in left_out)
