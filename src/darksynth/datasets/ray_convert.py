"""The dataset conversion as a Ray Data map: the same items, seeds and files as ``convert_dataset``, on a cluster.

Planning, carrying annotation files and the manifest run on the driver; each item is converted by
:func:`darksynth.datasets.convert_item` in a Ray task (one CPU, one torch thread). Because every item's output
depends only on the run's options and the item's relative path, the result is byte-identical to a local run
(tested on a local Ray instance), and a run that stops half-way resumes like a local one: items already recorded
as done are not sent again. On a cluster the dataset and the output folder must be on a file system every node
sees (NFS, Lustre, a mounted bucket); nothing is sent back to the driver but a one-line status per item.

``ray`` is an optional dependency (``pip install 'darksynth[ray]'``); this module imports it only when called.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from darksynth.datasets.convert import (
    ConversionReport,
    ConvertOptions,
    conversion_options,
    convert_item,
    start_conversion,
    write_manifest_if_complete,
)
from darksynth.datasets.formats import DatasetFormat
from darksynth.errors import DarksynthError
from darksynth.profile import Profile


def _convert_row(row: dict[str, Any], options: ConvertOptions) -> dict[str, Any]:
    """One Ray task: convert the item and return only what the driver reports (the record is on disk)."""
    import torch

    # One CPU per task: torch's own thread pool would compete with the node's other tasks.
    torch.set_num_threads(1)
    record = convert_item(row, options)
    return {"input": record["input"], "status": record["status"], "error": record.get("error") or ""}


def convert_dataset_with_ray(
    dataset: Path,
    output: Path,
    profile: Profile | Path | str,
    *,
    format: DatasetFormat,
    seed: int = 0,
    jitter: bool = False,
    images_root: Path | None = None,
    overwrite: bool = False,
    codec: str | None = None,
    crf: int | None = None,
    concurrency: int | None = None,
    on_failure: Callable[[str], None] | None = None,
) -> ConversionReport:
    """Convert a dataset with Ray Data; connects to the running Ray instance (``ray.init()`` if none is).

    Args:
        concurrency: at most this many conversions at once (None: as many as Ray's CPUs allow).
        on_failure: called with each failure message.
        Others: as for :func:`darksynth.datasets.convert_dataset` (no ``workers`` or ``shard``: Ray schedules).

    Returns:
        What this run did; ``manifest`` is written once every item has a record.

    Raises:
        DarksynthError: the run cannot start (as for ``convert_dataset``), or ray is not installed.
    """
    try:
        import ray
        import ray.data
    except ImportError:
        raise DarksynthError("the Ray path needs ray: pip install 'darksynth[ray]'") from None
    started = time.perf_counter()
    options = conversion_options(
        dataset,
        output,
        profile,
        format=format,
        seed=seed,
        jitter=jitter,
        images_root=images_root,
        overwrite=overwrite,
        codec=codec,
        crf=crf,
    )
    run = start_conversion(options, on_failure)
    report, todo = run.report, run.todo
    if todo:
        if not ray.is_initialized():
            ray.init()
        # One row per block, so that Ray can spread the items over its workers however few there are.
        rows = ray.data.from_items([item.to_row() for item in todo]).repartition(len(todo))
        results = rows.map(functools.partial(_convert_row, options=options), num_cpus=1, concurrency=concurrency)
        for result in sorted(results.take_all(), key=lambda r: str(r["input"])):
            if result["status"] == "done":
                report.converted += 1
            else:
                run.failed(str(result["error"]))
    report.manifest, report.pending = write_manifest_if_complete(options, run.plan)
    report.seconds = time.perf_counter() - started
    return report
