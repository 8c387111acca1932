"""Training of the Starlight generator under the DEN's self-supervised settings, and its held-out figures.

The target distribution is exactly the DEN's synthetic training data: clean crops from
:func:`~darksynth.training.corpus.sample_clean_clips`, darkened and made noisy by
:func:`~darksynth.training.batches.synthesize_batch` (alpha ~ U(0.05, 0.3), gamma ~ U(0.1, 1), v from the
training ranges with each component absent with probability 0.15, 8-bit output). The generator receives the
dark clean clip (``batch.dark``) and must make noisy clips distributed like ``batch.noisy``.

The training is the shared adversarial one of :mod:`darksynth.baselines.adversarial` (patch discriminator,
least-squares GAN losses, statistics matching), here with the statistics matched on batch means, the physics
parameters on a learning rate of their own, and every learning rate decaying over the last part of the run.
"""

from __future__ import annotations

import copy
import itertools
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import torch
from torch import nn

from darksynth.baselines.adversarial import (
    AdversarialBaseline,
    AdversarialConfig,
    AdversarialSample,
    ProgressCallback,
    batch_statistics_loss,
    histogram_kl,
    initial_networks,
    train_adversarial,
    training_summary,
    write_summary,
)
from darksynth.baselines.starlight_model import (
    MODEL_NAME,
    MODEL_VERSION,
    StarlightConfig,
    StarlightGenerator,
    save_starlight,
)
from darksynth.noise.components import model_parameters
from darksynth.training.batches import TrainingBatch, random_noisy_version, synthesize_batch
from darksynth.training.corpus import CleanCorpus
from darksynth.training.scaffold import draw_validation_batches

LEVEL_EDGES = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0)
"""Dark-level bins of the noise-level table in the summary."""


@dataclass(frozen=True)
class StarlightTrainConfig(AdversarialConfig):
    """Starlight's training settings, written beside the weights. Defaults: those of the shipped weights.

    Attributes:
        generator: the generator's shape.
        physics_learning_rate: Adam's for the physics parameters (``log_*``); the U-Net's is ``learning_rate``.
        decay_from: from this fraction of the steps on, every learning rate falls linearly to a tenth at the last
            step.
    """

    generator: StarlightConfig = field(default_factory=StarlightConfig)
    physics_learning_rate: float = 2e-2
    decay_from: float = 0.5


def validation_batches(holdout: CleanCorpus, config: StarlightTrainConfig) -> list[TrainingBatch]:
    """The run's fixed validation set (:func:`~darksynth.training.scaffold.draw_validation_batches`): target
    batches drawn as in training from held-out material, ``validation_crop`` pixels wide."""

    def draw(generator: torch.Generator) -> TrainingBatch:
        return _target_batch(holdout, config, config.frames, config.validation_crop, generator)

    return draw_validation_batches(draw, config.validation_size, config.batch, config.seed)


def _target_batch(
    corpus: CleanCorpus, config: StarlightTrainConfig, frames: int, crop: int, generator: torch.Generator
) -> TrainingBatch:
    """Clean clips of the corpus darkened and made noisy with the paper's model, as the DEN's training draws them."""
    clean = config.clean_clips(corpus, frames, crop, generator)
    return synthesize_batch(
        clean, generator=generator, absent_probability=config.absent_probability, noise_model="paper"
    )


def _training_sample(
    config: StarlightTrainConfig, corpus: CleanCorpus, frames: int, crop: int, generator: torch.Generator
) -> AdversarialSample:
    batch = _target_batch(corpus, config, frames, crop, generator)
    return AdversarialSample(dark=batch.dark, target=batch.noisy)


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
        # The floor: the target's own law drawn again (new v, new noise) on the same dark crops, as 8-bit levels.
        second, _ = random_noisy_version(
            batch.dark, generator=redraw, absent_probability=absent_probability, noise_model="paper"
        )
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


def prior_mean_values(absent_probability: float = 0.15) -> dict[str, float]:
    """Mean of each of the paper's noise parameters under the target's prior (uniform over its range, present
    or not): Starlight is trained on the paper's model."""
    return {
        p.name: round((1.0 - absent_probability) * 0.5 * (p.training_range[0] + p.training_range[1]), 6)
        for p in model_parameters("paper")
    }


def _physics_and_network(config: StarlightTrainConfig, model: nn.Module) -> list[dict[str, Any]]:
    """The U-Net's parameters at the configured learning rate, the physics parameters at theirs."""
    physics = [p for n, p in model.named_parameters() if n.startswith("log_")]
    network = [p for n, p in model.named_parameters() if not n.startswith("log_")]
    return [{"params": network}, {"params": physics, "lr": config.physics_learning_rate}]


def _physics_report(model: nn.Module) -> dict[str, Any]:
    assert isinstance(model, StarlightGenerator)
    return {"physics": _rounded(model.physics_values())}


def starlight_baseline(config: StarlightTrainConfig) -> AdversarialBaseline:
    """Starlight's part of the adversarial training: samples of the DEN's synthetic data, statistics matched on
    batch means, the physics on their own learning rate, every learning rate decaying (``decay_from``), the
    physics in every report."""
    return AdversarialBaseline(
        draw=partial(_training_sample, config),
        statistics_loss=batch_statistics_loss,
        parameter_groups=partial(_physics_and_network, config),
        learning_rate_factor=partial(_decay, config),
        report_extras=_physics_report,
    )


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
    model, discriminator = initial_networks(
        config, lambda: StarlightGenerator(config.generator), config.generator.channels
    )
    initial = copy.deepcopy(model)
    result = train_adversarial(model, discriminator, corpus, config, starlight_baseline(config), progress=progress)
    summary: dict[str, Any] = {
        "model": MODEL_NAME,
        "version": MODEL_VERSION,
        **training_summary(config, corpus, result),
        "final_physics": _rounded(model.physics_values()),
        "target_prior_mean": prior_mean_values(config.absent_probability),
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
        write_summary(out, summary)
    return model, summary


def _decay(config: StarlightTrainConfig, step: int) -> float:
    """Learning-rate factor after ``step`` steps: 1, then linear down to 0.1 from ``decay_from`` of the steps."""
    start = config.decay_from * config.steps
    if step <= start or config.steps <= start:
        return 1.0
    return 1.0 - 0.9 * min(1.0, (step - start) / (config.steps - start))


def _rounded(values: dict[str, float | list[float]]) -> dict[str, float | list[float]]:
    return {k: [round(x, 6) for x in v] if isinstance(v, list) else round(v, 6) for k, v in values.items()}
