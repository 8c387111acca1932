"""``darksynth convert``: a whole annotated dataset -> its low-light version, resumable and shardable.

The output mirrors the dataset: each image, video or clip (see :mod:`darksynth.datasets.formats`) is converted to
the same relative path with the same size and format, every other file is carried over, so every annotation
stays valid. Conversion reuses ``apply``'s machinery: :func:`darksynth.apply.run_task` for one item,
:func:`darksynth.apply.execute` for the process pool, and seeds derived from the run seed and the relative path.

State kept in ``OUTPUT/.darksynth/``, so that a run killed at any moment can be started again with the same
command and ends byte-identical to an uninterrupted run:

- ``convert-state.json``: the options that decide the output bytes; a run with other options is refused
  (unless ``overwrite``), so outputs of two different runs are never mixed.
- ``records/<hash of the key>.json``: one record per item, written atomically once all its outputs exist;
  an item with a ``done`` record whose outputs exist is skipped. Failed items are recorded too (and retried).

``OUTPUT/darksynth-manifest.json`` is assembled from the records as soon as every item of every shard has one.
It holds no times and no absolute output paths, so it does not depend on interruptions or on the output location.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import torch

from darksynth import __version__
from darksynth.apply import MANIFEST_NAME, check_video_options, execute, run_task
from darksynth.apply_outputs import (
    STATE_FOLDER,
    changes_from_earlier_run,
    other_options_error,
    read_record,
    state_document,
    write_record_file,
)
from darksynth.apply_outputs import record_path as shared_record_path
from darksynth.datasets.convert_options import ConversionReport, ConvertOptions
from darksynth.datasets.formats import CarriedFile, DatasetPlan, MediaItem, plan_dataset
from darksynth.datasets.formats import rewrite_yolo_yaml as _rewrite_yolo_yaml
from darksynth.errors import DarksynthError, error_reason
from darksynth.io.atomic import atomic_output, write_text_atomic
from darksynth.io.atomic import remove_stale_temps as remove_temps_of

_STATE_NAME: Final = "convert-state.json"
_RECORDS: Final = "records"

ProgressCallback = Callable[[int, int], None]
"""Called with (items finished, items of this run) as each item ends (already done items count at the start)."""


def record_path(output: Path, key: str) -> Path:
    """Where the record of the item ``key`` lives."""
    return shared_record_path(output, _RECORDS, key)


def convert_item(item: MediaItem | Mapping[str, Any], options: ConvertOptions) -> dict[str, Any]:
    """Convert one item and write its record; the per-row function for a Ray Data ``map`` or any other scheduler.

    Pure apart from its files: the outputs depend only on the item and the options (the item's seed derives from
    ``options.seed`` and ``item.key``), so it may run anywhere, in any order, any number of times.

    Args:
        item: a :class:`MediaItem` or its row form ``{"kind": str, "key": str, "inputs": [relative paths]}``
            (see :meth:`MediaItem.to_row`; rows come from ``plan_dataset(...).items``).
        options: the run's options (``options.dataset`` and ``options.output`` absolute).

    Returns:
        The record also written to :func:`record_path`: ``{"input", "kind", "status": "done", "outputs" (relative),
        "frames", "seed", "parameters"}``, or ``{"input", "kind", "status": "failed", "error"}``. A bad input is a
        failed record, never an exception.

    Raises:
        DarksynthError: only if the record itself cannot be written.
    """
    media = item if isinstance(item, MediaItem) else MediaItem.from_row(dict(item))
    try:
        record = _record(media, run_task(media.task(options.dataset, options.output), options.apply_options()), None)
    except DarksynthError as error:
        record = _record(media, None, str(error))
    _write_record(options.output, record)
    return record


def _record(item: MediaItem, result: dict[str, Any] | None, error: str | None) -> dict[str, Any]:
    if result is None:
        return {"input": item.key, "kind": item.kind, "status": "failed", "error": error}
    return {
        "input": item.key,
        "kind": item.kind,
        "status": "done",
        "outputs": list(item.inputs),
        "frames": result["frames"],
        "seed": result["seed"],
        "parameters": result["parameters"],
    }


def _write_record(output: Path, record: dict[str, Any]) -> None:
    write_record_file(record_path(output, record["input"]), record)


def _read_record(output: Path, key: str) -> dict[str, Any] | None:
    return read_record(record_path(output, key), key)


def is_done(output: Path, item: MediaItem) -> bool:
    """Whether an earlier run finished ``item``: its record says done and all its outputs exist."""
    record = _read_record(output, item.key)
    return record is not None and record.get("status") == "done" and all((output / p).is_file() for p in item.inputs)


def convert_dataset(
    options: ConvertOptions,
    *,
    on_progress: ProgressCallback | None = None,
    on_failure: Callable[[str], None] | None = None,
) -> ConversionReport:
    """Convert a dataset (this shard of it), resuming where an earlier run with the same options stopped.

    Bad inputs (see :mod:`darksynth.datasets.formats`) and items that fail are reported in
    ``ConversionReport.failures`` and the rest goes on.

    Args:
        options: what to convert and how (see :class:`ConvertOptions`).
        on_progress: see :data:`ProgressCallback`.
        on_failure: called with each failure message as it happens.

    Returns:
        What this run did.

    Raises:
        DarksynthError: the run cannot start: bad dataset, format or options; an output inside the dataset,
            not writable, or written by a run with other options (without ``overwrite``).
    """
    started = time.perf_counter()
    run = start_conversion(options, on_failure)
    options, plan, report, items, todo = run.options, run.plan, run.report, run.items, run.todo
    finished = report.already_done
    if on_progress:
        on_progress(finished, len(items))
    by_key = {i.key: i for i in todo}
    apply_options = options.apply_options()
    tasks = [i.task(options.dataset, options.output) for i in todo]
    for task, result, error in execute(tasks, apply_options):
        record = _record(by_key[task.key], result, error)
        try:
            _write_record(options.output, record)
        except DarksynthError as write_error:
            run.failed(str(write_error))
        if error is not None:
            run.failed(error)
        else:
            report.converted += 1
        finished += 1
        if on_progress:
            on_progress(finished, len(items))

    report.manifest, report.pending = write_manifest_if_complete(options, plan)
    report.seconds = time.perf_counter() - started
    return report


@dataclass
class StartedConversion:
    """A run after :func:`start_conversion`: its checked options, its plan, its report so far, its items and
    those still to do."""

    options: ConvertOptions
    plan: DatasetPlan
    report: ConversionReport
    items: list[MediaItem]
    todo: list[MediaItem]
    failed: Callable[[str], None]


def start_conversion(options: ConvertOptions, on_failure: Callable[[str], None] | None = None) -> StartedConversion:
    """Everything before the items are converted, the same whatever schedules them (processes here, Ray):
    plan the dataset, claim the output, remove a killed run's temporary files, report bad inputs, carry the
    annotation files over, and list this run's items that no earlier run finished.

    Raises:
        DarksynthError: bad options (see :meth:`ConvertOptions.checked`), the dataset cannot be planned or the
            output cannot be claimed (see :func:`prepare_output`).
    """
    options = options.checked()
    plan = plan_dataset(options.dataset, options.format, images_root=options.images_root)
    videos = [item for item in plan.items if item.kind == "video"]
    if videos:
        check_video_options(options.apply_options(), options.output / videos[0].inputs[0])
    prepare_output(options, has_videos=bool(videos))
    owns = options.shard.owns if options.shard is not None else (lambda key: True)
    items = [i for i in plan.items if owns(i.key)]
    remove_stale_temps(options, plan, owns)
    report = ConversionReport(other_shards=len(plan.items) - len(items))

    def failed(message: str) -> None:
        report.failures.append(message)
        if on_failure:
            on_failure(message)

    for problem in plan.problems:
        if owns(problem.key):
            failed(problem.message)
    for carried in plan.carried:
        if owns(carried.key):
            try:
                report.carried += carry_file(options, carried)
            except DarksynthError as carry_error:
                failed(str(carry_error))
    todo = [i for i in items if not is_done(options.output, i)]
    report.already_done = len(items) - len(todo)
    return StartedConversion(options, plan, report, items, todo, failed)


def prepare_output(options: ConvertOptions, *, has_videos: bool = True) -> None:
    """Check that the output can be written and belongs to this run; record the run's options.

    Call once per run before converting (every shard may call it; it writes the same state). A conversion is
    resumed when every option that can change its outputs is the same: the video options do not count for a
    dataset without videos (``has_videos`` False), and an option the earlier run's state does not record (made
    before the option existed) counts at its default.

    Raises:
        DarksynthError: the output cannot be written, holds a conversion with other options, or is a non-empty
            folder that is not a conversion (the last two unless ``options.overwrite``).
    """
    output = options.output
    state_path = output / STATE_FOLDER / _STATE_NAME
    document = state_document("convert", options.fingerprint(has_videos=has_videos))
    try:
        if state_path.is_file():
            changed = changes_from_earlier_run(state_path, options, document)
            if changed is None:
                return
            # No option named: the same conversion recorded in an earlier form, resumed; its state is rewritten below.
            if changed:
                if not options.overwrite:
                    raise other_options_error(output, "a conversion", changed)
                shutil.rmtree(output / STATE_FOLDER / _RECORDS, ignore_errors=True)
                (output / MANIFEST_NAME).unlink(missing_ok=True)
        elif output.is_dir() and any(output.iterdir()) and not options.overwrite:
            raise DarksynthError(
                f"{output}: not empty and not the output of a conversion; choose an empty or new folder, or add "
                "--overwrite to write into it anyway"
            )
        write_text_atomic(state_path, json.dumps(document, indent=2, sort_keys=True) + "\n")
    except OSError as error:
        where = error.filename or output
        raise DarksynthError(f"{where}: cannot write the output folder ({error_reason(error)})") from None


def remove_stale_temps(options: ConvertOptions, plan: DatasetPlan, owns: Callable[[str], bool]) -> None:
    """Remove temporary files that a killed run left behind for outputs this run owns.

    Another shard's temporary files may belong to a conversion still running, so they are left alone.
    """
    output = options.output
    owned: set[str] = set()
    for item in plan.items:
        if owns(item.key):
            owned.update(item.inputs)
            owned.add(record_path(output, item.key).relative_to(output).as_posix())
    owned.update(c.key for c in plan.carried if owns(c.key))
    if options.shard is None:
        owned.update({MANIFEST_NAME, f"{STATE_FOLDER}/{_STATE_NAME}"})
    remove_temps_of(output / relative for relative in owned)


def carry_file(options: ConvertOptions, carried: CarriedFile) -> bool:
    """Copy or rewrite one file into the output; False if it was already there.

    Raises:
        DarksynthError: the file cannot be read, rewritten or written (one line naming it).
    """
    source, target = options.dataset / carried.key, options.output / carried.key
    try:
        if carried.action == "yolo-yaml":
            try:
                text = _rewrite_yolo_yaml(source.read_text(encoding="utf-8"), options.dataset, options.output)
            except (DarksynthError, UnicodeDecodeError) as error:
                raise DarksynthError(f"{source}: cannot rewrite the dataset YAML ({error}); not written") from None
            if target.is_file() and target.read_text(encoding="utf-8") == text:
                return False
            write_text_atomic(target, text)
            return True
        # Atomic writes make a file that exists complete; the size guards against an input replaced since.
        if target.is_file() and target.stat().st_size == source.stat().st_size:
            return False
        with atomic_output(target) as tmp:
            shutil.copyfile(source, tmp)
        return True
    except OSError as error:
        where = error.filename or target
        raise DarksynthError(f"{where}: cannot carry over {carried.key} ({error_reason(error)})") from None


def write_manifest_if_complete(options: ConvertOptions, plan: DatasetPlan) -> tuple[Path | None, int]:
    """Write the manifest if every item has a record; return its path (or None) and the items still missing.

    Raises:
        DarksynthError: the manifest cannot be written.
    """
    records = [_read_record(options.output, item.key) for item in plan.items]
    pending = sum(r is None for r in records)
    if pending:
        return None, pending
    done = [r for r in records if r is not None and r["status"] == "done"]
    failed = [{"input": r["input"], "error": r["error"]} for r in records if r is not None and r["status"] != "done"]
    document = {
        "format": "darksynth-convert-manifest",
        "version": 1,
        "darksynth": __version__,
        "torch": torch.__version__,
        "dataset": str(options.dataset),
        "dataset_format": plan.format,
        "seed": options.seed,
        **options.recipe.to_json(),
        "device": options.device,
        **options.encoding.to_json(),
        "images_root": None if options.images_root is None else str(options.images_root),
        "files": done,
        "failures": failed,
        "problems": [{"file": p.key, "problem": p.message} for p in plan.problems],
        "carried": [{"file": c.key, "action": c.action} for c in plan.carried],
    }
    path = options.output / MANIFEST_NAME
    text = json.dumps(document, indent=2) + "\n"
    try:
        # Shards finishing together may both write it: the same bytes, each atomically.
        write_text_atomic(path, text)
    except OSError as error:
        raise DarksynthError(f"{path}: cannot write the manifest ({error_reason(error)})") from None
    return path, 0
