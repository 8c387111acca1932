"""The command line: the only place that parses arguments and wires objects together."""

from __future__ import annotations

import dataclasses
import logging
import os
import secrets
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, cast, get_args

import typer
from rich.console import Console

from darksynth.apply import ApplyOptions, ApplyReport, Task, apply
from darksynth.commands import COMMAND_HELP, new_app
from darksynth.console_progress import progress_display
from darksynth.darkening import Darkening
from darksynth.datasets import FORMATS, ConversionReport, ConvertOptions, DatasetFormat, Shard
from darksynth.errors import DarksynthError, error_reason
from darksynth.estimation.assemble import EstimateOptions
from darksynth.evaluation.options import EvaluationOptions
from darksynth.models.den import DENConfig, Variant
from darksynth.noise.components import NoiseModel
from darksynth.preview import PANEL_SIZE
from darksynth.profile import load_profile
from darksynth.synthesize import DarkeningChoice
from darksynth.training.loop import TrainConfig
from darksynth.training.weights import LOG_LEVELS, NETWORK_MODELS, DENChoice

app = new_app()
console = Console(stderr=True)


def say(message: str, target: Console = console) -> None:
    """Print a message as is: no markup, no highlighting, never wrapped, so that an error stays one line."""
    target.print(message, markup=False, highlight=False, soft_wrap=True)


class WarningLines(logging.Handler):
    """The library's logged warnings as the command line's own lines, ``darksynth: warning: ...`` on stderr
    (through the console, so that they print above a progress bar instead of through it)."""

    def emit(self, record: logging.LogRecord) -> None:
        kind = "error" if record.levelno >= logging.ERROR else "warning"
        say(f"darksynth: {kind}: {' '.join(record.getMessage().split())}")


_library_logger = logging.getLogger("darksynth")
if not any(isinstance(handler, WarningLines) for handler in _library_logger.handlers):
    _library_logger.addHandler(WarningLines(logging.WARNING))


def fail(message: str) -> typer.Exit:
    """Print a one-line error and return the exit to raise."""
    say(f"darksynth: error: {message}")
    return typer.Exit(code=1)


def default_of(options: type[Any], name: str) -> Any:
    """The default of a field of a job's options dataclass: the command line writes no default of its own."""
    for option in dataclasses.fields(options):
        if option.name == name:
            if option.default is not dataclasses.MISSING:
                return option.default
            if option.default_factory is not dataclasses.MISSING:
                return option.default_factory()
            raise TypeError(f"{options.__name__}.{name} has no default")
    raise TypeError(f"{options.__name__} has no field {name!r}")


def checked_choice(flag: str, value: str, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``, else a one-line error naming the flag."""
    if value not in choices:
        allowed = " or ".join(choices) if len(choices) == 2 else f"one of {', '.join(choices)}"
        raise DarksynthError(f"{flag} must be {allowed}, got {value!r}")
    return value


VARIANTS: tuple[str, ...] = get_args(Variant)


def darkening_choice(alpha: float | None, gamma: float | None, no_darken: bool) -> DarkeningChoice:
    """Turn the darkening flags into a choice, rejecting contradictory ones."""
    if no_darken:
        if alpha is not None or gamma is not None:
            raise DarksynthError("--no-darken cannot be combined with --alpha or --gamma")
        return None
    if (alpha is None) != (gamma is None):
        raise DarksynthError("--alpha and --gamma must be given together")
    if alpha is None or gamma is None:
        return "profile"
    if not 0.0 < alpha <= 1.0:
        raise DarksynthError(f"--alpha must lie in (0, 1], got {alpha}")
    if not 0.0 < gamma <= 10.0:
        raise DarksynthError(f"--gamma must lie in (0, 10], got {gamma}")
    return Darkening(alpha=alpha, gamma=gamma)


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


JITTER_HELP = "Draw each file's or clip's parameters within the profile's ranges (default: the profile's values)."
QUIET_HELP = "No progress and no summary; warnings and errors are still printed."


@app.command("apply", help=COMMAND_HELP["apply"])
def apply_command(
    input_path: Annotated[Path, typer.Argument(metavar="INPUT", help="Clean image, video, or folder of them.")],
    output_path: Annotated[Path, typer.Argument(metavar="OUTPUT", help="Output file or folder (never inside INPUT).")],
    profile: Annotated[Path, typer.Option("--profile", "-p", help="Noise profile JSON.")],
    seed: Annotated[int | None, typer.Option(help="Run seed; random (and recorded) when omitted.")] = None,
    alpha: Annotated[float | None, typer.Option(help="Darkening scale, with --gamma.")] = None,
    gamma: Annotated[float | None, typer.Option(help="Darkening exponent: x_d = alpha * x ** (1/gamma).")] = None,
    no_darken: Annotated[bool, typer.Option("--no-darken", help="Add noise only, keep the brightness.")] = False,
    clip: Annotated[bool, typer.Option("--clip", help="Each folder of frames is one clip.")] = default_of(
        ApplyOptions, "clip"
    ),
    jitter: Annotated[bool, typer.Option("--jitter", help=JITTER_HELP)] = default_of(ApplyOptions, "jitter"),
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace outputs that exist (otherwise the run is refused).")
    ] = default_of(ApplyOptions, "overwrite"),
    workers: Annotated[int, typer.Option(min=1, help="Processes for folders.")] = default_of(ApplyOptions, "workers"),
    codec: Annotated[str | None, typer.Option(help="Video codec, e.g. libx264 (default), ffv1.")] = default_of(
        ApplyOptions, "codec"
    ),
    crf: Annotated[int | None, typer.Option(min=0, max=63, help="Video quality (lower is better).")] = default_of(
        ApplyOptions, "crf"
    ),
    pix_fmt: Annotated[
        str | None, typer.Option("--pix-fmt", help="Video pixel format, e.g. yuv444p (default yuv420p for H.264).")
    ] = default_of(ApplyOptions, "pix_fmt"),
    device: Annotated[str, typer.Option(help="torch device: cpu, cuda, cuda:1 ...")] = default_of(
        ApplyOptions, "device"
    ),
    compile_kernel: Annotated[
        bool | None, typer.Option("--compile/--no-compile", help="Fuse the 8-bit kernel (default: for long clips).")
    ] = default_of(ApplyOptions, "compile"),
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
) -> None:
    try:
        options = ApplyOptions(
            profile=load_profile(profile),
            seed=seed if seed is not None else secrets.randbits(31),
            darkening=darkening_choice(alpha, gamma, no_darken),
            jitter=jitter,
            overwrite=overwrite,
            clip=clip,
            workers=workers,
            codec=codec,
            crf=crf,
            pix_fmt=pix_fmt,
            device=device,
            compile=compile_kernel,
            profile_source=str(profile),
        )
        report = run_with_progress(input_path, output_path, options, quiet=quiet)
    except DarksynthError as error:
        raise fail(str(error)) from None
    frames = sum(int(r["frames"]) for r in report.records)
    if not quiet:
        say(
            f"wrote {len(report.records)} file(s), {frames} frame(s) in {report.seconds:.1f} s; "
            f"seed {options.seed}; manifest {report.manifest}"
        )
    if report.skipped and not quiet:
        say(f"skipped {len(report.skipped)} file(s) that are not images or videos: {', '.join(report.skipped)}")
    if report.failures:
        raise fail(f"{len(report.failures)} file(s) failed; see the messages above and the manifest")


@app.command("convert", help=COMMAND_HELP["convert"])
def convert_command(
    dataset: Annotated[Path, typer.Argument(metavar="DATASET", help="Root folder of the annotated dataset.")],
    output: Annotated[Path, typer.Argument(metavar="OUTPUT", help="Output folder (never inside DATASET).")],
    profile: Annotated[Path, typer.Option("--profile", "-p", help="Noise profile JSON.")],
    dataset_format: Annotated[
        str, typer.Option("--format", "-f", help="coco, yolo, folder (class per folder) or video-folder.")
    ],
    seed: Annotated[int, typer.Option(help="Run seed (the same seed gives the same bytes).")] = default_of(
        ConvertOptions, "seed"
    ),
    workers: Annotated[int, typer.Option(min=1, help="Processes on this machine.")] = default_of(
        ConvertOptions, "workers"
    ),
    jitter: Annotated[bool, typer.Option("--jitter", help=JITTER_HELP)] = default_of(ConvertOptions, "jitter"),
    shard: Annotated[str | None, typer.Option(help="Convert only part K of N (1-based), e.g. 3/8.")] = default_of(
        ConvertOptions, "shard"
    ),
    images_root: Annotated[
        Path | None, typer.Option("--images-root", help="COCO: folder that file_name entries are relative to.")
    ] = default_of(ConvertOptions, "images_root"),  # noqa: B008 (a dataclass default: immutable, read once)
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Start over in an output written with other options.")
    ] = default_of(ConvertOptions, "overwrite"),
    codec: Annotated[str | None, typer.Option(help="Video codec, e.g. libx264 (default), ffv1.")] = default_of(
        ConvertOptions, "codec"
    ),
    crf: Annotated[int | None, typer.Option(min=0, max=63, help="Video quality (lower is better).")] = default_of(
        ConvertOptions, "crf"
    ),
    pix_fmt: Annotated[
        str | None, typer.Option("--pix-fmt", help="Video pixel format, e.g. yuv444p (default yuv420p for H.264).")
    ] = default_of(ConvertOptions, "pix_fmt"),
    device: Annotated[str, typer.Option(help="torch device: cpu, cuda, cuda:1 ...")] = default_of(
        ConvertOptions, "device"
    ),
    use_ray: Annotated[
        bool,
        typer.Option(
            "--ray",
            help="Run as a Ray Data map on the Ray cluster RAY_ADDRESS names (a local one if unset); "
            "needs darksynth[ray].",
        ),
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
) -> None:
    from darksynth.datasets import convert_dataset

    try:
        options = ConvertOptions(
            dataset=dataset,
            output=output,
            profile=load_profile(profile),
            format=cast(DatasetFormat, checked_choice("--format", dataset_format, FORMATS)),
            seed=seed,
            jitter=jitter,
            workers=workers,
            shard=None if shard is None else Shard.parse(shard),
            images_root=images_root,
            overwrite=overwrite,
            codec=codec,
            crf=crf,
            pix_fmt=pix_fmt,
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
        _convert_counts(report)
    if report.failures:
        raise fail(f"{len(report.failures)} failure(s); see the messages above and the manifest")


def _convert_counts(report: ConversionReport) -> None:
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


@app.command("train", help=COMMAND_HELP["train"])
def train_command(
    data: Annotated[list[Path], typer.Argument(help="Clean images, folders of them, and videos.")],
    out: Annotated[Path, typer.Option("--out", help="Weights file to write (.safetensors).")],
    clips: Annotated[
        list[Path] | None, typer.Option("--clips", help="Folder whose sub-folders of frames and videos are clips.")
    ] = None,
    holdout: Annotated[
        list[Path] | None, typer.Option("--holdout", help="Clean material for validation only (never trained on).")
    ] = None,
    variant: Annotated[str, typer.Option(help="v3 (U-Net + head) or v2 (encoder + head).")] = default_of(
        DENConfig, "variant"
    ),
    model: Annotated[
        str, typer.Option("--model", help="Noise model: srgb (paper + sRGB structure, default) or paper.")
    ] = default_of(DENConfig, "noise_model"),
    width: Annotated[
        int, typer.Option(min=4, help="Channels of the first level (the shipped DENs: 8, docs/den.md).")
    ] = default_of(DENConfig, "width"),
    depth: Annotated[int, typer.Option(min=1, max=5, help="Down-sampling steps.")] = default_of(DENConfig, "depth"),
    steps: Annotated[int, typer.Option(min=1)] = default_of(TrainConfig, "steps"),
    batch: Annotated[int, typer.Option(min=1)] = default_of(TrainConfig, "batch"),
    frames: Annotated[int, typer.Option(min=1, help="Frames per training clip.")] = default_of(TrainConfig, "frames"),
    crop: Annotated[int, typer.Option(min=32, help="Side of the square training crops.")] = default_of(
        TrainConfig, "crop"
    ),
    learning_rate: Annotated[float, typer.Option("--lr", help="Adam learning rate (paper: 2e-4).")] = default_of(
        TrainConfig, "learning_rate"
    ),
    lambda_parameters: Annotated[float, typer.Option("--lambda1", help="Weight of MSE(v_hat, v).")] = default_of(
        TrainConfig, "lambda_parameters"
    ),
    lambda_reconstruction: Annotated[float, typer.Option("--lambda2", help="Weight of L1(x_hat_d, x_d).")] = default_of(
        TrainConfig, "lambda_reconstruction"
    ),
    validate_every: Annotated[int, typer.Option(min=1)] = default_of(TrainConfig, "validate_every"),
    bright_fraction: Annotated[
        float,
        typer.Option(
            min=0.0,
            max=1.0,
            help="Share of clips darkened less than the paper's ranges (real references are often brighter).",
        ),
    ] = default_of(TrainConfig, "bright_fraction"),
    lambda_level: Annotated[
        float,
        typer.Option(
            "--lambda-level",
            min=0.0,
            help="Weight of the noise-level target (log-ratio of the clip's mean noise variance); 0: paper loss.",
        ),
    ] = default_of(TrainConfig, "lambda_level"),
    seed: Annotated[int, typer.Option()] = default_of(TrainConfig, "seed"),
    resume: Annotated[bool, typer.Option("--resume", help="Continue from OUT's checkpoint.")] = False,
    device: Annotated[str, typer.Option(help="torch device.")] = default_of(TrainConfig, "device"),
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
) -> None:
    from darksynth.training.corpus import load_corpus
    from darksynth.training.distributed import ranks_from_environment
    from darksynth.training.loop import train

    try:
        noise_model = cast(NoiseModel, checked_choice("--model", model, NETWORK_MODELS))
        config = TrainConfig(
            den=DENConfig(
                variant=cast(Variant, checked_choice("--variant", variant, VARIANTS)),
                width=width,
                depth=depth,
                noise_model=noise_model,
                log_levels=LOG_LEVELS[noise_model],
            ),
            steps=steps,
            batch=batch,
            frames=frames,
            crop=crop,
            learning_rate=learning_rate,
            lambda_parameters=lambda_parameters,
            lambda_reconstruction=lambda_reconstruction,
            validate_every=validate_every,
            bright_fraction=bright_fraction,
            lambda_level=lambda_level,
            seed=seed,
            device=device,
        )
        ranks = ranks_from_environment(os.environ)  # torchrun's WORLD_SIZE, RANK, LOCAL_RANK; none: one process
        corpus = load_corpus(data, clips or [], minimum_side=crop)
        held = load_corpus(holdout, minimum_side=crop) if holdout else corpus
        if ranks.is_main and not quiet:
            say(f"training on {len(corpus.images)} images and {len(corpus.clips)} clips; validating on {len(held)}")
        # Only the main process of a torchrun job reports.
        with progress_display(console, "train", unit="steps", quiet=quiet or not ranks.is_main) as display:
            display.update(total=steps)

            def on_step(step: int, loss: float, report: dict[str, object] | None) -> None:
                display.update(completed=step, description=f"loss {loss:.4f}")
                if report is not None and ranks.is_main and not quiet:
                    display.say(f"step {step}: validation R2 {report['r2']}")

            summary = train(corpus, held, config, out, resume=resume, progress=on_step, ranks=ranks)
    except DarksynthError as error:
        raise fail(str(error)) from None
    if ranks.is_main and not quiet:
        say(f"wrote {out} and {out.with_suffix('.json')} after {summary['steps']} steps")


@app.command("estimate", help=COMMAND_HELP["estimate"])
def estimate_command(
    reference: Annotated[Path, typer.Argument(help="Real low-light image, video, or frame folder (with --clip).")],
    out: Annotated[Path | None, typer.Option("--out", help="Profile JSON to write (stdout when omitted).")] = None,
    clip: Annotated[bool, typer.Option("--clip", help="REFERENCE is a folder of frames of one clip.")] = default_of(
        EstimateOptions, "clip"
    ),
    weights: Annotated[Path | None, typer.Option(help="DEN weights (default: the shipped model of --variant).")] = None,
    variant: Annotated[
        str, typer.Option(help="Shipped DEN to use without --weights: v3 (full, default) or v2 (ablation).")
    ] = default_of(DENChoice, "variant"),
    model: Annotated[
        str,
        typer.Option(
            "--model",
            help="Shipped noise model without --weights: srgb (the paper's components plus sRGB structure, "
            "default) or paper (the paper's five components, white noise).",
        ),
    ] = default_of(DENChoice, "noise_model"),
    device: Annotated[str, typer.Option(help="torch device.")] = default_of(EstimateOptions, "device"),
    refine: Annotated[
        bool,
        typer.Option(
            "--refine/--no-refine",
            help="Refine the sRGB network's noise on the reference itself by analysis by synthesis (default; "
            "stronger, closer to the real pairs' noise, see docs/refine.md); --no-refine keeps the network's values.",
        ),
    ] = default_of(EstimateOptions, "refine"),
    spectrum: Annotated[
        bool,
        typer.Option(
            "--spectrum/--no-spectrum",
            help="With the sRGB model and --refine, measure the noise's spectrum on the reference (per octave, in "
            "brightness and colour, per intensity, frame to frame; default, docs/spectral-noise.md); --no-spectrum "
            "gives the version-3 profile (one length per part, refined as in docs/refine.md).",
        ),
    ] = default_of(EstimateOptions, "spectrum"),
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
) -> None:
    import json

    from darksynth.estimation.assemble import estimate_file
    from darksynth.profile import profile_to_dict, save_profile
    from darksynth.training.weights import load_weights

    try:
        choice = DENChoice(
            weights=weights,
            noise_model=checked_choice("--model", model, NETWORK_MODELS),
            variant=checked_choice("--variant", variant, VARIANTS),
        )
        options = EstimateOptions(clip=clip, device=device, refine=refine, spectrum=spectrum)
        network = load_weights(choice.path(), device=options.device)
        result = estimate_file(reference, network, options)
    except DarksynthError as error:
        raise fail(str(error)) from None
    for warning in result.warnings:
        say(f"darksynth: warning: {warning}")
    if out is None:
        typer.echo(json.dumps(profile_to_dict(result.profile), indent=2))
        return
    try:
        save_profile(out, result.profile)
    except OSError as error:
        raise fail(f"{out}: {error_reason(error)}") from None
    if not quiet:
        say(f"wrote {out} from {result.per_crop.batch_shape[0]} crops")


@app.command("preview", help=COMMAND_HELP["preview"])
def preview_command(
    image: Annotated[Path, typer.Argument(metavar="IMAGE", help="One clean image.")],
    profile: Annotated[Path, typer.Option("--profile", "-p", help="Noise profile JSON.")],
    out: Annotated[Path, typer.Option("--out", help="Preview image to write.")] = Path("preview.png"),
    seed: Annotated[int | None, typer.Option(help="Run seed, as apply's; random (and printed) when omitted.")] = None,
    alpha: Annotated[float | None, typer.Option(help="Darkening scale, with --gamma.")] = None,
    gamma: Annotated[float | None, typer.Option(help="Darkening exponent: x_d = alpha * x ** (1/gamma).")] = None,
    no_darken: Annotated[bool, typer.Option("--no-darken", help="Add noise only, keep the brightness.")] = False,
    crop: Annotated[
        str, typer.Option(help="Largest panel, WIDTHxHEIGHT or SIDE; a larger image is shown by its centre.")
    ] = "x".join(map(str, PANEL_SIZE)),
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing OUT.")] = False,
    device: Annotated[str, typer.Option(help="torch device: cpu, cuda, cuda:1 ...")] = default_of(
        ApplyOptions, "device"
    ),
) -> None:
    from darksynth.preview import PreviewOptions, parse_panel_size, run_preview

    try:
        options = PreviewOptions(
            synthesis=ApplyOptions(
                profile=load_profile(profile),
                seed=seed if seed is not None else secrets.randbits(31),
                darkening=darkening_choice(alpha, gamma, no_darken),
                device=device,
                profile_source=str(profile),
            ),
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


def parse_weights(entries: list[str]) -> dict[str, Path]:
    """``NAME=FILE`` options into a mapping, rejecting malformed ones."""
    weights: dict[str, Path] = {}
    for entry in entries:
        name, sep, file = entry.partition("=")
        if not sep or not name or not file:
            raise DarksynthError(f"--weights {entry!r}: expected METHOD=FILE, for example den-v2=den_v2.safetensors")
        weights[name] = Path(file)
    return weights


def evaluate_command_line(pairs: list[Path], out: Path, options: EvaluationOptions) -> str:
    """The command that asks for this evaluation, every option spelled out, so that a report states exactly
    what produced it."""
    arguments = [part for path in pairs for part in ("--pairs", str(path))]
    arguments += ["--methods", ",".join(options.methods)]
    arguments += [part for name, file in options.weights.items() for part in ("--weights", f"{name}={file}")]
    arguments += ["--seed", str(options.seed), "--device", options.device] + ([] if options.inception else ["--no-fid"])
    for root in options.downstream:
        arguments += ["--downstream", str(root)]
    if options.downstream:
        arguments += ["--downstream-steps", str(options.downstream_steps)]
    return shlex.join(["darksynth", "evaluate", *arguments, "--out", str(out)])


@app.command("evaluate", help=COMMAND_HELP["evaluate"])
def evaluate_command(
    pairs: Annotated[
        list[Path], typer.Option("--pairs", help="Folder of real pairs (noisy/NAME, clean/NAME); repeatable.")
    ],
    out: Annotated[Path, typer.Option("--out", help="Folder for results.json, results.md and report.html.")],
    methods: Annotated[
        str,
        typer.Option(
            help=f"Comma-separated methods. Default: {', '.join(default_of(EvaluationOptions, 'methods'))}. "
            "Also by name: srgb-oracle and its ablations (docs/srgb-noise.md)."
        ),
    ] = "",
    weights: Annotated[
        list[str] | None, typer.Option("--weights", help="METHOD=FILE weights for a DEN variant; repeatable.")
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the synthetic noise.")] = default_of(EvaluationOptions, "seed"),
    device: Annotated[str, typer.Option(help="torch device.")] = default_of(EvaluationOptions, "device"),
    inception: Annotated[bool, typer.Option("--fid/--no-fid", help="Compute FID and KID (InceptionV3).")] = default_of(
        EvaluationOptions, "inception"
    ),
    downstream: Annotated[
        list[Path] | None,
        typer.Option(
            "--downstream",
            help="Clean training images (folder; repeatable): also train a small denoiser on each method's "
            "noise and test it on the real pairs (PSNR, SSIM). About 25 s per set and method on a CPU.",
        ),
    ] = None,
    downstream_steps: Annotated[int, typer.Option(help="Training steps of each downstream denoiser.")] = default_of(
        EvaluationOptions, "downstream_steps"
    ),
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help=QUIET_HELP)] = False,
) -> None:
    from darksynth.evaluation.job import rank_by_kld, run_evaluation

    chosen = [m.strip() for m in methods.split(",") if m.strip()]
    try:
        options = EvaluationOptions(
            methods=chosen or default_of(EvaluationOptions, "methods"),
            seed=seed,
            device=device,
            weights=parse_weights(weights or []),
            inception=inception,
            downstream=tuple(downstream or ()),
            downstream_steps=downstream_steps,
        )
        options = dataclasses.replace(options, command=evaluate_command_line(pairs, out, options))
        with progress_display(console, "evaluate", quiet=quiet) as display:
            run = run_evaluation(pairs, out, options, progress=lambda message: display.update(description=message))
    except DarksynthError as error:
        raise fail(str(error)) from None
    for problem in run.results["problems"]:
        say(f"darksynth: warning: {problem}")
    if quiet:
        return
    for name, ranked in rank_by_kld(run.results).items():
        pair_count = run.results["sets"][name]["pairs"]
        say(f"{name} ({pair_count} pairs), kld: " + ", ".join(f"{m} {kld:.3f}" for m, kld in ranked))
    say(f"wrote {', '.join(str(path) for path in run.files[:-1])} and {run.files[-1]}")


@app.command("demo", help=COMMAND_HELP["demo"])
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


def main(argv: Sequence[str] | None = None) -> None:
    """Run a command (``argv``: the arguments after the program name; sys.argv's by default). The console
    script enters through :func:`darksynth.main.main`, which answers ``--version`` and ``--help`` without this
    module."""
    app(list(sys.argv[1:] if argv is None else argv), prog_name="darksynth")
