"""Training of the Starlight generator under the DEN's self-supervised settings, and its held-out figures.

The target distribution is exactly the DEN's synthetic training data: clean crops from
:func:`~darksynth.training.corpus.sample_clean_clips`, darkened and made noisy by
:func:`~darksynth.training.batches.synthesize_batch` (alpha ~ U(0.05, 0.3), gamma ~ U(0.1, 1), v from the
training ranges with each component absent with probability 0.15, 8-bit output). The generator receives the
dark clean clip (``batch.dark``) and must make noisy clips distributed like ``batch.noisy``.

Loss, as in Starlight, adversarial: a small patch discriminator with spectral normalisation judges the noise
residual (noisy - dark) of each frame beside the dark frame it belongs to, the residual minus its mean over the
clip (what is held over frames) and its column means (column patterns span the whole frame height, beyond
a small patch's reach); least-squares GAN losses. Added to the generator's loss, with weight
``lambda_statistics``, a statistics-matching term: the squared difference between the batch means of the
DEN's fixed noise statistics (:mod:`darksynth.noise.statistics`, log variances of pixel noise binned
by level, of column patterns split into per-frame and held parts, and of period-4 projections) of generated
and target clips. The adversarial term alone is slow to find the column components within a 15-minute CPU
budget; the statistics make every component's strength observable from the first step.
"""

from __future__ import annotations

import copy
import itertools
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import torch
from torch import nn
from torch.nn.utils.parametrizations import spectral_norm

from darksynth.baselines.starlight_model import (
    MODEL_NAME,
    MODEL_VERSION,
    StarlightConfig,
    StarlightGenerator,
    save_starlight,
)
from darksynth.io.atomic import write_text_atomic
from darksynth.noise.components import model_parameters
from darksynth.noise.statistics import LEVEL_BINS, noise_statistics
from darksynth.seeding import seeded_generator
from darksynth.training.batches import TrainingBatch, synthesize_batch
from darksynth.training.corpus import CleanCorpus, sample_clean_clips
from darksynth.training.scaffold import (
    Report,
    StepPlan,
    draw_validation_batches,
    initial_weights,
    run_steps,
    single_frame_step,
)

RESIDUAL_FEATURE_SCALE = 10.0
"""The discriminator reads residuals times this (they are of the order of 0.01-0.1)."""

DARK_FEATURE_SCALE = 4.0
"""The discriminator reads the dark frame times this (its values lie in [0, 0.3])."""

STATISTICS_WITH_GRADIENT = [*range(2 * LEVEL_BINS), *range(3 * LEVEL_BINS, 3 * LEVEL_BINS + 8)]
"""Entries of :func:`noise_statistics` that depend on the noise values (not the bin shares, not 1 / T)."""

KL_BINS = 200
KL_RANGE = (-0.5, 0.5)
"""Histogram of the noise residual for the KL divergence: 200 bins of 0.005 (1.3 8-bit levels) over
[-0.5, 0.5]; values beyond fall in the end bins."""

KL_SMOOTHING = 1e-6
"""Probability mass added to every bin before the KL divergence, so that empty bins count (not dropped)."""

LEVEL_EDGES = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0)
"""Dark-level bins of the noise-level table in the summary."""


@dataclass(frozen=True)
class StarlightTrainConfig:
    """Training settings, written beside the weights. Defaults: those of the shipped weights."""

    generator: StarlightConfig = field(default_factory=StarlightConfig)
    steps: int = 1500
    batch: int = 8
    frames: int = 4
    crop: int = 64
    clip_fraction: float = 0.5
    single_frame_every: int = 2
    """Every this-th batch holds single frames, as in the DEN's training
    (:func:`~darksynth.training.scaffold.single_frame_step`); 0: none."""
    absent_probability: float = 0.15
    learning_rate: float = 5e-4
    physics_learning_rate: float = 2e-2
    discriminator_learning_rate: float = 5e-4
    betas: tuple[float, float] = (0.5, 0.999)
    decay_from: float = 0.5
    """From this fraction of the steps on, every learning rate falls linearly to a tenth at the last step."""
    lambda_adversarial: float = 1.0
    lambda_statistics: float = 1.0
    discriminator_width: int = 16
    seed: int = 0
    max_seconds: float | None = None
    """Stop early once training has taken this long (the summary records the steps done); None: no limit."""
    log_every: int = 50
    validation_size: int = 64
    """Clips of the fixed validation set (:func:`validation_batches`) the final figures are measured on."""
    validation_crop: int = 128
    device: str = "cpu"

    def to_dict(self) -> dict[str, Any]:
        document = asdict(self)
        document["generator"] = self.generator.to_dict()
        return document


class PatchDiscriminator(nn.Module):
    """Per-frame patch discriminator: (N, 12, H, W) -> (N, 1, H / 4, W / 4) scores (LSGAN, no sigmoid)."""

    def __init__(self, width: int = 16, inputs: int = 12) -> None:
        super().__init__()

        def conv(a: int, b: int, kernel: int, stride: int) -> nn.Module:
            padding = (kernel - 1) // 2 if stride == 1 else 1
            return spectral_norm(nn.Conv2d(a, b, kernel, stride=stride, padding=padding))

        self.body = nn.Sequential(
            conv(inputs, width, 3, 1),
            nn.LeakyReLU(0.2),
            conv(width, 2 * width, 4, 2),
            nn.LeakyReLU(0.2),
            conv(2 * width, 2 * width, 4, 2),
            nn.LeakyReLU(0.2),
            conv(2 * width, 2 * width, 3, 1),
            nn.LeakyReLU(0.2),
            conv(2 * width, 1, 3, 1),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        result: torch.Tensor = self.body(x)
        return result


def discriminator_features(dark: torch.Tensor, noisy: torch.Tensor) -> torch.Tensor:
    """What the discriminator reads of a clip batch (B, T, C, H, W): (B * T, 4 C, H, W).

    Per frame: the dark frame, the noise residual, the residual minus its mean over the clip's frames, and the
    residual's column means broadcast down the columns.
    """
    residual = noisy - dark
    held = residual - residual.mean(dim=1, keepdim=True)
    columns = residual.mean(dim=-2, keepdim=True).expand_as(residual)
    features = torch.cat(
        [
            dark * DARK_FEATURE_SCALE,
            residual * RESIDUAL_FEATURE_SCALE,
            held * RESIDUAL_FEATURE_SCALE,
            columns * (3.0 * RESIDUAL_FEATURE_SCALE),
        ],
        dim=2,
    )
    return features.flatten(0, 1)


def discriminator_step(
    discriminator: nn.Module,
    optimizer: torch.optim.Optimizer,
    dark: torch.Tensor,
    real: torch.Tensor,
    fake: torch.Tensor,
) -> torch.Tensor:
    """One least-squares GAN step of the discriminator (real scored 1, the generator's clips 0); its loss."""
    scores_real = discriminator(discriminator_features(dark, real))
    scores_fake = discriminator(discriminator_features(dark, fake.detach()))
    loss: torch.Tensor = 0.5 * ((scores_real - 1.0).square().mean() + scores_fake.square().mean())
    optimizer.zero_grad(set_to_none=True)
    loss.backward()  # type: ignore[no-untyped-call]
    optimizer.step()
    return loss


def adversarial_loss(discriminator: nn.Module, dark: torch.Tensor, fake: torch.Tensor) -> torch.Tensor:
    """The generator's least-squares GAN loss: its clips should be scored 1."""
    result: torch.Tensor = (discriminator(discriminator_features(dark, fake)) - 1.0).square().mean()
    return result


def statistics_loss(fake: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
    """Mean squared difference of the batch means of the DEN's noise statistics (log10 units)."""
    fake_statistics = noise_statistics(fake)[:, STATISTICS_WITH_GRADIENT].mean(0)
    real_statistics = noise_statistics(real)[:, STATISTICS_WITH_GRADIENT].mean(0)
    return (fake_statistics - real_statistics).square().mean()


def histogram_kl(first: torch.Tensor, second: torch.Tensor) -> float:
    """Symmetric KL divergence between the histograms of two sets of noise values (see KL_BINS, KL_RANGE)."""
    low, high = KL_RANGE

    def histogram(values: torch.Tensor) -> torch.Tensor:
        clamped = values.detach().double().flatten().clamp(low, high)
        counts = torch.histc(clamped, bins=KL_BINS, min=low, max=high)
        probability = counts / counts.sum()
        return (probability + KL_SMOOTHING) / (1.0 + KL_BINS * KL_SMOOTHING)

    p, q = histogram(first), histogram(second)
    forward = (p * (p / q).log()).sum()
    inverse = (q * (q / p).log()).sum()
    return float(0.5 * (forward + inverse))


def validation_batches(holdout: CleanCorpus, config: StarlightTrainConfig) -> list[TrainingBatch]:
    """The run's fixed validation set (:func:`~darksynth.training.scaffold.draw_validation_batches`): target
    batches drawn as in training from held-out material, ``validation_crop`` pixels wide."""

    def draw(generator: torch.Generator) -> TrainingBatch:
        clean = sample_clean_clips(
            holdout,
            config.batch,
            config.frames,
            config.validation_crop,
            clip_fraction=config.clip_fraction,
            generator=generator,
        )
        return synthesize_batch(
            clean, generator=generator, absent_probability=config.absent_probability, noise_model="paper"
        )

    return draw_validation_batches(draw, config.validation_size, config.batch, config.seed)


def _noise_levels(dark: torch.Tensor, residual: torch.Tensor) -> list[float | None]:
    """Standard deviation of the residual in each dark-level bin of LEVEL_EDGES (None for an empty bin)."""
    levels = []
    for low, high in itertools.pairwise(LEVEL_EDGES):
        inside = (dark >= low) & (dark < high)
        levels.append(round(float(residual[inside].std()), 5) if int(inside.sum()) > 1 else None)
    return levels


@torch.no_grad()
def evaluate_starlight(
    model: StarlightGenerator, batches: list[TrainingBatch], *, seed: int = 0, absent_probability: float = 0.15
) -> dict[str, Any]:
    """Figures of a generator against a target set: KL divergence of noise histograms, noise levels.

    Also reported: the same for the physics part alone (the U-Net's residual zeroed), and the KL divergence
    between the target and a second, independent draw of the target on the same clean crops (the floor the
    figure can reach with a finite sample and per-clip random parameters).
    """
    device = next(model.parameters()).device
    physics = copy.deepcopy(model)
    physics.zero_residual()
    was_training = model.training
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    redraw = torch.Generator().manual_seed(seed + 1)
    target, generated, physics_only, second_draw, darks = [], [], [], [], []
    for batch in batches:
        dark = batch.dark.to(device)
        darks.append(batch.dark)
        target.append(batch.noisy - batch.dark)
        generated.append((model(dark, generator) - dark).cpu())
        physics_only.append((physics(dark, generator) - dark).cpu())
        # The floor: the target's own law drawn again (new v, new noise) on the same dark crops.
        second = _redraw_target(batch, redraw, absent_probability)
        second_draw.append(second - batch.dark)
    model.train(was_training)
    dark_all = torch.cat(darks)
    target_all, generated_all = torch.cat(target), torch.cat(generated)
    physics_all, second_all = torch.cat(physics_only), torch.cat(second_draw)
    return {
        "kl_generated_vs_target": round(histogram_kl(generated_all, target_all), 5),
        "kl_physics_only_vs_target": round(histogram_kl(physics_all, target_all), 5),
        "kl_second_target_draw_vs_target": round(histogram_kl(second_all, target_all), 5),
        "residual_std": {
            "generated": round(float(generated_all.std()), 5),
            "physics_only": round(float(physics_all.std()), 5),
            "target": round(float(target_all.std()), 5),
        },
        "residual_std_by_dark_level": {
            "level_edges": list(LEVEL_EDGES),
            "generated": _noise_levels(dark_all, generated_all),
            "target": _noise_levels(dark_all, target_all),
        },
        "samples": int(target_all.shape[0]),
        "frames": int(target_all.shape[1]),
        "crop": int(target_all.shape[-1]),
    }


def _redraw_target(batch: TrainingBatch, generator: torch.Generator, absent_probability: float) -> torch.Tensor:
    """Another draw of the target's noise law on the same dark clips (new v, new noise), as 8-bit levels."""
    from darksynth.training.batches import random_noisy_version

    noisy, _ = random_noisy_version(
        batch.dark, generator=generator, absent_probability=absent_probability, noise_model="paper"
    )
    return noisy


def prior_mean_values(absent_probability: float = 0.15) -> dict[str, float]:
    """Mean of each of the paper's noise parameters under the target's prior (uniform over its range, present
    or not): Starlight is trained on the paper's model."""
    return {
        p.name: round((1.0 - absent_probability) * 0.5 * (p.training_range[0] + p.training_range[1]), 6)
        for p in model_parameters("paper")
    }


ProgressCallback = Callable[[int, dict[str, Any]], None]


class _StarlightSteps:
    """Starlight's part of :func:`~darksynth.training.scaffold.run_steps`: a discriminator step then a generator
    step on a batch of the target, and at a report the mean losses since the last one and the physics."""

    def __init__(
        self,
        model: StarlightGenerator,
        discriminator: PatchDiscriminator,
        corpus: CleanCorpus,
        config: StarlightTrainConfig,
    ) -> None:
        self.model, self.discriminator, self.corpus, self.config = model, discriminator, corpus, config
        self.device = torch.device(config.device)
        physics = [p for n, p in model.named_parameters() if n.startswith("log_")]
        network = [p for n, p in model.named_parameters() if not n.startswith("log_")]
        groups: list[dict[str, Any]] = [{"params": network}, {"params": physics, "lr": config.physics_learning_rate}]
        self.optimizer = torch.optim.Adam(groups, lr=config.learning_rate, betas=config.betas)
        self.optimizer_d = torch.optim.Adam(
            discriminator.parameters(), lr=config.discriminator_learning_rate, betas=config.betas
        )
        self.schedules = [
            torch.optim.lr_scheduler.LambdaLR(o, partial(_decay, config)) for o in (self.optimizer, self.optimizer_d)
        ]
        self.generator = seeded_generator(config.seed)

    def train_step(self, step: int) -> dict[str, float]:
        config, model, discriminator = self.config, self.model, self.discriminator
        frames = 1 if single_frame_step(step, config.single_frame_every) else config.frames
        clean = sample_clean_clips(
            self.corpus, config.batch, frames, config.crop, clip_fraction=config.clip_fraction, generator=self.generator
        )
        batch = synthesize_batch(
            clean, generator=self.generator, absent_probability=config.absent_probability, noise_model="paper"
        )
        dark, real = batch.dark.to(self.device), batch.noisy.to(self.device)
        fake = model(dark, self.generator)

        loss_d = discriminator_step(discriminator, self.optimizer_d, dark, real, fake)
        adversarial = adversarial_loss(discriminator, dark, fake)
        matching = statistics_loss(fake, real)
        loss_g = config.lambda_adversarial * adversarial + config.lambda_statistics * matching
        self.optimizer.zero_grad(set_to_none=True)
        loss_g.backward()  # type: ignore[no-untyped-call]
        self.optimizer.step()
        for schedule in self.schedules:
            schedule.step()
        return {
            "discriminator": float(loss_d.detach()),
            "adversarial": float(adversarial.detach()),
            "statistics": float(matching.detach()),
        }

    def report(self, report: Report) -> dict[str, Any]:
        entry: dict[str, Any] = {"step": report.step, **{k: round(v, 5) for k, v in report.mean_losses.items()}}
        entry["physics"] = _rounded(self.model.physics_values())
        entry["seconds"] = round(report.seconds, 1)
        return entry


def train_starlight(
    corpus: CleanCorpus,
    config: StarlightTrainConfig | None = None,
    *,
    holdout: CleanCorpus | None = None,
    out: Path | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[StarlightGenerator, dict[str, Any]]:
    """Train a Starlight generator adversarially on the DEN's synthetic data; optionally save it.

    Args:
        corpus: clean training material.
        config: training settings (the shipped weights' by default).
        holdout: clean held-out material for the final figures, on :func:`validation_batches` (none when None).
        out: weights path; its summary goes to ``OUT_STEM_training.json`` beside it. Nothing is written when None.
        progress: called every ``log_every`` steps (and at the last) with the step and the logged figures.

    Returns:
        The trained generator (eval mode) and the summary.
    """
    config = config or StarlightTrainConfig()
    device = torch.device(config.device)
    model, discriminator = initial_weights(
        config.seed,
        lambda: (
            StarlightGenerator(config.generator),
            PatchDiscriminator(config.discriminator_width, inputs=4 * config.generator.channels),
        ),
    )
    model, discriminator = model.to(device), discriminator.to(device)
    initial = copy.deepcopy(model)
    steps = _StarlightSteps(model, discriminator, corpus, config)

    def on_step(step: int, losses: dict[str, float], entry: dict[str, Any] | None) -> None:
        if progress and entry is not None:
            progress(step, entry)

    model.train()
    result = run_steps(steps, StepPlan(config.steps, config.log_every, config.max_seconds), on_step=on_step)
    model.eval()
    summary: dict[str, Any] = {
        "model": MODEL_NAME,
        "version": MODEL_VERSION,
        "config": config.to_dict(),
        "steps": result.steps,
        "stopped_by_time_limit": result.stopped_by_time_limit,
        "training_seconds": round(result.seconds, 1),
        "torch_threads": torch.get_num_threads(),
        "training_sources": len(corpus),
        "final_physics": _rounded(model.physics_values()),
        "target_prior_mean": prior_mean_values(config.absent_probability),
        "history": result.history,
    }
    if holdout is not None:
        batches = validation_batches(holdout, config)
        absent = config.absent_probability
        summary["holdout_sources"] = holdout.sources
        summary["holdout"] = evaluate_starlight(model, batches, seed=config.seed, absent_probability=absent)
        untrained = evaluate_starlight(initial, batches, seed=config.seed, absent_probability=absent)
        summary["holdout_untrained"] = {"kl_generated_vs_target": untrained["kl_generated_vs_target"]}
    if out is not None:
        save_starlight(out, model, training={"steps": result.steps, "final_physics": summary["final_physics"]})
        write_text_atomic(summary_path(out), json.dumps(summary, indent=2) + "\n")
    return model, summary


def _decay(config: StarlightTrainConfig, step: int) -> float:
    """Learning-rate factor after ``step`` steps: 1, then linear down to 0.1 from ``decay_from`` of the steps."""
    start = config.decay_from * config.steps
    if step <= start or config.steps <= start:
        return 1.0
    return 1.0 - 0.9 * min(1.0, (step - start) / (config.steps - start))


def summary_path(weights: Path) -> Path:
    """Where the training summary of a weights file goes: ``STEM_training.json`` beside it."""
    return weights.with_name(weights.stem + "_training.json")


def _rounded(values: dict[str, float | list[float]]) -> dict[str, float | list[float]]:
    return {k: [round(x, 6) for x in v] if isinstance(v, list) else round(v, 6) for k, v in values.items()}
