"""The commands of the estimation network: ``train`` the DEN, ``estimate`` a profile from a real reference with it."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, cast

import typer

from darksynth.cli.common import VARIANTS, QuietOption, checked_choice, console, default_of, fail, say
from darksynth.console_progress import progress_display
from darksynth.errors import DarksynthError, error_reason
from darksynth.estimation.assemble import EstimateOptions
from darksynth.estimation.noise.camera_conditional import CameraPriorUse
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.models.den import DENConfig, Variant
from darksynth.noise.components import NoiseModel
from darksynth.training.loop import TrainConfig
from darksynth.training.weights import LOG_LEVELS, NETWORK_MODELS, DENChoice


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
    quiet: QuietOption = False,
) -> None:
    from darksynth.training.corpus import load_corpus
    from darksynth.training.distributed import ranks_from_environment
    from darksynth.training.loop import train

    try:
        noise_model = cast(NoiseModel, checked_choice("--model", model, NETWORK_MODELS))
        config = TrainConfig(
            steps=steps,
            batch=batch,
            frames=frames,
            crop=crop,
            learning_rate=learning_rate,
            seed=seed,
            device=device,
            den=DENConfig(
                variant=cast(Variant, checked_choice("--variant", variant, VARIANTS)),
                width=width,
                depth=depth,
                noise_model=noise_model,
                log_levels=LOG_LEVELS[noise_model],
            ),
            lambda_parameters=lambda_parameters,
            lambda_reconstruction=lambda_reconstruction,
            bright_fraction=bright_fraction,
            lambda_level=lambda_level,
            validate_every=validate_every,
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
    device: Annotated[str, typer.Option(help="torch device.")] = default_of(NoiseEstimateOptions, "device"),
    refine: Annotated[
        bool,
        typer.Option(
            "--refine/--no-refine",
            help="After the sRGB network, measure the noise's spectrum on the reference itself (per octave, in "
            "brightness and colour, per intensity, frame to frame; default, docs/spectral-noise.md); --no-refine "
            "keeps the network's values.",
        ),
    ] = default_of(NoiseEstimateOptions, "refine"),
    camera_prior: Annotated[
        bool,
        typer.Option(
            "--camera-prior/--no-camera-prior",
            help="Take what one reference cannot show (the noise's dependence on texture) from the shipped prior "
            "over real cameras, given what the reference shows (docs/camera-prior.md). Off by default: judged on "
            "real cameras it had not seen, the prior's expectation was further from the truth than none.",
        ),
    ] = default_of(NoiseEstimateOptions, "camera_prior") is not None,
    prior_octaves: Annotated[
        bool,
        typer.Option(
            "--prior-octaves",
            help="With --camera-prior, also take the coarse octaves the reference cannot show from the prior instead "
            "of continuing the finer ones (docs/camera-prior.md).",
        ),
    ] = default_of(CameraPriorUse, "octaves"),
    quiet: QuietOption = False,
) -> None:
    import json

    from darksynth.cameras.prior import shipped_prior
    from darksynth.estimation.assemble import estimate_file
    from darksynth.profile import profile_to_dict, save_profile
    from darksynth.training.weights import load_weights

    try:
        choice = DENChoice(
            weights=weights,
            noise_model=checked_choice("--model", model, NETWORK_MODELS),
            variant=checked_choice("--variant", variant, VARIANTS),
        )
        if prior_octaves and not camera_prior:
            raise fail("--prior-octaves needs --camera-prior")
        prior = CameraPriorUse(shipped_prior(), octaves=prior_octaves) if camera_prior else None
        noise = NoiseEstimateOptions(device=device, refine=refine, camera_prior=prior)
        options = EstimateOptions(clip=clip, noise=noise)
        network = load_weights(choice.path(), device=device)
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
