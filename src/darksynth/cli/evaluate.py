"""The ``evaluate`` command: each method's synthetic noise against real noise on sets of real pairs, and the
command line that a report states it was made by."""

from __future__ import annotations

import dataclasses
import shlex
from pathlib import Path
from typing import Annotated

import typer

from darksynth.cli.common import QuietOption, console, default_of, fail, say
from darksynth.console_progress import progress_display
from darksynth.errors import DarksynthError
from darksynth.evaluation.run.options import EvaluationOptions


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
        arguments += ["--downstream-steps", str(options.downstream_steps), "--downstream-net", options.downstream_net]
    return shlex.join(["darksynth", "evaluate", *arguments, "--out", str(out)])


def evaluate_command(
    pairs: Annotated[
        list[Path], typer.Option("--pairs", help="Folder of real pairs (noisy/NAME, clean/NAME); repeatable.")
    ],
    out: Annotated[Path, typer.Option("--out", help="Folder for results.json, results.md and report.html.")],
    methods: Annotated[
        str,
        typer.Option(
            help=f"Comma-separated methods. Default: {', '.join(default_of(EvaluationOptions, 'methods'))}. "
            "Also by name: den-network (the network's values alone), den-prior (den with the texture dependence "
            "from the camera prior), den-prior-octaves (and the coarse octaves), "
            "spectral-oracle (the clean-aided fit), prior (whole cameras drawn from the camera prior, no "
            "reference) and albumentations' noise at its default ranges: albu-gauss (GaussNoise), albu-iso "
            "(ISONoise), albu-gauss-jpeg (GaussNoise + ImageCompression). The camera prior's methods use a prior "
            "fitted without the set judged."
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
    downstream_net: Annotated[
        str,
        typer.Option(
            help="Size of each downstream denoiser: small (16 channels, 5 layers; minutes per method on a CPU) or "
            "dncnn (64 channels, 17 layers, DnCNN's; for a GPU with --device cuda and tens of thousands of steps)."
        ),
    ] = default_of(EvaluationOptions, "downstream_net"),
    quiet: QuietOption = False,
) -> None:
    from darksynth.evaluation.run.job import rank_by_kld, run_evaluation

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
            downstream_net=downstream_net,
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
