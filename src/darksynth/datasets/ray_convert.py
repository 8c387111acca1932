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

import dataclasses
import functools
import time
from collections.abc import Callable
from typing import Any, Final

from darksynth.datasets.convert import convert_item, start_conversion, write_manifest_if_complete
from darksynth.datasets.convert_options import ConversionReport, ConvertOptions
from darksynth.errors import DarksynthError

RAY_SCHEDULES: Final = ("shard", "workers", "device")
"""The options of :class:`ConvertOptions` that Ray decides itself: a Ray run takes them at their defaults."""


def _convert_row(row: dict[str, Any], options: ConvertOptions) -> dict[str, Any]:
    """One Ray task: convert the item and return only what the driver reports (the record is on disk)."""
    import torch

    # One CPU per task: torch's own thread pool would compete with the node's other tasks.
    torch.set_num_threads(1)
    record = convert_item(row, options)
    return {"input": record["input"], "status": record["status"], "error": record.get("error") or ""}


def convert_dataset_with_ray(
    options: ConvertOptions,
    *,
    concurrency: int | None = None,
    on_failure: Callable[[str], None] | None = None,
) -> ConversionReport:
    """Convert a dataset with Ray Data; connects to the running Ray instance (``ray.init()`` if none is).

    Args:
        options: as for :func:`darksynth.datasets.convert_dataset`, with ``workers``, ``shard`` and ``device``
            left at their defaults: Ray decides where and how many conversions run.
        concurrency: at most this many conversions at once (None: as many as Ray's CPUs allow).
        on_failure: called with each failure message.

    Returns:
        What this run did; ``manifest`` is written once every item has a record.

    Raises:
        DarksynthError: the run cannot start (as for ``convert_dataset``), options that Ray decides are set, or
            ray is not installed.
    """
    defaults = {option.name: option.default for option in dataclasses.fields(ConvertOptions)}
    scheduled = [name for name in RAY_SCHEDULES if getattr(options, name) != defaults[name]]
    if scheduled:
        raise DarksynthError(
            "--ray schedules the work itself: it takes no --shard, --workers or --device "
            f"(got {', '.join(f'--{name}' for name in scheduled)})"
        )
    try:
        import ray
        import ray.data
    except ImportError:
        raise DarksynthError("the Ray path needs ray: pip install 'darksynth[ray]'") from None
    started = time.perf_counter()
    run = start_conversion(options, on_failure)
    options, report, todo = run.options, run.report, run.todo
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
