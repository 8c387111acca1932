"""Whole annotated datasets (COCO, YOLO, class folders, video folders) -> their low-light versions.

``convert_dataset(ConvertOptions(...))`` runs a conversion end to end; ``plan_dataset`` and ``convert_item`` are
its two halves for other schedulers (a Ray Data ``map`` over ``[item.to_row() for item in plan.items]``).
Importing this package needs neither rich nor typer.
"""

from __future__ import annotations

from darksynth.apply import MANIFEST_NAME
from darksynth.datasets.convert import (
    StartedConversion,
    carry_file,
    convert_dataset,
    convert_item,
    is_done,
    prepare_output,
    record_path,
    remove_stale_temps,
    start_conversion,
    write_manifest_if_complete,
)
from darksynth.datasets.convert_options import SCHEDULING_OPTIONS, ConversionReport, ConvertOptions, Shard, shard_of
from darksynth.datasets.formats import (
    FORMATS,
    CarriedFile,
    DatasetFormat,
    DatasetPlan,
    MediaItem,
    Problem,
    plan_dataset,
    rewrite_yolo_yaml,
)
from darksynth.recipe import fixed_darkening

__all__ = [
    "FORMATS",
    "MANIFEST_NAME",
    "SCHEDULING_OPTIONS",
    "CarriedFile",
    "ConversionReport",
    "ConvertOptions",
    "DatasetFormat",
    "DatasetPlan",
    "MediaItem",
    "Problem",
    "Shard",
    "StartedConversion",
    "carry_file",
    "convert_dataset",
    "convert_item",
    "fixed_darkening",
    "is_done",
    "plan_dataset",
    "prepare_output",
    "record_path",
    "remove_stale_temps",
    "rewrite_yolo_yaml",
    "shard_of",
    "start_conversion",
    "write_manifest_if_complete",
]
