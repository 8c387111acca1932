"""Training of the ablation v1 (:mod:`darksynth.baselines.den_v1`) on the DEN's synthetic data.

Each step draws, as for v2 and v3, clean crops darkened with the paper's alpha and gamma and made noisy with the
paper's f(v) for a random v (:func:`~darksynth.training.batches.synthesize_batch`): that is the reference. A
second set of clean crops is darkened and made noisy with the *same* v: that is the target. v1 reads the
reference and makes the second set's dark crops noisy; it must give them the reference's noise, on other
content, as it will at inference (a real reference, a clean image to degrade).

v1 outputs pixels, so its loss is on distributions, not on v. An L1 or MSE loss against the target's pixels, the
loss of v3's decoder, is minimised by the target's mean, the dark crop itself, and would teach v1 to add no noise;
v1 is trained as the Starlight baseline is, by the shared adversarial training
(:mod:`darksynth.baselines.adversarial`): a patch discriminator with least-squares losses judges the residual
beside its dark frame, and a statistics term matches the DEN's fixed noise statistics
(:mod:`darksynth.models.statistics`) of every generated clip to those of its own target clip. That term, per clip
and not per batch as in Starlight, is what makes the output depend on the reference.

The budget is that of the v2 and v3 runs in time (docs/results.md): they took 18000 steps in about 20 minutes
on this 2-core CPU; a step of v1 runs a generator and a discriminator at full resolution, about 0.5 s, so v1 gets
the same 20 minutes (``max_seconds``) rather than the same step count.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import torch

from darksynth.baselines.adversarial import (
    AdversarialBaseline,
    AdversarialConfig,
    AdversarialSample,
    ProgressCallback,
    histogram_kl,
    initial_networks,
    per_clip_statistics_loss,
    train_adversarial,
    training_summary,
    write_summary,
)
from darksynth.baselines.den_v1 import DENv1, DENv1Config, save_den_v1
from darksynth.light.darkening import darken
from darksynth.noise.sampling import random_darkening_values
from darksynth.noise.simulate import add_noise
from darksynth.seeding import seeded_generator
from darksynth.tensors import to_8bit_levels
from darksynth.training.batches import TrainingBatch, synthesize_batch
from darksynth.training.corpus import CleanCorpus
from darksynth.training.scaffold import calibration_clip_lengths, draw_validation_batches


@dataclass(frozen=True)
class V1TrainConfig(AdversarialConfig):
    """v1's training settings, written beside the weights (defaults: the shipped weights')."""

    steps: int = 18000
    max_seconds: float | None = 1200.0
    log_every: int = 100
    validation_size: int = 32
    network: DENv1Config = field(default_factory=DENv1Config)


def draw_sample(
    corpus: CleanCorpus, config: V1TrainConfig, frames: int, crop: int, generator: torch.Generator
) -> AdversarialSample:
    """A reference batch of the paper's model and a target batch sharing its noise values: the target's dark clips
    are what v1 makes noisy, after reading the reference."""
    batch: TrainingBatch = synthesize_batch(
        config.clean_clips(corpus, frames, crop, generator),
        generator=generator,
        absent_probability=config.absent_probability,
        noise_model="paper",
    )
    other = config.clean_clips(corpus, frames, crop, generator)
    alpha, gamma = random_darkening_values(batch_shape=(config.batch,), generator=generator, device=other.device)
    dark = darken(other, alpha, gamma)
    target = to_8bit_levels(add_noise(dark, batch.values, generator=generator))
    return AdversarialSample(dark=dark, target=target, reference=batch.noisy)


@torch.no_grad()
def evaluate_v1(model: DENv1, samples: list[AdversarialSample], *, seed: int = 0) -> dict[str, Any]:
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
        assert sample.reference is not None  # v1's samples always hold one
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


def validation_samples(holdout: CleanCorpus, config: V1TrainConfig) -> list[AdversarialSample]:
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
    model, discriminator = initial_networks(config, lambda: DENv1(config.network), config.network.channels)
    _calibrate_encoder(model, corpus, config)
    samples = validation_samples(holdout, config) if holdout is not None else []
    untrained = evaluate_v1(model, samples, seed=config.seed) if samples else None
    baseline = AdversarialBaseline(
        draw=lambda corpus, frames, crop, generator: draw_sample(corpus, config, frames, crop, generator),
        statistics_loss=per_clip_statistics_loss,
    )
    result = train_adversarial(model, discriminator, corpus, config, baseline, progress=progress)
    summary = training_summary(config, corpus, result)
    if samples:
        summary["holdout_sources"] = holdout.sources if holdout is not None else []
        summary["holdout"] = evaluate_v1(model, samples, seed=config.seed)
        summary["holdout_untrained"] = untrained
    if out is not None:
        save_den_v1(out, model, training={"steps": result.steps, "holdout": summary.get("holdout")})
        write_summary(out, summary)
    return model, summary


def _calibrate_encoder(model: DENv1, corpus: CleanCorpus, config: V1TrainConfig) -> None:
    """Standardise the encoder's noise statistics with those of training references, as for v2 and v3."""
    generator = seeded_generator(config.seed + 1)
    measured = []
    for frames in calibration_clip_lengths(config.frames):
        sample = draw_sample(corpus, config, frames, config.crop, generator)
        assert sample.reference is not None
        measured.append(model.encoder.statistics(sample.reference))
    model.encoder.set_statistics_scale(torch.cat(measured).to(next(model.parameters()).device))
