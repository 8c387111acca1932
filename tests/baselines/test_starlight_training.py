"""Starlight training (baselines/starlight_training.py on baselines/adversarial.py): deterministic GAN training,
and the histogram KL of its summaries."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
import scipy.stats
import torch

from darksynth.baselines.adversarial import KL_BINS, KL_RANGE, KL_SMOOTHING
from darksynth.baselines.starlight import (
    PHYSICS_NAMES,
    StarlightGenerator,
    StarlightTrainConfig,
    evaluate_starlight,
    histogram_kl,
    load_starlight,
    summary_path,
    train_starlight,
    validation_batches,
)
from darksynth.training.corpus import CleanCorpus
from tests.baselines.test_starlight_model import TINY, _generator

TINY_TRAINING = StarlightTrainConfig(
    generator=TINY,
    steps=4,
    batch=2,
    frames=2,
    crop=32,
    discriminator_width=4,
    log_every=2,
    validation_size=2,
    validation_crop=32,
)


@pytest.fixture(scope="module")
def corpus() -> CleanCorpus:
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:80, 0:80]
    images = [
        np.clip(np.stack([x * 3, y * 3, (x + y) * 1.5], -1) + rng.integers(0, 40, (80, 80, 3)), 0, 255).astype(np.uint8)
        for _ in range(2)
    ]
    clip = np.stack([np.roll(images[0], shift, axis=1) for shift in range(4)])
    return CleanCorpus(images=images, clips=[clip], sources=["a", "b", "clip"])


@pytest.mark.slow  # GAN training, three runs
def test_training_is_deterministic_changes_the_parameters_and_writes_weights_and_summary(
    corpus: CleanCorpus, tmp_path: Path
) -> None:
    out = tmp_path / "run" / "starlight.safetensors"
    pause = 0.25
    before = time.perf_counter()
    # A pause inside the training loop at each of the two log steps: the reported time must include it.
    first, summary = train_starlight(
        corpus, TINY_TRAINING, holdout=corpus, out=out, progress=lambda step, entry: time.sleep(pause)
    )
    elapsed = time.perf_counter() - before
    second, _ = train_starlight(corpus, TINY_TRAINING, holdout=corpus)
    third, _ = train_starlight(corpus, TINY_TRAINING.__class__(**{**TINY_TRAINING.__dict__, "seed": 1}))
    a, b, c = first.state_dict(), second.state_dict(), third.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a), "same seed, same weights"
    assert not all(torch.equal(a[k], c[k]) for k in a), "another seed, other weights"
    torch.manual_seed(TINY_TRAINING.seed)
    untrained = StarlightGenerator(TINY).state_dict()
    changed = [k for k in a if not torch.equal(a[k], untrained[k])]
    assert {f"log_{name}" for name in PHYSICS_NAMES} <= set(changed)
    assert "net.out.weight" in changed
    assert torch.equal(load_starlight(out).state_dict()["log_shot"], a["log_shot"])
    written = json.loads(summary_path(out).read_text())
    assert written["steps"] == 4 and written["config"]["crop"] == 32
    assert [entry["step"] for entry in written["history"]] == [2, 4]
    assert set(written["holdout"]) >= {"kl_generated_vs_target", "kl_physics_only_vs_target", "residual_std"}
    # The summary's figures are those of the trained model, not of the untrained one it started from.
    figures = evaluate_starlight(
        load_starlight(out),
        validation_batches(corpus, TINY_TRAINING),
        seed=TINY_TRAINING.seed,
        absent_probability=TINY_TRAINING.absent_probability,
    )
    assert written["holdout"]["kl_generated_vs_target"] == figures["kl_generated_vs_target"] > 0
    assert written["holdout_untrained"]["kl_generated_vs_target"] != figures["kl_generated_vs_target"]
    assert 2 * pause - 0.05 <= summary["training_seconds"] <= elapsed + 0.05


@pytest.mark.slow  # GAN training, 30 steps
def test_statistics_matching_alone_moves_the_read_noise_towards_the_target(corpus: CleanCorpus) -> None:
    """With the adversarial term off, the physics follow the statistics: read noise grows from its small start."""
    config = TINY_TRAINING.__class__(
        **{**TINY_TRAINING.__dict__, "steps": 30, "lambda_adversarial": 0.0, "physics_learning_rate": 0.05}
    )
    model, summary = train_starlight(corpus, config)
    losses = [entry["statistics"] for entry in summary["history"]]
    assert np.mean(losses[-3:]) < np.mean(losses[:3])
    assert model.physics_values()["read"] > 2 * StarlightGenerator().physics_values()["read"]  # type: ignore[operator]


def test_histogram_kl_matches_a_hand_computed_symmetric_kl_of_two_known_histograms() -> None:
    low, high = KL_RANGE
    width = (high - low) / KL_BINS
    centre = {name: low + (index + 0.5) * width for name, index in (("a", 90), ("b", 110))}
    # Three quarters in bin a and one quarter in bin b, against the reverse.
    first = torch.tensor([centre["a"]] * 3 + [centre["b"]])
    second = torch.tensor([centre["a"]] + [centre["b"]] * 3)
    p = np.full(KL_BINS, KL_SMOOTHING)
    q = np.full(KL_BINS, KL_SMOOTHING)
    p[90], p[110] = 0.75 + KL_SMOOTHING, 0.25 + KL_SMOOTHING
    q[90], q[110] = 0.25 + KL_SMOOTHING, 0.75 + KL_SMOOTHING
    # scipy.stats.entropy(p, q) is KL(p || q) after normalising both; about 0.5 * ln 3 here.
    expected = 0.5 * (scipy.stats.entropy(p, q) + scipy.stats.entropy(q, p))
    assert histogram_kl(first, second) == pytest.approx(expected, rel=1e-9)
    assert expected == pytest.approx(0.5 * math.log(3), rel=1e-3)


def test_histogram_kl_is_zero_for_equal_samples_and_grows_with_the_mismatch() -> None:
    values = torch.randn(20000, generator=_generator(0)) * 0.05
    assert histogram_kl(values, values) == pytest.approx(0.0, abs=1e-12)
    near = histogram_kl(values, torch.randn(20000, generator=_generator(1)) * 0.05)
    far = histogram_kl(values, torch.randn(20000, generator=_generator(1)) * 0.1)
    assert 0 < near < 0.05 < far
