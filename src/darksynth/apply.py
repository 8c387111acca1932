"""``darksynth apply``: clean image, video or folder -> low-light output tree and a manifest.

Each output file is derived from one task (an image, a video, or with ``clip`` a folder of frames), with a
seed derived from the run seed and the task's path relative to the input, so the result does not depend on
the order or the process in which tasks run.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from fractions import Fraction
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch

from darksynth import __version__
from darksynth.apply_outputs import claim_outputs, read_state, write_record, write_state
from darksynth.errors import DarksynthError, error_reason
from darksynth.io.arrays import chw_to_hwc, hwc_to_chw
from darksynth.io.atomic import write_text_atomic
from darksynth.io.discover import check_output_location, classify_input, scan_folder
from darksynth.io.images import IMAGE_SUFFIXES, Image, read_image, write_image
from darksynth.io.video import (
    DEFAULT_ENCODING,
    VIDEO_SUFFIXES,
    VideoEncoding,
    VideoWriter,
    iter_video_frames,
    probe_video,
    to_stream_size,
)
from darksynth.recipe import ClipParameters, ClipRecipe
from darksynth.seeding import derive_seed
from darksynth.synthesize import ClipSynthesizer
from darksynth.worker_pool import init_worker

logger = logging.getLogger(__name__)

TaskKind = Literal["image", "video", "clip"]

COMPILE_MIN_ELEMENTS = 500_000_000
"""Streams of at least this many values (frames x channels x pixels) are worth ``torch.compile``.

Measured on the development machine (docs/performance.md): the eager 8-bit kernel, run in blocks of rows,
costs about 14 ns a value (88 ms a 1080p RGB frame), the compiled one about 2.2 ns (14 ms), and compiling
costs about 13 s the first time on a machine and 3-4 s with the on-disk cache of later runs. At 5e8 values
(about 80 frames of 1080p RGB) the saving, about 6 s, exceeds a warm compilation; a cold one pays off from
about 1.1e9 values on. The spectral model's kernels (the default profile's) save about 60 ms a 1080p frame
(105 eager against 38-45 compiled), about the same."""

MANIFEST_NAME = "darksynth-manifest.json"
"""The manifest of a run into a folder, inside it (``apply`` and ``convert`` alike); a single output file's
manifest lies beside it as ``NAME.manifest.json``."""

Progress = Callable[[int], None]
"""Called with the number of frames just finished."""


@dataclass(frozen=True)
class ApplyOptions:
    """Everything ``apply`` needs besides the paths.

    Attributes:
        recipe: how each file's (or clip's) parameters are chosen: the profile, the darkening, ``--jitter``,
            ``--no-blur``, ``--no-flicker``, ``--match-colour``, ``--camera`` (:class:`darksynth.recipe.ClipRecipe`).
        seed: run seed; each task's seed derives from it and the task's relative path.
        overwrite: replace outputs that exist before the run (otherwise the run is refused).
        clip: treat each folder of images as one clip (shared parameters and temporal banding).
        workers: processes for folders.
        encoding: the videos' codec, quality and pixel format (the writer's defaults where it leaves a choice).
        device: torch device for the computation.
        compile: fuse the 8-bit kernel with torch.compile; None decides by stream length.
        profile_source: where the profile came from, for the manifest.
    """

    recipe: ClipRecipe
    seed: int
    overwrite: bool = False
    clip: bool = False
    workers: int = 1
    encoding: VideoEncoding = DEFAULT_ENCODING
    device: str = "cpu"
    compile: bool | None = None
    profile_source: str = ""


@dataclass(frozen=True)
class Task:
    """One unit of output: its kind, its input files (frames in order) and its output path(s)."""

    kind: TaskKind
    key: str
    inputs: tuple[Path, ...]
    outputs: tuple[Path, ...]


@dataclass
class ApplyReport:
    """What a run did: one record per finished task, the failures with reasons, the skipped files."""

    records: list[dict[str, Any]] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    manifest: Path | None = None
    seconds: float = 0.0
    already_done: int = 0
    """Files an earlier, killed run with the same options finished (their records are in ``records``)."""


def task_seed(run_seed: int, key: str) -> int:
    """A task's seed from the run seed and its relative path: independent of processing order."""
    return derive_seed("darksynth", run_seed, key)


def manifest_path(output: Path, *, folder: bool) -> Path:
    """A folder's manifest lies inside it (:data:`MANIFEST_NAME`), a file's beside it: ``OUTPUT.manifest.json``."""
    return output / MANIFEST_NAME if folder else output.with_name(output.name + ".manifest.json")


def plan(input_path: Path, output_path: Path, *, clip: bool) -> tuple[list[Task], list[str], Path]:
    """List the tasks of a run, the files a folder run skips, and the output path (a file input given an
    existing folder as output writes into it under its own name).

    Raises:
        DarksynthError: the input does not exist, is of an unknown type, or the output lies in the input.
    """
    kind = classify_input(input_path)
    if kind != "folder" and output_path.is_dir():
        output_path = output_path / input_path.name
    check_output_location(input_path, output_path)
    if kind != "folder":
        suffixes = IMAGE_SUFFIXES if kind == "image" else VIDEO_SUFFIXES
        if output_path.suffix.lower() not in suffixes:
            raise DarksynthError(
                f"{output_path}: an output {kind} needs one of the suffixes {' '.join(sorted(suffixes))}"
            )
        return [Task(kind, input_path.name, (input_path,), (output_path,))], [], output_path
    listing = scan_folder(input_path)

    def task(kind: TaskKind, key: str, files: list[Path]) -> Task:
        return Task(kind, key, tuple(input_path / f for f in files), tuple(output_path / f for f in files))

    if clip:
        by_folder: dict[Path, list[Path]] = {}
        for relative in listing.images:
            by_folder.setdefault(relative.parent, []).append(relative)
        tasks = [task("clip", folder.as_posix() + "/", frames) for folder, frames in sorted(by_folder.items())]
    else:
        tasks = [task("image", r.as_posix(), [r]) for r in listing.images]
    tasks += [task("video", r.as_posix(), [r]) for r in listing.videos]
    tasks.sort(key=lambda t: t.key)
    return tasks, [r.as_posix() for r in listing.skipped], output_path


def run_task(task: Task, options: ApplyOptions, progress: Progress | None = None) -> dict[str, Any]:
    """Produce one task's output files atomically and return its manifest record.

    Raises:
        DarksynthError: an input that cannot be read or an output that cannot be written.
    """
    try:
        return _run_task(task, options, progress)
    except OSError as error:
        # Disk full, permission denied, a folder where a file should go: one line naming the file.
        where = error.filename or task.outputs[0]
        raise DarksynthError(f"{where}: {error_reason(error)}") from None


def start_task(
    key: str, options: ApplyOptions, first_frame: np.ndarray | None = None
) -> tuple[int, torch.Generator, ClipParameters]:
    """A task's seed, the generator its noise is drawn from and its parameters, all fixed by the run seed and the
    task's key (its path relative to the input; for a single input file, its name). With ``first_frame`` (H, W, C)
    and a profile that carries the reference's tones, the darkening is matched to them
    (:func:`darksynth.exposure.matched_darkening`), and with ``match_colour`` the colour cast too."""
    seed = task_seed(options.seed, key)
    generator = torch.Generator(device=options.device).manual_seed(seed)
    first = None if first_frame is None else hwc_to_chw(first_frame)
    parameters = options.recipe.choose(generator, first, source=key)
    return seed, generator, parameters


def synthesize_image(pixels: np.ndarray, key: str, options: ApplyOptions) -> tuple[np.ndarray, ClipParameters]:
    """The low-light pixels that ``apply`` writes for an image task with this key, and the parameters drawn.

    Args:
        pixels: the clean image (H, W, C), uint8 or uint16.
        key: the task's key; an image given to ``apply`` as its input has its file name as key.

    Returns:
        The low-light image in the dtype of ``pixels``, and its parameters.
    """
    _, generator, parameters = start_task(key, options, pixels)
    compile_kernel = _worth_compiling(options, pixels.size)
    synthesizer = ClipSynthesizer(parameters, generator=generator, device=options.device, compile=compile_kernel)
    return chw_to_hwc(synthesizer.image(hwc_to_chw(pixels))), parameters


def _run_task(task: Task, options: ApplyOptions, progress: Progress | None) -> dict[str, Any]:
    # The first frame, which the darkening is matched on (None for a video without frames: its run then fails with
    # its own message); an image's is kept for its synthesis, not read twice.
    if task.kind == "video":
        seed, generator, parameters = start_task(task.key, options, next(iter_video_frames(task.inputs[0]), None))
        frames = _run_video(task, options, parameters, generator, progress)
    else:
        first = read_image(task.inputs[0])
        seed, generator, parameters = start_task(task.key, options, first.pixels)
        frames = _run_frames(task, options, parameters, generator, progress, first)
    return {
        "input": task.key,
        "kind": task.kind,
        "outputs": [str(p) for p in task.outputs],
        "frames": frames,
        "seed": seed,
        "parameters": parameters.to_json(),
    }


def _run_frames(
    task: Task,
    options: ApplyOptions,
    parameters: ClipParameters,
    generator: torch.Generator,
    progress: Progress | None,
    first: Image,
) -> int:
    """An image, or a clip's frames in order (``first`` already read); a clip's frame is written once blurred."""
    compile_kernel = _worth_compiling(options, len(task.inputs) * first.pixels.size)
    name = str(task.inputs[0].parent if task.kind == "clip" else task.inputs[0])
    synthesizer = ClipSynthesizer(
        parameters, generator=generator, device=options.device, compile=compile_kernel, name=name
    )
    pending: list[tuple[Path, Image]] = []
    for index, (source, target) in enumerate(zip(task.inputs, task.outputs, strict=True)):
        image = first if index == 0 else read_image(source)
        frame = hwc_to_chw(image.pixels)
        pending.append((target, image))
        # A clip's frame of another size is the synthesizer's to handle (it logs the change and goes on).
        results = [synthesizer.image(frame)] if task.kind == "image" else synthesizer.push(frame)
        for result in results:
            _write_pending(pending, result, progress)
    for result in synthesizer.finish():
        _write_pending(pending, result, progress)
    return len(task.inputs)


def _write_pending(pending: list[tuple[Path, Image]], result: torch.Tensor, progress: Progress | None) -> None:
    target, image = pending.pop(0)
    write_image(target, dataclasses.replace(image, pixels=chw_to_hwc(result)))
    if progress:
        progress(1)


def _run_video(
    task: Task,
    options: ApplyOptions,
    parameters: ClipParameters,
    generator: torch.Generator,
    progress: Progress | None,
) -> int:
    source, target = task.inputs[0], task.outputs[0]
    info = probe_video(source)
    # A container that does not state its length is taken to be long.
    frames = info.frame_count if info.frame_count is not None else COMPILE_MIN_ELEMENTS
    compile_kernel = _worth_compiling(options, frames * 3 * info.width * info.height)
    synthesizer = ClipSynthesizer(parameters, generator=generator, device=options.device, compile=compile_kernel)
    # The source's audio goes into the output unchanged (a track the output's container cannot hold is left out
    # with a notice).
    count = 0
    resized = False
    with VideoWriter(
        target, width=info.width, height=info.height, fps=info.fps, encoding=options.encoding, audio_from=source
    ) as writer:
        for frame in iter_video_frames(source):
            if frame.shape[:2] != (info.height, info.width):
                frame = to_stream_size(source, frame, info.width, info.height, first=not resized)
                resized = True
            for result in synthesizer.push(hwc_to_chw(frame)):
                writer.write(chw_to_hwc(result))
                if progress:
                    progress(1)
            count += 1
        for result in synthesizer.finish():
            writer.write(chw_to_hwc(result))
            if progress:
                progress(1)
    if count == 0:
        raise DarksynthError(f"{source}: the video has no decodable frames")
    return count


def check_video_options(options: ApplyOptions, output: Path) -> None:
    """Refuse a codec, crf or pixel format the writer cannot use, once, before a run writes any video (else
    every video of a folder would fail with the same line). ``output``: the first video output, named in the error.

    Raises:
        DarksynthError: the writer refuses the options.
    """
    # Constructing a writer checks its options without opening a file; an even size leaves odd-size rules out.
    VideoWriter(output, width=16, height=16, fps=Fraction(25), encoding=options.encoding)


def _worth_compiling(options: ApplyOptions, values: int) -> bool:
    return options.compile if options.compile is not None else values >= COMPILE_MIN_ELEMENTS


def execute(
    tasks: list[Task],
    options: ApplyOptions,
    *,
    on_frames: Progress | None = None,
) -> Iterator[tuple[Task, dict[str, Any] | None, str | None]]:
    """Run tasks, in this process or in ``options.workers`` processes; yield (task, record, error) as each ends."""
    if options.workers <= 1 or len(tasks) <= 1:
        for task in tasks:
            try:
                yield task, run_task(task, options, on_frames), None
            except DarksynthError as error:
                yield task, None, str(error)
        return
    threads = max(1, (os.cpu_count() or 1) // options.workers)
    # "spawn": forking a process that already runs torch's thread pools can deadlock.
    context = get_context("spawn")
    with ProcessPoolExecutor(options.workers, mp_context=context, initializer=init_worker, initargs=(threads,)) as pool:
        futures = {pool.submit(run_task, task, options): task for task in tasks}
        for future in as_completed(futures):
            task = futures[future]
            try:
                yield task, future.result(), None
            except DarksynthError as error:
                yield task, None, str(error)


def write_manifest(path: Path, input_path: Path, output_path: Path, options: ApplyOptions, report: ApplyReport) -> None:
    """Record everything needed to reproduce each output: versions, profile, run seed, per-task seeds and values.

    Raises:
        DarksynthError: the manifest cannot be written.
    """
    document = {
        "darksynth": __version__,
        "torch": torch.__version__,
        "command": sys.argv,
        "input": str(input_path),
        "output": str(output_path),
        "profile_source": options.profile_source,
        **options.recipe.to_json(),
        "seed": options.seed,
        "device": options.device,
        "clip": options.clip,
        **options.encoding.to_json(),
        "files": sorted(report.records, key=lambda r: r["input"]),
        "failures": report.failures,
        "skipped": report.skipped,
        "seconds": round(report.seconds, 3),
    }
    try:
        write_text_atomic(path, json.dumps(document, indent=2) + "\n")
    except OSError as error:
        raise DarksynthError(f"{error.filename or path}: cannot write the manifest ({error_reason(error)})") from None


def apply(
    input_path: Path,
    output_path: Path,
    options: ApplyOptions,
    *,
    on_start: Callable[[list[Task], int], None] | None = None,
    on_frames: Progress | None = None,
    on_task: Callable[[Task, str | None], None] | None = None,
) -> ApplyReport:
    """Run ``apply`` end to end and write the manifest.

    In a folder run, a task that fails is recorded with its reason and the others go on; a single-file run
    raises the file's error and writes no manifest.

    Args:
        on_start: called with the tasks and the total frame count before work starts (for a progress bar).
        on_frames: called as frames finish (single process only).
        on_task: called as each task ends, with the error message or None.

    Raises:
        DarksynthError: the run cannot start (bad input path, output inside input, outputs that exist without
            ``options.overwrite``, an output location that cannot be written), the single input file fails, or
            the manifest cannot be written.
    """
    started = time.perf_counter()
    tasks, skipped, output_path = plan(input_path, output_path, clip=options.clip)
    folder = input_path.is_dir()
    manifest = manifest_path(output_path, folder=folder)
    videos = [task.outputs[0] for task in tasks if task.kind == "video"]
    if videos:
        check_video_options(options, videos[0])
    report = ApplyReport(skipped=skipped)
    resume = None
    if folder:
        # A folder run resumes an earlier one with the same options (darksynth.apply_outputs.read_state).
        resume = read_state(output_path, options, {t.key: t.outputs for t in tasks}, has_videos=bool(videos))
        report.records.extend(resume.done.values())
        report.already_done = len(resume.done)
        tasks = [task for task in tasks if task.key not in resume.done]
    outputs = [path for task in tasks for path in task.outputs]
    overwrite = options.overwrite or (resume is not None and resume.owned)
    claim_outputs([*outputs, manifest], output_path, folder=folder, overwrite=overwrite)
    total_frames = sum(_frame_estimate(t) for t in tasks)
    if on_start:
        on_start(tasks, total_frames)
    if resume is not None:
        write_state(resume)
        for task, record, error in execute(tasks, options, on_frames=on_frames):
            if record is not None:
                write_record(resume, task.key, record)
                report.records.append(record)
            if error is not None:
                report.failures.append(error)
            if on_task:
                on_task(task, error)
    else:
        # One file: its failure is the run's failure, raised as such, and then there is nothing to record.
        report.records.append(run_task(tasks[0], options, on_frames))
    report.seconds = time.perf_counter() - started
    report.manifest = manifest
    write_manifest(manifest, input_path, output_path, options, report)
    return report


def _frame_estimate(task: Task) -> int:
    if task.kind != "video":
        return len(task.inputs)
    try:
        return probe_video(task.inputs[0]).frame_count or 0
    except DarksynthError:
        return 0
