"""What ``apply`` may write where: claiming a run's outputs, and resuming a folder run that was killed (its
options and each finished file's record, kept in the output folder).

A folder run writes, in ``OUTPUT/.darksynth/``, the options that decide its bytes (``apply-state.json``) before any
work, and a record per task as each one finishes (``apply-records/``). Rerun with the same options, it keeps the
tasks whose record and outputs exist ("already done") and redoes the rest, replacing what a killed run left of
them (outputs are written atomically, so a file is either whole or absent, but one written without its record is
redone, as its record may not have been kept). Rerun with other options it is refused, naming them, unless
``--overwrite``; an output folder that holds files but no state is refused as before. As for ``convert``: the
options that change no byte (workers, where the profile came from) may differ, the video options count only for
a folder with videos, and an option an earlier version did not record counts at its default.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from darksynth.errors import DarksynthError, error_reason
from darksynth.io.atomic import remove_stale_temps, write_text_atomic

STATE_FOLDER: Final = ".darksynth"
"""The folder of a run's state inside its output folder (``apply`` and ``convert`` alike)."""

STATE_NAME: Final = "apply-state.json"
RECORDS: Final = "apply-records"

UNRECORDED_OPTIONS: Final = frozenset({"overwrite", "workers", "profile_source"})
"""Options of :class:`~darksynth.apply.ApplyOptions` that change no output byte: a run may resume with others."""

VIDEO_OPTIONS: Final = frozenset({"encoding"})
"""Options that change only videos: they do not decide the resume of a folder without videos."""


def options_fingerprint(options: Any, *, left_out: frozenset[str] | set[str]) -> dict[str, Any]:
    """The fields of an options dataclass (:class:`~darksynth.apply.ApplyOptions`,
    :class:`~darksynth.datasets.ConvertOptions`) but those ``left_out``, as JSON values: what decides a run's
    bytes, recorded so that a rerun can tell whether it continues the same run."""
    fingerprint: dict[str, Any] = {}
    for option in dataclasses.fields(options):
        if option.name in left_out:
            continue
        value = getattr(options, option.name)
        if _is_group(value):
            # Each choice of a group (the encoding, the recipe) under its own name, as the command line and the
            # manifest name them.
            fingerprint.update(value.to_json())
            continue
        fingerprint[option.name] = str(value) if isinstance(value, Path) else value
    return fingerprint


def _is_group(value: object) -> bool:
    """Whether an option's value is a group of choices recorded one by one: a dataclass with ``to_json``
    (:class:`~darksynth.io.video_encoding.VideoEncoding`, :class:`~darksynth.recipe.ClipRecipe`)."""
    return dataclasses.is_dataclass(value) and not isinstance(value, type) and hasattr(value, "to_json")


def changed_options(options: Any, fingerprint: dict[str, Any], recorded: dict[str, Any]) -> list[str]:
    """The names whose value in ``fingerprint`` differs from the earlier run's ``recorded`` one; an option the
    earlier run did not record (it did not exist then) counts at its default."""
    groups = [getattr(options, f.name) for f in dataclasses.fields(options) if _is_group(getattr(options, f.name))]
    fields = (*dataclasses.fields(options), *(f for group in groups for f in dataclasses.fields(group)))
    defaults = {f.name: None if f.default is dataclasses.MISSING else f.default for f in fields}
    return sorted(name for name, value in fingerprint.items() if recorded.get(name, defaults.get(name)) != value)


@dataclass
class ResumeState:
    """What a folder run found of an earlier one in its output folder.

    Attributes:
        root: the output folder.
        document: the state this run records.
        done: the records of tasks an earlier run with the same options finished, by task key.
        owned: the output folder holds this run's state: its outputs without a record may be replaced.
    """

    root: Path
    document: dict[str, Any]
    done: dict[str, dict[str, Any]] = field(default_factory=dict)
    owned: bool = False


def record_path(root: Path, folder: str, key: str) -> Path:
    """Where the record of the task or item ``key`` lives, in the records ``folder`` of a run's state in ``root``
    (``apply`` and ``convert`` alike: a hash of the key, so that any path makes a valid file name)."""
    return root / STATE_FOLDER / folder / f"{hashlib.sha256(key.encode()).hexdigest()[:32]}.json"


def read_record(path: Path, key: str) -> dict[str, Any] | None:
    """The record at ``path`` if it is the one of ``key``; None when missing or unreadable (atomic writes rule the
    latter out): the task is then done again."""
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("input") == key else None


def write_record_file(path: Path, record: dict[str, Any]) -> None:
    """Write one record atomically.

    Raises:
        DarksynthError: the record cannot be written.
    """
    try:
        write_text_atomic(path, json.dumps(record, indent=1, sort_keys=True) + "\n")
    except OSError as error:
        raise DarksynthError(f"{error.filename or path}: cannot write the record ({error_reason(error)})") from None


def state_document(kind: str, fingerprint: dict[str, Any]) -> dict[str, Any]:
    """The state file of a run (``kind`` "apply" or "convert") with the options ``fingerprint``."""
    digest = hashlib.sha256(json.dumps(fingerprint, sort_keys=True).encode()).hexdigest()
    return {"format": f"darksynth-{kind}-state", "version": 1, "hash": digest, "options": fingerprint}


def changes_from_earlier_run(path: Path, options: Any, document: dict[str, Any]) -> list[str] | None:
    """How the run whose state is at ``path`` differs from this one (its :func:`state_document` ``document``):
    None when it is recorded exactly so; the names of the options that differ (:func:`changed_options`); an empty
    list for the same options recorded in an earlier form; ``["state"]`` for a state that is not valid JSON.

    Raises:
        OSError: the state cannot be read (each caller reports it in its own words)."""
    try:
        previous = json.loads(path.read_text(encoding="utf-8"))
    except ValueError:
        previous = {}
    if not isinstance(previous, dict):
        previous = {}
    if previous.get("hash") == document["hash"]:
        return None
    recorded = previous.get("options")
    if not isinstance(recorded, dict):
        return ["state"]
    return changed_options(options, document["options"], recorded)


def other_options_error(root: Path, run: str, changed: list[str]) -> DarksynthError:
    """The one-line refusal of an output folder that holds ``run`` (e.g. "a conversion") made with other options."""
    return DarksynthError(
        f"{root}: holds {run} made with other options ({', '.join(changed)}); rerun the same command to resume it, "
        "add --overwrite to start over, or choose another output folder"
    )


def read_state(root: Path, options: Any, keys: dict[str, tuple[Path, ...]], *, has_videos: bool) -> ResumeState:
    """The earlier run found in ``root`` for tasks ``keys`` (task key -> its output paths); nothing is written.

    Raises:
        DarksynthError: ``root`` holds a run made with other options and ``options.overwrite`` is off.
    """
    left_out = UNRECORDED_OPTIONS if has_videos else UNRECORDED_OPTIONS | VIDEO_OPTIONS
    document = state_document("apply", options_fingerprint(options, left_out=left_out))
    state = ResumeState(root, document)
    path = root / STATE_FOLDER / STATE_NAME
    if not path.is_file() or options.overwrite:
        return state
    try:
        changed = changes_from_earlier_run(path, options, document)
    except OSError:
        changed = ["state"]
    if changed:
        raise other_options_error(root, "an apply run", changed)
    state.owned = True
    for key, outputs in keys.items():
        record = read_record(record_path(root, RECORDS, key), key)
        if record is not None and all(path.is_file() for path in outputs):
            state.done[key] = record
    return state


def write_state(state: ResumeState) -> None:
    """Record the run's options in its output folder (after its outputs were claimed), clearing the records of
    an earlier run that is not resumed.

    Raises:
        DarksynthError: the state cannot be written.
    """
    folder = state.root / STATE_FOLDER
    try:
        if not state.owned:
            shutil.rmtree(folder / RECORDS, ignore_errors=True)
        write_text_atomic(folder / STATE_NAME, json.dumps(state.document, indent=2, sort_keys=True) + "\n")
    except OSError as error:
        raise DarksynthError(
            f"{error.filename or folder}: cannot write the run's state ({error_reason(error)})"
        ) from None


def write_record(state: ResumeState, key: str, record: dict[str, Any]) -> None:
    """Record that task ``key`` finished (after its outputs were written).

    Raises:
        DarksynthError: the record cannot be written.
    """
    write_record_file(record_path(state.root, RECORDS, key), record)


def claim_outputs(outputs: list[Path], root: Path, *, folder: bool, overwrite: bool) -> None:
    """Check, before any work, that a run may write its outputs; remove what a killed run left for them.

    Refused without ``overwrite``: any output (manifest included) that exists already. Refused always: an
    output location that cannot be written (read-only file system, no permission, a file where a folder should
    be), found by creating the folder and a file in it, so that it fails once instead of once per file.

    Raises:
        DarksynthError: one line naming the first existing output and the count, or the unwritable location.
    """
    if not overwrite:
        existing = [path for path in outputs if path.exists()]
        if existing:
            more = f" (and {len(existing) - 1} more of this run's outputs)" if len(existing) > 1 else ""
            raise DarksynthError(f"{existing[0]}: exists{more}; add --overwrite to replace, or choose another output")
    location = root if folder else root.parent
    try:
        location.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=location, prefix=".darksynth-probe-"):
            pass
    except OSError as error:
        raise DarksynthError(f"{location}: cannot write the output here ({error_reason(error)})") from None
    remove_stale_temps(outputs)
