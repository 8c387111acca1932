"""The commands that put a profile's noise on clean material: ``apply`` (images, videos, folders), ``convert`` (a
whole annotated dataset), ``preview`` (one image, before converting) and ``demo`` (the shipped sample)."""

from __future__ import annotations

import secrets
from pathlib import Path
from typing import Annotated, cast

import typer

from darksynth.apply import ApplyOptions, ApplyReport, Task, apply
from darksynth.cameras.presets import CAMERA_CHOICES
from darksynth.cli.common import (
    QuietOption,
    checked_choice,
    console,
    darkening_choice,
    default_of,
    fail,
    say,
)
from darksynth.cli.synthesis_options import (
    AlphaOption,
    BlurOption,
    CameraOption,
    CodecOption,
    CrfOption,
    DeviceOption,
    FlickerOption,
    GammaOption,
    JitterOption,
    MatchColourOption,
    NoDarkenOption,
    PixFmtOption,
    ProfileOption,
)
from darksynth.console_progress import progress_display
from darksynth.datasets import FORMATS, ConversionReport, ConvertOptions, DatasetFormat, Shard
from darksynth.errors import DarksynthError
from darksynth.io.video_encoding import VideoEncoding
from darksynth.preview import PANEL_SIZE
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import ClipRecipe, DarkeningChoice


def _recipe(
    profile: Path | None,
    camera: str | None,
    darkening: DarkeningChoice,
    *,
    jitter: bool,
    blur: bool,
    flicker: bool,
    match_colour: bool,
) -> tuple[ClipRecipe, Path]:
    """The recipe a command's options ask for, and the profile file it read (kept for the manifest): ``--profile``,
    or without it, when ``--camera`` draws the noise, the default profile (its darkening and column noise stay).

    Raises:
        DarksynthError: neither is given, or ``--camera`` names no camera.
    """
    if camera is not None:
        checked_choice("--camera", camera, CAMERA_CHOICES)
    if profile is None and camera is None:
        raise DarksynthError("give --profile (a noise profile, e.g. from darksynth estimate) or --camera NAME")
    path = profile if profile is not None else default_profile_path()
    recipe = ClipRecipe(
        load_profile(path),
        darkening=darkening,
        jitter=jitter,
        blur=blur,
        flicker=flicker,
        match_colour=match_colour,
        camera=camera,
    )
    return recipe, path


def _run_seed(seed: int | None) -> int:
    """``--seed``, or a random one (recorded in the manifest and printed) when it is omitted."""
    return seed if seed is not None else secrets.randbits(31)


def run_with_progress(
    input_path: Path, output_path: Path, options: ApplyOptions, *, quiet: bool = False
) -> ApplyReport:
    """Run ``apply`` showing its progress over frames and the outcome of each failed task."""
    with progress_display(console, "apply", unit="frames", quiet=quiet) as display:

        def on_start(tasks: list[Task], total_frames: int) -> None:
            display.update(total=total_frames or None, description=f"{len(tasks)} file(s)")

        def on_task(task: Task, error: str | None) -> None:
            if options.workers > 1:
                display.advance(len(task.inputs) if task.kind != "video" else 0)
            if error is not None:
                display.say(f"darksynth: error: {error}")

        return apply(input_path, output_path, options, on_start=on_start, on_frames=display.advance, on_task=on_task)


def apply_command(
    input_path: Annotated[Path, typer.Argument(metavar="INPUT", help="Clean image, video, or folder of them.")],
    output_path: Annotated[Path, typer.Argument(metavar="OUTPUT", help="Output file or folder (never inside INPUT).")],
    profile: ProfileOption = None,
    seed: Annotated[int | None, typer.Option(help="Run seed; random (and recorded) when omitted.")] = None,
    alpha: AlphaOption = None,
    gamma: GammaOption = None,
    no_darken: NoDarkenOption = False,
    clip: Annotated[bool, typer.Option("--clip", help="Each folder of frames is one clip.")] = default_of(
        ApplyOptions, "clip"
    ),
    jitter: JitterOption = default_of(ClipRecipe, "jitter"),
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace outputs that exist (otherwise the run is refused).")
    ] = default_of(ApplyOptions, "overwrite"),
    workers: Annotated[int, typer.Option(min=1, help="Processes for folders.")] = default_of(ApplyOptions, "workers"),
    codec: CodecOption = default_of(VideoEncoding, "codec"),
    crf: CrfOption = default_of(VideoEncoding, "crf"),
    pix_fmt: PixFmtOption = default_of(VideoEncoding, "pix_fmt"),
    device: DeviceOption = default_of(ApplyOptions, "device"),
    blur: BlurOption = default_of(ClipRecipe, "blur"),
    flicker: FlickerOption = default_of(ClipRecipe, "flicker"),
    match_colour: MatchColourOption = default_of(ClipRecipe, "match_colour"),
    camera: CameraOption = default_of(ClipRecipe, "camera"),
    compile_kernel: Annotated[
        bool | None, typer.Option("--compile/--no-compile", help="Fuse the 8-bit kernel (default: for long clips).")
    ] = default_of(ApplyOptions, "compile"),
    quiet: QuietOption = False,
) -> None:
    try:
        darkening = darkening_choice(alpha, gamma, no_darken)
        recipe, source = _recipe(
            profile, camera, darkening, jitter=jitter, blur=blur, flicker=flicker, match_colour=match_colour
        )
        options = ApplyOptions(
            recipe=recipe,
            seed=_run_seed(seed),
            overwrite=overwrite,
            clip=clip,
            workers=workers,
            encoding=VideoEncoding(codec=codec, crf=crf, pix_fmt=pix_fmt),
            device=device,
            compile=compile_kernel,
            profile_source=str(source),
        )
        report = run_with_progress(input_path, output_path, options, quiet=quiet)
    except DarksynthError as error:
        raise fail(str(error)) from None
    frames = sum(int(r["frames"]) for r in report.records)
    if not quiet:
        resumed = f" ({len(report.records) - report.already_done} new, {report.already_done} already done)"
        say(
            f"wrote {len(report.records)} file(s){resumed if report.already_done else ''}, {frames} frame(s) in "
            f"{report.seconds:.1f} s; seed {options.seed}; manifest {report.manifest}"
        )
    if report.skipped and not quiet:
        say(f"skipped {len(report.skipped)} file(s) that are not images or videos: {', '.join(report.skipped)}")
    if report.failures:
        raise fail(f"{len(report.failures)} file(s) failed; see the messages above and the manifest")


def convert_command(
    dataset: Annotated[Path, typer.Argument(metavar="DATASET", help="Root folder of the annotated dataset.")],
    output: Annotated[Path, typer.Argument(metavar="OUTPUT", help="Output folder (never inside DATASET).")],
    dataset_format: Annotated[
        str, typer.Option("--format", "-f", help="coco, yolo, folder (class per folder) or video-folder.")
    ],
    profile: ProfileOption = None,
    seed: Annotated[int, typer.Option(help="Run seed (the same seed gives the same bytes).")] = default_of(
        ConvertOptions, "seed"
    ),
    workers: Annotated[int, typer.Option(min=1, help="Processes on this machine.")] = default_of(
        ConvertOptions, "workers"
    ),
    jitter: JitterOption = default_of(ClipRecipe, "jitter"),
    shard: Annotated[str | None, typer.Option(help="Convert only part K of N (1-based), e.g. 3/8.")] = default_of(
        ConvertOptions, "shard"
    ),
    images_root: Annotated[
        Path | None, typer.Option("--images-root", help="COCO: folder that file_name entries are relative to.")
    ] = default_of(ConvertOptions, "images_root"),
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Start over in an output written with other options.")
    ] = default_of(ConvertOptions, "overwrite"),
    codec: CodecOption = default_of(VideoEncoding, "codec"),
    crf: CrfOption = default_of(VideoEncoding, "crf"),
    pix_fmt: PixFmtOption = default_of(VideoEncoding, "pix_fmt"),
    device: DeviceOption = default_of(ConvertOptions, "device"),
    blur: BlurOption = default_of(ClipRecipe, "blur"),
    flicker: FlickerOption = default_of(ClipRecipe, "flicker"),
    match_colour: MatchColourOption = default_of(ClipRecipe, "match_colour"),
    camera: CameraOption = default_of(ClipRecipe, "camera"),
    use_ray: Annotated[
        bool,
        typer.Option(
            "--ray",
            help="Run as a Ray Data map on the Ray cluster RAY_ADDRESS names (a local one if unset); "
            "needs darksynth[ray].",
        ),
    ] = False,
    quiet: QuietOption = False,
) -> None:
    from darksynth.datasets import convert_dataset

    try:
        recipe, _ = _recipe(
            profile, camera, "profile", jitter=jitter, blur=blur, flicker=flicker, match_colour=match_colour
        )
        options = ConvertOptions(
            dataset=dataset,
            output=output,
            recipe=recipe,
            format=cast(DatasetFormat, checked_choice("--format", dataset_format, FORMATS)),
            seed=seed,
            workers=workers,
            shard=None if shard is None else Shard.parse(shard),
            images_root=images_root,
            overwrite=overwrite,
            encoding=VideoEncoding(codec=codec, crf=crf, pix_fmt=pix_fmt),
            device=device,
        )
        if use_ray:
            from darksynth.datasets.ray_convert import convert_dataset_with_ray

            report = convert_dataset_with_ray(options, on_failure=lambda message: say(f"darksynth: error: {message}"))
        else:
            with progress_display(console, "convert", unit="files", quiet=quiet) as display:

                def on_progress(finished: int, total: int) -> None:
                    display.update(completed=finished, total=total)

                def on_failure(message: str) -> None:
                    display.say(f"darksynth: error: {message}")

                report = convert_dataset(options, on_progress=on_progress, on_failure=on_failure)
    except DarksynthError as error:
        raise fail(str(error)) from None
    _convert_summary(report, quiet=quiet)


def _convert_summary(report: ConversionReport, *, quiet: bool) -> None:
    """The closing lines of a conversion (none with ``quiet``); exit 1 after them if anything failed."""
    if not quiet:
        done = report.converted + report.already_done
        say(
            f"converted {done} file(s) ({report.converted} new, {report.already_done} already done), carried over "
            f"{report.carried} file(s), {len(report.failures)} failure(s), in {report.seconds:.1f} s"
        )
        if report.other_shards:
            say(f"left {report.other_shards} file(s) to other shards")
        if report.manifest is not None:
            say(f"manifest {report.manifest}")
        else:
            say(f"manifest not written yet: {report.pending} file(s) of other shards have no record yet")
    if report.failures:
        raise fail(f"{len(report.failures)} failure(s); see the messages above and the manifest")


def preview_command(
    image: Annotated[Path, typer.Argument(metavar="IMAGE", help="One clean image.")],
    profile: ProfileOption = None,
    out: Annotated[Path, typer.Option("--out", help="Preview image to write.")] = Path("preview.png"),
    seed: Annotated[int | None, typer.Option(help="Run seed, as apply's; random (and printed) when omitted.")] = None,
    alpha: AlphaOption = None,
    gamma: GammaOption = None,
    no_darken: NoDarkenOption = False,
    crop: Annotated[
        str, typer.Option(help="Largest panel, WIDTHxHEIGHT or SIDE; a larger image is shown by its centre.")
    ] = "x".join(map(str, PANEL_SIZE)),
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing OUT.")] = False,
    device: DeviceOption = default_of(ApplyOptions, "device"),
    blur: BlurOption = default_of(ClipRecipe, "blur"),
    flicker: FlickerOption = default_of(ClipRecipe, "flicker"),
    match_colour: MatchColourOption = default_of(ClipRecipe, "match_colour"),
    camera: CameraOption = default_of(ClipRecipe, "camera"),
) -> None:
    from darksynth.preview import PreviewOptions, parse_panel_size, run_preview

    try:
        darkening = darkening_choice(alpha, gamma, no_darken)
        recipe, source = _recipe(
            profile,
            camera,
            darkening,
            jitter=default_of(ClipRecipe, "jitter"),
            blur=blur,
            flicker=flicker,
            match_colour=match_colour,
        )
        options = PreviewOptions(
            # --overwrite here replaces OUT, the preview's own file, not outputs of apply's.
            synthesis=ApplyOptions(recipe=recipe, seed=_run_seed(seed), device=device, profile_source=str(source)),
            panel_size=parse_panel_size(crop),
            overwrite=overwrite,
            profile_path=profile,
        )
        report = run_preview(image, out, options)
    except DarksynthError as error:
        raise fail(str(error)) from None
    for warning in report.warnings:
        say(f"darksynth: warning: {warning}")
    width, height = report.panel_size
    say(
        f"wrote {report.output}: {len(report.labels)} panels of {width}x{height}, seed {options.synthesis.seed}, "
        f"dark panels brightened x{report.gain:.1f}"
    )


def demo_command(
    out: Annotated[Path, typer.Option(help="Folder to write the demo into.")] = Path("darksynth-demo"),
    seed: Annotated[int, typer.Option(help="Seed of the demo.")] = 0,
) -> None:
    from darksynth.demo import run_demo

    try:
        written = run_demo(out, seed=seed)
    except DarksynthError as error:
        raise fail(str(error)) from None
    for path in written:
        say(f"wrote {path}")
