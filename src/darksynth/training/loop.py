"""The DEN's training: Adam on lambda1 * MSE(v_hat, v) + lambda2 * L1(x_hat_d, x_d), validation, checkpoints.

The step loop, the validation set's seed and the single-frame steps are the shared ones of
:mod:`darksynth.training.scaffold`; this module draws the batches, computes the loss, validates and checkpoints.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from safetensors import safe_open
from safetensors.torch import load_file, save_file

from darksynth.errors import DarksynthError
from darksynth.io.atomic import atomic_output, write_text_atomic
from darksynth.models.den import DEN, DENConfig
from darksynth.noise.components import NoiseModel, model_parameters
from darksynth.noise.level import mean_noise_variance
from darksynth.noise.values import NoiseValues, model_vector
from darksynth.seeding import seeded_generator
from darksynth.training.batches import TrainingBatch, synthesize_batch
from darksynth.training.corpus import CleanCorpus
from darksynth.training.distributed import (
    SINGLE_PROCESS,
    Ranks,
    all_agree,
    all_gather_tensor,
    all_state_digests,
    generator_key,
    per_process_batch,
    process_group,
    process_seed,
    rank_device,
    wrap_model,
)
from darksynth.training.scaffold import (
    Report,
    StepPlan,
    SyntheticTrainingConfig,
    calibration_clip_lengths,
    draw_validation_batches,
    initial_weights,
    run_steps,
)
from darksynth.training.weights import save_weights


def vector_names(noise_model: NoiseModel = "srgb") -> tuple[str, ...]:
    """A label for every entry of a noise model's v: ``shot``, ..., ``periodic[2]``."""
    return tuple(
        p.name if p.size == 1 else f"{p.name}[{i}]" for p in model_parameters(noise_model) for i in range(p.size)
    )


@dataclass(frozen=True)
class TrainConfig(SyntheticTrainingConfig):
    """The DEN's training settings (the paper's optimiser by default). Written beside the weights.

    ``lambda_level`` weighs a second target beyond the paper: the squared log-ratio of the mean noise variance
    the predicted v would give the clip to the true one (:func:`darksynth.noise.level.mean_noise_variance`), so
    that the network gets the overall level right even where shot and read cannot be told apart.

    Single-frame batches (``single_frame_every``) let one network serve image references (where temporal banding
    cannot be told from banding) and clips.
    """

    steps: int = 4000
    crop: int = 128
    learning_rate: float = 2e-4
    den: DENConfig = field(default_factory=DENConfig)
    lambda_parameters: float = 1.0
    lambda_reconstruction: float = 1.0
    bright_fraction: float = 0.0
    lambda_level: float = 0.0
    validate_every: int = 250


def training_batch(
    clean: torch.Tensor, config: TrainConfig, generator: torch.Generator, *, absent_probability: float | None = None
) -> TrainingBatch:
    """A synthetic batch drawn as ``config`` says (noise model, level prior, bright share); the configured
    absence probability unless one is given (validation uses 0)."""
    return synthesize_batch(
        clean,
        generator=generator,
        absent_probability=config.absent_probability if absent_probability is None else absent_probability,
        noise_model=config.den.noise_model,
        bright_fraction=config.bright_fraction,
        log_levels=config.den.log_levels,
    )


LEVEL_FLOOR = (0.5 / 255) ** 2
"""Variance added to both sides of the level loss: below half an 8-bit step, levels need not be told apart."""


def level_loss(predicted: NoiseValues, batch: TrainingBatch, device: torch.device) -> torch.Tensor:
    """Mean squared log-ratio of the clips' mean noise variance under the predicted and the true v."""
    dark = batch.dark.to(device)
    estimate = mean_noise_variance(predicted, dark)
    truth = mean_noise_variance(batch.values.to(device), dark)
    return ((estimate + LEVEL_FLOOR).log() - (truth + LEVEL_FLOOR).log()).square().mean()


def r_squared(predicted: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Coefficient of determination per column of (N, K) tensors."""
    residual = (predicted - truth).square().sum(0)
    total = (truth - truth.mean(0)).square().sum(0).clamp_min(1e-20)
    return 1.0 - residual / total


def validation_batches(holdout: CleanCorpus, config: TrainConfig, *, frames: int | None = None) -> list[TrainingBatch]:
    """The run's fixed validation set (:func:`~darksynth.training.scaffold.draw_validation_batches`): synthetic
    batches of ``frames``-frame clips (the configured length by default) from held-out material, every
    component present."""

    def draw(generator: torch.Generator) -> TrainingBatch:
        clean = config.clean_clips(holdout, frames or config.frames, config.crop, generator)
        return training_batch(clean, config, generator, absent_probability=0.0)

    return draw_validation_batches(draw, config.validation_size, config.batch, config.seed)


@torch.no_grad()
def evaluate(model: DEN, batches: list[TrainingBatch], device: torch.device) -> dict[str, Any]:
    """R^2 and mean absolute error of every entry of v over a synthetic set."""
    model.eval()
    predicted, truth = [], []
    for batch in batches:
        predicted.append(model_vector(model(batch.noisy.to(device)).values, model.noise_model).cpu())
        truth.append(batch.vector)
    model.train()
    p, t = torch.cat(predicted), torch.cat(truth)
    r2 = r_squared(p, t)
    mae = (p - t).abs().mean(0)
    names = vector_names(model.noise_model)
    return {
        "r2": {name: round(float(v), 4) for name, v in zip(names, r2, strict=True)},
        "mae": {name: float(v) for name, v in zip(names, mae, strict=True)},
        "samples": int(t.shape[0]),
    }


def _save_checkpoint(
    path: Path,
    model: DEN,
    optimizer: torch.optim.Optimizer,
    generator_states: list[torch.Tensor],
    step: int,
    history: list[dict[str, Any]],
    config: TrainConfig,
) -> None:
    """Write weights, Adam state and every process's data-generator state (in rank order); a checkpoint of a
    multi-process run also records how many processes made it."""
    tensors = {f"model.{k}": v.detach().cpu().contiguous() for k, v in model.state_dict().items()}
    state = optimizer.state_dict()
    for index, values in state["state"].items():
        for key, value in values.items():
            tensors[f"optimizer.{index}.{key}"] = torch.as_tensor(value).detach().cpu().contiguous()
    for rank, generator_state in enumerate(generator_states):
        tensors[generator_key(rank)] = generator_state
    metadata = {"step": str(step), "history": json.dumps(history), "config": json.dumps(config.to_dict())}
    if len(generator_states) > 1:
        metadata["processes"] = str(len(generator_states))
    with atomic_output(path) as temporary:
        save_file(tensors, str(temporary), metadata=metadata)


def _load_checkpoint(
    path: Path,
    model: DEN,
    optimizer: torch.optim.Optimizer,
    generator: torch.Generator,
    config: TrainConfig,
    ranks: Ranks = SINGLE_PROCESS,
) -> tuple[int, list[dict[str, Any]]]:
    try:
        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata() or {}
        tensors = load_file(str(path))
    except FileNotFoundError:
        raise DarksynthError(f"{path}: no checkpoint to resume from") from None
    except Exception as error:
        raise DarksynthError(f"{path}: unreadable checkpoint ({error})") from None
    saved = json.loads(metadata.get("config", "{}"))
    if saved.get("den") != config.den.to_dict():
        raise DarksynthError(f"{path}: checkpoint of another model shape {saved.get('model')}")
    processes = int(metadata.get("processes", "1"))
    if processes != ranks.world_size:
        # Each process resumes its own data stream: another count of processes cannot continue the same run.
        raise DarksynthError(
            f"{path}: checkpoint of a run on {processes} process(es); resume it on {processes}, not {ranks.world_size}"
        )
    model.load_state_dict({k[6:]: v for k, v in tensors.items() if k.startswith("model.")})
    state = optimizer.state_dict()
    for index in range(len(state["param_groups"][0]["params"])):
        entries = {k.split(".")[2]: v for k, v in tensors.items() if k.startswith(f"optimizer.{index}.")}
        if entries:
            state["state"][index] = entries
    optimizer.load_state_dict(state)
    generator.set_state(tensors[generator_key(ranks.rank)])
    return int(metadata["step"]), json.loads(metadata.get("history", "[]"))


def _calibrate_statistics(model: DEN, corpus: CleanCorpus, config: TrainConfig, generator: torch.Generator) -> None:
    """Measure the head's statistics on training batches of both clip lengths and standardise with them."""
    measured = []
    for frames in calibration_clip_lengths(config.frames):
        batch = training_batch(config.clean_clips(corpus, frames, config.crop, generator), config, generator)
        measured.append(model.statistics(batch.noisy))
    model.set_statistics_scale(torch.cat(measured).to(next(model.parameters()).device))


ProgressCallback = Callable[[int, float, dict[str, Any] | None], None]


def train(
    corpus: CleanCorpus,
    holdout: CleanCorpus,
    config: TrainConfig,
    out: Path,
    *,
    resume: bool = False,
    progress: ProgressCallback | None = None,
    ranks: Ranks = SINGLE_PROCESS,
) -> dict[str, Any]:
    """Train a DEN, validating and checkpointing every ``validate_every`` steps; write weights and config.

    Under torchrun every process calls this with its ``ranks``
    (:func:`darksynth.training.distributed.ranks_from_environment`): it joins the process group for the run and
    leaves it at the end. The processes train one DistributedDataParallel network, each on ``batch / world_size``
    clips per step drawn from its own generator; rank 0 calibrates the statistics (sent to the others), validates,
    calls ``progress`` (with its own share's loss) and writes every file. See docs/den.md.

    Returns:
        The final summary (validation figures, steps, seconds), also written to ``OUT.json``; the other processes
        return theirs, without validation figures.
    """
    device = rank_device(config.device, ranks)
    batch_size = per_process_batch(config.batch, ranks)  # checked before joining: no process waits for another
    with process_group(ranks, device):
        return _train(corpus, holdout, config, out, device, batch_size, resume=resume, progress=progress, ranks=ranks)


def _stop_unless_all_agree(failure: Exception | None) -> None:
    """Raise on every process when any failed (a collective), so that none waits for a process that stopped."""
    if all_agree(failure is None):
        return
    if failure is not None:
        raise failure
    raise DarksynthError("training stopped: another process failed (see its message)")


class _DENSteps:
    """The DEN's part of :func:`~darksynth.training.scaffold.run_steps`: one Adam step on the loss of a batch of
    this process's share, and at a report the validation figures and a checkpoint (rank 0)."""

    def __init__(
        self,
        model: DEN,
        network: torch.nn.Module,
        optimizer: torch.optim.Optimizer,
        generator: torch.Generator,
        corpus: CleanCorpus,
        holdout: CleanCorpus,
        config: TrainConfig,
        checkpoint: Path,
        device: torch.device,
        batch_size: int,
        ranks: Ranks,
    ) -> None:
        self.model, self.network, self.optimizer, self.generator = model, network, optimizer, generator
        self.corpus, self.config, self.checkpoint = corpus, config, checkpoint
        self.device, self.batch_size, self.ranks = device, batch_size, ranks
        self.validation = validation_batches(holdout, config) if ranks.is_main else []
        self.single_frames = validation_batches(holdout, config, frames=1) if ranks.is_main else []

    def train_step(self, step: int) -> dict[str, float]:
        config, model, device = self.config, self.model, self.device
        clean = config.clean_clips(
            self.corpus, config.frames_at(step), config.crop, self.generator, batch=self.batch_size
        )
        batch = training_batch(clean, config, self.generator)
        output = self.network(batch.noisy.to(device))
        loss = config.lambda_parameters * F.mse_loss(output.normalised, model.normalise(batch.vector.to(device)))
        if config.lambda_level > 0:
            loss = loss + config.lambda_level * level_loss(output.values, batch, device)
        if output.dark is not None and config.lambda_reconstruction > 0:
            loss = loss + config.lambda_reconstruction * F.l1_loss(output.dark, batch.dark.to(device))
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]
        self.optimizer.step()
        return {"loss": loss.item()}

    def report(self, report: Report) -> dict[str, Any] | None:
        generator_states = all_gather_tensor(self.generator.get_state())
        # Equal shares: the mean of the processes' mean losses is the whole batch's mean loss.
        losses = all_gather_tensor(torch.tensor([report.mean_losses["loss"]], dtype=torch.float64))
        entry, failure = None, None
        if self.ranks.is_main:
            try:
                mean_loss = sum(float(x) for x in losses) / len(losses)
                entry = {"step": report.step, "loss": mean_loss, **evaluate(self.model, self.validation, self.device)}
                entry["single_frame"] = evaluate(self.model, self.single_frames, self.device)
                history = [*report.history, entry]
                _save_checkpoint(
                    self.checkpoint, self.model, self.optimizer, generator_states, report.step, history, self.config
                )
            except Exception as error:
                failure = error
        _stop_unless_all_agree(failure)
        return entry


def _train(
    corpus: CleanCorpus,
    holdout: CleanCorpus,
    config: TrainConfig,
    out: Path,
    device: torch.device,
    batch_size: int,
    *,
    resume: bool,
    progress: ProgressCallback | None,
    ranks: Ranks,
) -> dict[str, Any]:
    model = initial_weights(config.seed, lambda: DEN(config.den)).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate, betas=config.betas)
    generator = seeded_generator(process_seed(config.seed, ranks))
    checkpoint = out.with_name(out.stem + ".checkpoint.safetensors")
    step, history = 0, list[dict[str, Any]]()
    if resume:
        step, history = _load_checkpoint(checkpoint, model, optimizer, generator, config, ranks)
    elif ranks.is_main:
        _calibrate_statistics(model, corpus, config, generator)  # the other processes receive rank 0's values
    # A v3 decoder whose loss weight is 0 gets no gradient, which DistributedDataParallel must be told about.
    unused = config.den.variant == "v3" and config.lambda_reconstruction <= 0
    network = wrap_model(model, device, find_unused_parameters=unused)
    steps = _DENSteps(
        model, network, optimizer, generator, corpus, holdout, config, checkpoint, device, batch_size, ranks
    )

    def on_step(step: int, losses: dict[str, float], entry: dict[str, Any] | None) -> None:
        if progress and ranks.is_main:
            progress(step, losses["loss"], entry)

    model.train()
    result = run_steps(
        steps, StepPlan(config.steps, config.validate_every), start=step, history=history, on_step=on_step
    )
    summary = {
        "config": config.to_dict(),
        "steps": result.steps,
        "seconds_this_run": round(result.seconds, 1),
        "final_validation": result.last,
        "history": result.history,
        "training_sources": len(corpus),
        "holdout_sources": holdout.sources,
    }
    if ranks.distributed:
        summary["processes"] = {
            "count": ranks.world_size,
            "batch_per_process": batch_size,
            "state_digests": all_state_digests(model),
        }
    failure = None
    if ranks.is_main:
        try:
            save_weights(out, model, training={"steps": result.steps, "final_validation": summary["final_validation"]})
            write_text_atomic(out.with_suffix(".json"), json.dumps(summary, indent=2) + "\n")
        except Exception as error:
            failure = error
    _stop_unless_all_agree(failure)
    return summary
