"""The ablation v1 (models/den_v1.py, training/den_v1.py): a U-Net that makes the noisy image without f."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import save_file

from darksynth.baselines.adversarial import per_clip_statistics_loss
from darksynth.baselines.den_v1 import DENv1, DENv1Config, default_den_v1_path, load_den_v1, save_den_v1
from darksynth.baselines.den_v1_training import V1TrainConfig, draw_sample, train_den_v1
from darksynth.errors import DarksynthError
from darksynth.tensors import to_8bit_levels
from darksynth.training.corpus import CleanCorpus
from tests.evaluation.test_classical import smooth_scene

TINY = DENv1Config(encoder_width=4, encoder_depth=2, code_size=4, width=4, depth=1)


def _clips(shape: tuple[int, ...], seed: int = 0, scale: float = 0.3) -> torch.Tensor:
    return scale * torch.rand(shape, generator=torch.Generator().manual_seed(seed))


def _with_output(seed: int) -> DENv1:
    """A network whose generator's last layer is not zero: it adds noise, as a trained one does."""
    torch.manual_seed(seed)
    model = DENv1(TINY).eval()
    with torch.no_grad():
        model.generator.out.weight.normal_(0.0, 0.5)
    return model


def test_the_untrained_network_adds_no_noise_and_keeps_shape_and_levels() -> None:
    model = DENv1(TINY).eval()
    dark = _clips((2, 3, 3, 20, 28))
    noisy = model(_clips((2, 2, 3, 32, 32), seed=1), dark, torch.Generator().manual_seed(0))
    assert noisy.shape == dark.shape
    assert torch.equal(noisy, to_8bit_levels(dark))


def test_the_output_depends_on_the_seed_and_on_the_reference() -> None:
    model = _with_output(0)
    dark = _clips((1, 2, 3, 24, 24))
    quiet, loud = _clips((1, 1, 3, 32, 32), seed=2, scale=0.01), _clips((1, 1, 3, 32, 32), seed=3, scale=1.0)
    with torch.no_grad():
        first = model(quiet, dark, torch.Generator().manual_seed(4))
        again = model(quiet, dark, torch.Generator().manual_seed(4))
        other_seed = model(quiet, dark, torch.Generator().manual_seed(5))
        other_reference = model(loud, dark, torch.Generator().manual_seed(4))
    assert torch.equal(first, again)
    assert not torch.equal(first, other_seed)
    assert not torch.equal(first, other_reference)
    assert torch.equal(first * 255, (first * 255).round()) and 0.0 <= float(first.min()) <= float(first.max()) <= 1.0


def test_gradients_reach_the_encoder_through_the_code() -> None:
    model = _with_output(1).train()
    out = model(_clips((1, 1, 3, 32, 32), seed=6), _clips((1, 1, 3, 24, 24)), torch.Generator().manual_seed(0))
    # The rounding passes the gradient straight through; a sum of squares reaches every layer.
    out.square().sum().backward()
    assert model.encoder.encoders[0].body[0].weight.grad is not None  # type: ignore[index, union-attr]
    assert float(model.encoder.encoders[0].body[0].weight.grad.abs().sum()) > 0  # type: ignore[index, union-attr]


def test_save_and_load_round_trip_is_exact_and_bad_files_are_named(tmp_path: Path) -> None:
    model = _with_output(2)
    path = tmp_path / "v1.safetensors"
    save_den_v1(path, model, training={"steps": 3})
    loaded = load_den_v1(path)
    reference, dark = _clips((1, 1, 3, 32, 32), seed=7), _clips((1, 1, 3, 16, 16))
    with torch.no_grad():
        expected = model(reference, dark, torch.Generator().manual_seed(1))
        assert torch.equal(loaded(reference, dark, torch.Generator().manual_seed(1)), expected)
    with pytest.raises(DarksynthError, match=r"absent\.safetensors: no v1 weights"):
        load_den_v1(tmp_path / "absent.safetensors")
    other = tmp_path / "other.safetensors"
    save_file({"x": torch.zeros(1)}, str(other), metadata={"model": "darksynth-den", "config": json.dumps({})})
    with pytest.raises(DarksynthError, match=r"other\.safetensors: not darksynth-den-v1 weights"):
        load_den_v1(other)
    broken = tmp_path / "broken.safetensors"
    broken.write_bytes(b"not safetensors")
    with pytest.raises(DarksynthError, match=r"broken\.safetensors: cannot read v1 weights"):
        load_den_v1(broken)


def test_the_statistics_loss_is_zero_for_the_same_clip_and_grows_with_the_level_gap() -> None:
    dark = _clips((2, 2, 3, 32, 32), scale=0.2)
    noise = torch.randn(dark.shape, generator=torch.Generator().manual_seed(8))
    target = to_8bit_levels(dark + 0.02 * noise)
    assert float(per_clip_statistics_loss(target, target)) == 0.0
    gaps = [float(per_clip_statistics_loss(to_8bit_levels(dark + s * noise), target)) for s in (0.025, 0.04, 0.08)]
    assert 0.0 < gaps[0] < gaps[1] < gaps[2]


@pytest.fixture(scope="module")
def corpus() -> CleanCorpus:
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:80, 0:80]
    images = [
        np.clip(np.stack([x * 3, y * 3, (x + y) * 1.5], -1) + rng.integers(0, 40, (80, 80, 3)), 0, 255).astype(np.uint8)
        for _ in range(2)
    ]
    return CleanCorpus(images=images, clips=[], sources=["a", "b"])


TINY_TRAINING = V1TrainConfig(
    network=TINY, steps=4, max_seconds=None, batch=2, frames=2, crop=32, discriminator_width=4, log_every=2,
    validation_size=2, validation_crop=32,
)  # fmt: skip


def test_a_sample_shares_the_references_noise_values_on_other_content(corpus: CleanCorpus) -> None:
    sample = draw_sample(corpus, TINY_TRAINING, 2, 32, torch.Generator().manual_seed(0))
    assert sample.reference.shape == sample.dark.shape == sample.target.shape == (2, 2, 3, 32, 32)
    assert torch.equal(sample.target * 255, (sample.target * 255).round())
    # Another crop, darkened anew: the target's clean content is not the reference's.
    assert not torch.allclose(sample.reference, sample.target, atol=0.05)


def test_training_is_deterministic_writes_weights_and_reports_held_out_figures(
    corpus: CleanCorpus, tmp_path: Path
) -> None:
    out = tmp_path / "run" / "v1.safetensors"
    first, summary = train_den_v1(corpus, TINY_TRAINING, holdout=corpus, out=out)
    second, _ = train_den_v1(corpus, TINY_TRAINING)
    for (name, a), (_, b) in zip(first.state_dict().items(), second.state_dict().items(), strict=True):
        assert torch.equal(a, b), name
    assert summary["steps"] == 4 and [entry["step"] for entry in summary["history"]] == [2, 4]
    assert set(summary["holdout"]) == {
        "kl_generated_vs_target", "std_ratio_median", "std_log_correlation", "std_log_correlation_shuffled_references",
        "clips",
    }  # fmt: skip
    # Untrained, v1 adds no noise at all: its std ratio is about 0 (rounding aside).
    assert summary["holdout_untrained"]["std_ratio_median"] < 0.2
    written = json.loads((tmp_path / "run" / "v1_training.json").read_text())
    assert written["steps"] == 4
    assert torch.equal(load_den_v1(out).generator.out.weight, first.generator.out.weight)


def test_the_shipped_weights_load_and_add_noise_on_8bit_levels() -> None:
    if not default_den_v1_path().is_file():
        pytest.skip("no shipped v1 weights")
    model = load_den_v1()
    dark = 0.2 * smooth_scene(64).float()[None, None]
    reference = to_8bit_levels(dark + 0.03 * torch.randn(dark.shape, generator=torch.Generator().manual_seed(9)))
    with torch.no_grad():
        noisy = model(reference, dark, torch.Generator().manual_seed(0))
    assert torch.equal(noisy * 255, (noisy * 255).round())
    # Untrained, v1 adds nothing (the test above); trained, a visible grain.
    assert float((noisy - dark).std()) > 0.01
