"""The adversarial training of the learned baselines (the Starlight generator, the paper's ablation v1).

Both learn to make a dark clean clip noisy like the DEN's synthetic data, and both are trained the same way: a
small patch discriminator with spectral normalisation judges the noise residual (noisy - dark) of each frame beside
the dark frame it belongs to, the residual minus its mean over the clip (what is held over frames) and its column
means (column patterns span the whole frame height, beyond a small patch's reach); least-squares GAN losses. Added
to the generator's loss, with weight ``lambda_statistics``, a statistics-matching term on the DEN's fixed noise
statistics (:mod:`darksynth.models.statistics`: log variances of pixel noise binned by level, of column patterns
split into per-frame and held parts, and of period-4 projections). The adversarial term alone is slow to find the
column components within a CPU budget of minutes; the statistics make every component's strength observable from
the first step.

What differs between the baselines is declared in an :class:`AdversarialBaseline`: how a sample is drawn, what
the generator reads besides the dark clip, how its statistics are matched (batch means for Starlight, clip by clip
for v1, whose output must follow its reference), its optimiser's parameter groups and learning-rate schedule, and
what a report adds. The step loop is the shared one of :mod:`darksynth.training.scaffold`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import torch
from torch import nn
from torch.nn.utils.parametrizations import spectral_norm

from darksynth.io.atomic import write_text_atomic
from darksynth.models.statistics import LEVEL_BINS, noise_statistics
from darksynth.seeding import seeded_generator
from darksynth.training.corpus import CleanCorpus
from darksynth.training.scaffold import (
    LoopResult,
    Report,
    StepPlan,
    SyntheticTrainingConfig,
    initial_weights,
    run_steps,
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

Network = TypeVar("Network", bound=nn.Module)


@dataclass(frozen=True)
class AdversarialConfig(SyntheticTrainingConfig):
    """The settings of an adversarial baseline's training, beyond those of every trainer.

    Attributes:
        discriminator_learning_rate: Adam's for the discriminator (it shares the generator's ``betas``).
        lambda_adversarial, lambda_statistics: weights of the generator's two losses.
        discriminator_width: channels of the discriminator's first layer.
        max_seconds: stop early once training has taken this long (the summary records the steps done); None: no
            limit.
        log_every: report (and call ``progress``) every this many steps, and at the last.
        validation_crop: side of the held-out crops the final figures are measured on, pixels.
    """

    discriminator_learning_rate: float = 5e-4
    lambda_adversarial: float = 1.0
    lambda_statistics: float = 1.0
    discriminator_width: int = 16
    max_seconds: float | None = None
    log_every: int = 50
    validation_crop: int = 128


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


def batch_statistics_loss(fake: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
    """Mean squared difference of the batch means of the DEN's noise statistics (log10 units)."""
    fake_statistics = noise_statistics(fake)[:, STATISTICS_WITH_GRADIENT].mean(0)
    real_statistics = noise_statistics(real)[:, STATISTICS_WITH_GRADIENT].mean(0)
    return (fake_statistics - real_statistics).square().mean()


def per_clip_statistics_loss(fake: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean squared difference of every clip's noise statistics (log10 units) to its own target's."""
    difference = (
        noise_statistics(fake)[:, STATISTICS_WITH_GRADIENT] - noise_statistics(target)[:, STATISTICS_WITH_GRADIENT]
    )
    return difference.square().mean()


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


@dataclass(frozen=True)
class AdversarialSample:
    """A training sample of an adversarial baseline.

    Attributes:
        dark: (B, T, C, H, W) dark clean clips, the generator's input.
        target: (B, T, C, H, W) their real noisy version (8-bit levels), what the generator's output should pass for.
        reference: (B, T, C, H, W) a noisy clip a conditioned generator reads before ``dark`` (v1: other content
            with the target's noise values); None for a generator that reads the dark clip alone.
    """

    dark: torch.Tensor
    target: torch.Tensor
    reference: torch.Tensor | None = None


def generate(model: nn.Module, sample: AdversarialSample, generator: torch.Generator) -> torch.Tensor:
    """The generator's noisy version of ``sample.dark`` (after its reference, if it reads one), on its device."""
    device = next(model.parameters()).device
    conditions = () if sample.reference is None else (sample.reference.to(device),)
    noisy: torch.Tensor = model(*conditions, sample.dark.to(device), generator)
    return noisy


def _all_parameters(model: nn.Module) -> list[dict[str, Any]]:
    return [{"params": list(model.parameters())}]


def _no_report_extras(model: nn.Module) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class AdversarialBaseline:
    """What a baseline adds to the shared adversarial training.

    Attributes:
        draw: ``draw(corpus, frames, crop, generator)``, a training sample of ``frames``-frame clips cropped to
            ``crop`` pixels.
        statistics_loss: ``statistics_loss(fake, target)``, the generator's statistics-matching term.
        parameter_groups: the generator's parameter groups for Adam (a group's own ``lr`` overrides the
            configured one); all parameters in one group by default.
        learning_rate_factor: the factor of every learning rate after a number of steps
            (``torch.optim.lr_scheduler.LambdaLR``); None: constant.
        report_extras: what a report adds to the losses, read from the generator.
    """

    draw: Callable[[CleanCorpus, int, int, torch.Generator], AdversarialSample]
    statistics_loss: Callable[[torch.Tensor, torch.Tensor], torch.Tensor]
    parameter_groups: Callable[[nn.Module], list[dict[str, Any]]] = _all_parameters
    learning_rate_factor: Callable[[int], float] | None = None
    report_extras: Callable[[nn.Module], dict[str, Any]] = _no_report_extras


class _AdversarialSteps:
    """The part of :func:`~darksynth.training.scaffold.run_steps` of an adversarial baseline: a discriminator step,
    then a generator step, on each sample; at a report the mean losses since the last one and the extras."""

    def __init__(
        self,
        model: nn.Module,
        discriminator: nn.Module,
        corpus: CleanCorpus,
        config: AdversarialConfig,
        baseline: AdversarialBaseline,
    ) -> None:
        self.model, self.discriminator, self.corpus, self.config = model, discriminator, corpus, config
        self.baseline = baseline
        self.device = torch.device(config.device)
        self.optimizer = torch.optim.Adam(baseline.parameter_groups(model), lr=config.learning_rate, betas=config.betas)
        self.optimizer_d = torch.optim.Adam(
            discriminator.parameters(), lr=config.discriminator_learning_rate, betas=config.betas
        )
        factor = baseline.learning_rate_factor
        self.schedules = (
            []
            if factor is None
            else [torch.optim.lr_scheduler.LambdaLR(o, factor) for o in (self.optimizer, self.optimizer_d)]
        )
        self.generator = seeded_generator(config.seed)

    def train_step(self, step: int) -> dict[str, float]:
        config, discriminator = self.config, self.discriminator
        sample = self.baseline.draw(self.corpus, config.frames_at(step), config.crop, self.generator)
        dark, target = sample.dark.to(self.device), sample.target.to(self.device)
        fake = generate(self.model, sample, self.generator)

        loss_d = discriminator_step(discriminator, self.optimizer_d, dark, target, fake)
        adversarial = adversarial_loss(discriminator, dark, fake)
        matching = self.baseline.statistics_loss(fake, target)
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
        return {
            "step": report.step,
            **{k: round(v, 5) for k, v in report.mean_losses.items()},
            **self.baseline.report_extras(self.model),
            "seconds": round(report.seconds, 1),
        }


ProgressCallback = Callable[[int, dict[str, Any]], None]
"""Called at every report with the step and the report's entry (losses, extras, seconds)."""


def initial_networks(
    config: AdversarialConfig, build: Callable[[], Network], channels: int
) -> tuple[Network, PatchDiscriminator]:
    """The generator ``build()`` makes and its discriminator, with the initial weights of the run seed
    (:func:`~darksynth.training.scaffold.initial_weights`), on the configured device."""
    device = torch.device(config.device)
    model, discriminator = initial_weights(
        config.seed, lambda: (build(), PatchDiscriminator(config.discriminator_width, inputs=4 * channels))
    )
    return model.to(device), discriminator.to(device)


def train_adversarial(
    model: nn.Module,
    discriminator: nn.Module,
    corpus: CleanCorpus,
    config: AdversarialConfig,
    baseline: AdversarialBaseline,
    *,
    progress: ProgressCallback | None = None,
) -> LoopResult:
    """Train ``model`` against ``discriminator`` for ``config.steps`` steps (or ``config.max_seconds``), reporting
    every ``config.log_every``; the model is left in eval mode."""

    def on_step(step: int, losses: dict[str, float], entry: dict[str, Any] | None) -> None:
        if progress and entry is not None:
            progress(step, entry)

    steps = _AdversarialSteps(model, discriminator, corpus, config, baseline)
    model.train()
    result = run_steps(steps, StepPlan(config.steps, config.log_every, config.max_seconds), on_step=on_step)
    model.eval()
    return result


def training_summary(config: AdversarialConfig, corpus: CleanCorpus, result: LoopResult) -> dict[str, Any]:
    """What every adversarial baseline's summary holds: its settings, how the run went, its history."""
    return {
        "config": config.to_dict(),
        "steps": result.steps,
        "stopped_by_time_limit": result.stopped_by_time_limit,
        "training_seconds": round(result.seconds, 1),
        "torch_threads": torch.get_num_threads(),
        "training_sources": len(corpus),
        "history": result.history,
    }


def summary_path(weights: Path) -> Path:
    """Where the training summary of a weights file goes: ``STEM_training.json`` beside it."""
    return weights.with_name(weights.stem + "_training.json")


def write_summary(weights: Path, summary: dict[str, Any]) -> None:
    """Write a training summary to :func:`summary_path` of its weights."""
    write_text_atomic(summary_path(weights), json.dumps(summary, indent=2) + "\n")
