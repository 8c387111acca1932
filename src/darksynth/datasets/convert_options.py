"""What ``darksynth convert`` is asked to do and what a run did: its options, the shard a run handles, its report.

The options are picklable, so that a Ray or process-pool worker can receive them; those that change no output byte
(:data:`SCHEDULING_OPTIONS`) may differ between the runs that resume one conversion.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from darksynth.apply import ApplyOptions
from darksynth.apply_outputs import VIDEO_OPTIONS, options_fingerprint
from darksynth.datasets.formats import FORMATS, DatasetFormat
from darksynth.errors import DarksynthError
from darksynth.io.discover import check_output_location
from darksynth.io.video_encoding import DEFAULT_ENCODING, VideoEncoding
from darksynth.recipe import ClipRecipe


def shard_of(key: str, count: int) -> int:
    """The 1-based shard that owns a key: a hash of the relative path, so adding files reshuffles no other file."""
    digest = hashlib.sha256(f"darksynth-shard:{key}".encode()).digest()
    return int.from_bytes(digest[:8], "little") % count + 1


@dataclass(frozen=True)
class Shard:
    """Shard ``index`` (1-based) of ``count``: the items, carried files and problems whose key it owns."""

    index: int
    count: int

    def __post_init__(self) -> None:
        if self.count < 1 or not 1 <= self.index <= self.count:
            raise DarksynthError(f"--shard must be K/N with 1 <= K <= N, got {self.index}/{self.count}")

    @classmethod
    def parse(cls, text: str) -> Shard:
        """Read ``"K/N"``."""
        index, sep, count = text.partition("/")
        if not sep or not index.strip().isdigit() or not count.strip().isdigit():
            raise DarksynthError(f"--shard must be K/N, for example 2/8, got {text!r}")
        return cls(int(index), int(count))

    def owns(self, key: str) -> bool:
        """Whether this shard handles ``key``."""
        return shard_of(key, self.count) == self.index


SCHEDULING_OPTIONS: Final = frozenset({"output", "workers", "shard", "overwrite"})
"""The options of :class:`ConvertOptions` that do not change a single output byte, so that a run may resume with
other values of them: where the output is, how the work is split, and whether an earlier run's state is kept."""


@dataclass(frozen=True)
class ConvertOptions:
    """Everything a conversion needs, and the defaults of ``darksynth convert``; picklable, so that a Ray or
    process-pool worker can receive it. :meth:`checked` makes the paths absolute; the functions that take
    options after it (:func:`~darksynth.datasets.convert.convert_item`,
    :func:`~darksynth.datasets.convert.prepare_output`, ...) expect checked options.

    Attributes:
        dataset: the dataset root.
        output: the output root (never the dataset or inside it).
        recipe: how each item's parameters are chosen, as for ``apply`` (:class:`darksynth.recipe.ClipRecipe`).
        format: the dataset format, one of :data:`darksynth.datasets.formats.FORMATS`.
        seed: run seed; each item's seed derives from it and the item's relative path.
        workers: processes on this machine.
        shard: the part of the dataset this run handles, or None for all of it.
        images_root: COCO: the folder ``file_name`` entries are relative to (tried first).
        overwrite: start over in an output written with other options.
        encoding, device: as for ``apply``.
    """

    dataset: Path
    output: Path
    recipe: ClipRecipe
    format: DatasetFormat
    seed: int = 0
    workers: int = 1
    shard: Shard | None = None
    images_root: Path | None = None
    overwrite: bool = False
    encoding: VideoEncoding = DEFAULT_ENCODING
    device: str = "cpu"

    def checked(self) -> ConvertOptions:
        """These options with absolute paths, once checked.

        Raises:
            DarksynthError: an unknown format or camera, fewer than one worker, an output that is the dataset or
                inside it.
        """
        if self.format not in FORMATS:
            raise DarksynthError(f"unknown dataset format {self.format!r}; use one of {', '.join(FORMATS)}")
        if self.workers < 1:
            raise DarksynthError(f"--workers must be at least 1, got {self.workers}")
        check_output_location(self.dataset, self.output)
        return dataclasses.replace(self, dataset=self.dataset.resolve(), output=self.output.resolve())

    def apply_options(self) -> ApplyOptions:
        """The ``apply`` options of each item (the same recipe)."""
        return ApplyOptions(
            recipe=self.recipe, seed=self.seed, workers=self.workers, encoding=self.encoding, device=self.device
        )

    def fingerprint(self, *, has_videos: bool = True) -> dict[str, Any]:
        """The options that decide the output bytes: all but those of :data:`SCHEDULING_OPTIONS`, and but those of
        :data:`VIDEO_OPTIONS` for a dataset without videos (``has_videos`` False)."""
        left_out = SCHEDULING_OPTIONS if has_videos else SCHEDULING_OPTIONS | VIDEO_OPTIONS
        return options_fingerprint(self, left_out=left_out)


@dataclass
class ConversionReport:
    """What one run did (this shard only).

    Attributes:
        converted: items converted by this run.
        already_done: items found complete from an earlier run and skipped.
        carried: files copied or rewritten by this run (those already in place are not counted).
        failures: one line per failed item, bad input found while planning, or file that could not be carried.
        other_shards: items left to other shards.
        pending: items of any shard without a record yet (the manifest waits for them).
        manifest: the manifest path once every item has a record, else None.
        seconds: wall time of the run.
    """

    converted: int = 0
    already_done: int = 0
    carried: int = 0
    failures: list[str] = field(default_factory=list)
    other_shards: int = 0
    pending: int = 0
    manifest: Path | None = None
    seconds: float = 0.0
