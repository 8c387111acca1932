"""Training of the ablation v1 (:mod:`darksynth.baselines.den_v1`) on the DEN's synthetic data.

Each step draws, as for v2 and v3, clean crops darkened with the paper's alpha and gamma and made noisy with the
paper's f(v) for a random v (:func:`~darksynth.training.batches.synthesize_batch`): that is the reference. A
second set of clean crops is darkened and made noisy with the *same* v: that is the target. v1 reads the
reference and makes the second set's dark crops noisy; it must give them the reference's noise, on other
content, as it will at inference (a real reference, a clean image to degrade).

v1 outputs pixels, so its loss is on distributions, not on v. An L1 or MSE loss against the target's pixels, the
loss of v3's decoder, is minimised by the target's mean, the dark crop itself, and would teach v1 to add no noise;
v1 is trained as the Starlight baseline is (:mod:`darksynth.baselines.starlight_training`): a patch
discriminator with least-squares losses judges the residual beside its dark frame, and a statistics term
matches the DEN's fixed noise statistics (:mod:`darksynth.noise.statistics`) of every generated clip to those of
its own target clip. That term, per clip and not per batch as in Starlight, is what makes the output depend on
the reference.

The budget is that of the v2 and v3 runs in time (docs/results.md): they took 18000 steps in about 20 minutes
on this 2-core CPU; a step of v1 runs a generator and a discriminator at full resolution, about 0.5 s, so v1 gets
the same 20 minutes (``max_seconds``) rather than the same step count.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import torch

from darksynth.baselines.den_v1 import DENv1, DENv1Config, save_den_v1
from darksynth.baselines.starlight_training import (
    STATISTICS_WITH_GRADIENT,
    PatchDiscriminator,
    adversarial_loss,
    discriminator_step,
    histogram_kl,
)
from darksynth.io.atomic import write_text_atomic
from darksynth.light.darkening import darken
from darksynth.noise.sampling import random_darkening_values
from darksynth.noise.simulate import add_noise
from darksynth.noise.statistics import noise_statistics
from darksynth.seeding import seeded_generator
from darksynth.tensors import to_8bit_levels
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


@dataclass(frozen=True)
class V1TrainConfig:
    """Training settings, written beside the weights (defaults: the shipped weights')."""

    network: DENv1Config = field(default_factory=DENv1Config)
    steps: int = 18000
    max_seconds: float | None = 1200.0
    batch: int = 8
    frames: int = 4
    crop: int = 64
    clip_fraction: float = 0.5
    single_frame_every: int = 2
    absent_probability: float = 0.15
    learning_rate: float = 5e-4
    discriminator_learning_rate: float = 5e-4
    betas: tuple[float, float] = (0.5, 0.999)
    lambda_adversarial: float = 1.0
    lambda_statistics: float = 1.0
    discriminator_width: int = 16
    seed: int = 0
    log_every: int = 100
    validation_size: int = 32
    validation_crop: int = 128
    device: str = "cpu"

    def to_dict(self) -> dict[str, Any]:
        document = asdict(self)
        document["network"] = self.network.to_dict()
        return document


@dataclass(frozen=True)
class ReferenceAndTarget:
    """A training sample of v1: a noisy reference and, with the same noise values, another dark clip and its
    noisy version."""

    reference: torch.Tensor  # (B, T, C, H, W) noisy, 8-bit levels
    dark: torch.Tensor  # (B, T, C, H, W) another dark clean clip
    target: torch.Tensor  # (B, T, C, H, W) ``dark`` made noisy with the reference's values


def draw_sample(
    corpus: CleanCorpus, config: V1TrainConfig, frames: int, crop: int, generator: torch.Generator
) -> ReferenceAndTarget:
    """A reference batch of the paper's model and a target batch sharing its noise values."""
    clean = sample_clean_clips(
        corpus, config.batch, frames, crop, clip_fraction=config.clip_fraction, generator=generator
    )
    batch: TrainingBatch = synthesize_batch(
        clean, generator=generator, absent_probability=config.absent_probability, noise_model="paper"
    )
    other = sample_clean_clips(
        corpus, config.batch, frames, crop, clip_fraction=config.clip_fraction, generator=generator
    )
    alpha, gamma = random_darkening_values(batch_shape=(config.batch,), generator=generator, device=other.device)
    dark = darken(other, alpha, gamma)
    target = to_8bit_levels(add_noise(dark, batch.values, generator=generator))
    return ReferenceAndTarget(reference=batch.noisy, dark=dark, target=target)


def per_clip_statistics_loss(fake: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean squared difference of every clip's noise statistics (log10 units) to its own target's."""
    difference = (
        noise_statistics(fake)[:, STATISTICS_WITH_GRADIENT] - noise_statistics(target)[:, STATISTICS_WITH_GRADIENT]
    )
    return difference.square().mean()


@torch.no_grad()
def evaluate_v1(model: DENv1, samples: list[ReferenceAndTarget], *, seed: int = 0) -> dict[str, Any]:
    """Held-out figures: the histogram KL divergence of generated against target noise; how well the generated
    noise's std follows the target's from clip to clip (the correlation of their logs over clips, and the median
    ratio); and that correlation again with the references shuffled among the clips of each batch, the control:
    what of it comes from the dark clip v1 is given rather than from the reference."""
    device = next(model.parameters()).device
    was_training = model.training
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    shuffle = torch.Generator().manual_seed(seed + 1)
    generated, target, ratios, pairs, shuffled_pairs = [], [], [], [], []
    for sample in samples:
        dark = sample.dark.to(device)
        noise_target = sample.target - sample.dark
        std_target = noise_target.flatten(1).std(dim=1).clamp_min(1e-6)
        noise_fake = model(sample.reference.to(device), dark, generator).cpu() - sample.dark
        std_fake = noise_fake.flatten(1).std(dim=1).clamp_min(1e-6)
        order = torch.randperm(sample.reference.shape[0], generator=shuffle)
        noise_shuffled = model(sample.reference[order].to(device), dark, generator).cpu() - sample.dark
        std_shuffled = noise_shuffled.flatten(1).std(dim=1).clamp_min(1e-6)
        generated.append(noise_fake)
        target.append(noise_target)
        ratios.append(std_fake / std_target)
        pairs.append(torch.stack([std_fake.log(), std_target.log()], dim=1))
        shuffled_pairs.append(torch.stack([std_shuffled.log(), std_target.log()], dim=1))
    model.train(was_training)
    logs, shuffled_logs = torch.cat(pairs), torch.cat(shuffled_pairs)
    return {
        "kl_generated_vs_target": round(histogram_kl(torch.cat(generated), torch.cat(target)), 5),
        "std_ratio_median": round(float(torch.cat(ratios).median()), 4),
        "std_log_correlation": round(float(torch.corrcoef(logs.T)[0, 1]), 4),
        "std_log_correlation_shuffled_references": round(float(torch.corrcoef(shuffled_logs.T)[0, 1]), 4),
        "clips": int(logs.shape[0]),
    }


class _V1Steps:
    """v1's part of :func:`~darksynth.training.scaffold.run_steps`: a discriminator step, then a generator step."""

    def __init__(
        self, model: DENv1, discriminator: PatchDiscriminator, corpus: CleanCorpus, config: V1TrainConfig
    ) -> None:
        self.model, self.discriminator, self.corpus, self.config = model, discriminator, corpus, config
        self.device = torch.device(config.device)
        self.optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate, betas=config.betas)
        self.optimizer_d = torch.optim.Adam(
            discriminator.parameters(), lr=config.discriminator_learning_rate, betas=config.betas
        )
        self.generator = seeded_generator(config.seed)

    def train_step(self, step: int) -> dict[str, float]:
        config, model, discriminator, device = self.config, self.model, self.discriminator, self.device
        frames = 1 if single_frame_step(step, config.single_frame_every) else config.frames
        sample = draw_sample(self.corpus, config, frames, config.crop, self.generator)
        dark, target = sample.dark.to(device), sample.target.to(device)
        fake = model(sample.reference.to(device), dark, self.generator)

        loss_d = discriminator_step(discriminator, self.optimizer_d, dark, target, fake)
        adversarial = adversarial_loss(discriminator, dark, fake)
        matching = per_clip_statistics_loss(fake, target)
        loss_g = config.lambda_adversarial * adversarial + config.lambda_statistics * matching
        self.optimizer.zero_grad(set_to_none=True)
        loss_g.backward()  # type: ignore[no-untyped-call]
        self.optimizer.step()
        return {
            "discriminator": float(loss_d.detach()),
            "adversarial": float(adversarial.detach()),
            "statistics": float(matching.detach()),
        }

    def report(self, report: Report) -> dict[str, Any]:
        return {
            "step": report.step,
            "seconds": round(report.seconds, 1),
            **{k: round(v, 5) for k, v in report.mean_losses.items()},
        }


ProgressCallback = Callable[[int, dict[str, Any]], None]


def validation_samples(holdout: CleanCorpus, config: V1TrainConfig) -> list[ReferenceAndTarget]:
    """The run's fixed held-out set: samples drawn as in training, ``validation_crop`` pixels wide."""
    return draw_validation_batches(
        partial(draw_sample, holdout, config, config.frames, config.validation_crop),
        config.validation_size,
        config.batch,
        config.seed,
    )


def train_den_v1(
    corpus: CleanCorpus,
    config: V1TrainConfig | None = None,
    *,
    holdout: CleanCorpus | None = None,
    out: Path | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[DENv1, dict[str, Any]]:
    """Train v1 on the DEN's synthetic data; optionally write its weights and ``OUT_STEM_training.json``.

    Returns:
        The trained network (eval mode) and the summary (held-out figures when ``holdout`` is given, beside
        those of the untrained network, which adds no noise).
    """
    config = config or V1TrainConfig()
    device = torch.device(config.device)
    model, discriminator = initial_weights(
        config.seed,
        lambda: (
            DENv1(config.network),
            PatchDiscriminator(config.discriminator_width, inputs=4 * config.network.channels),
        ),
    )
    model, discriminator = model.to(device), discriminator.to(device)
    _calibrate_encoder(model, corpus, config)
    samples = validation_samples(holdout, config) if holdout is not None else []
    untrained = evaluate_v1(model, samples, seed=config.seed) if samples else None
    steps = _V1Steps(model, discriminator, corpus, config)

    def on_step(step: int, losses: dict[str, float], entry: dict[str, Any] | None) -> None:
        if progress and entry is not None:
            progress(step, entry)

    model.train()
    result = run_steps(steps, StepPlan(config.steps, config.log_every, config.max_seconds), on_step=on_step)
    model.eval()
    summary: dict[str, Any] = {
        "config": config.to_dict(),
        "steps": result.steps,
        "stopped_by_time_limit": result.stopped_by_time_limit,
        "training_seconds": round(result.seconds, 1),
        "torch_threads": torch.get_num_threads(),
        "training_sources": len(corpus),
        "history": result.history,
    }
    if samples:
        summary["holdout_sources"] = holdout.sources if holdout is not None else []
        summary["holdout"] = evaluate_v1(model, samples, seed=config.seed)
        summary["holdout_untrained"] = untrained
    if out is not None:
        save_den_v1(out, model, training={"steps": result.steps, "holdout": summary.get("holdout")})
        write_text_atomic(out.with_name(out.stem + "_training.json"), json.dumps(summary, indent=2) + "\n")
    return model, summary


def _calibrate_encoder(model: DENv1, corpus: CleanCorpus, config: V1TrainConfig) -> None:
    """Standardise the encoder's noise statistics with those of training references, as for v2 and v3."""
    generator = seeded_generator(config.seed + 1)
    measured = []
    for index in range(16):
        frames = 1 if single_frame_step(index + 1, 2) else config.frames
        sample = draw_sample(corpus, config, frames, config.crop, generator)
        measured.append(model.encoder.statistics(sample.reference))
    model.encoder.set_statistics_scale(torch.cat(measured).to(next(model.parameters()).device))
