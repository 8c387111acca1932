"""train(): outputs on disk, determinism, an exact resume; r_squared."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import torch
from safetensors.torch import load_file

from darksynth.errors import DarksynthError
from darksynth.models.den import DENConfig
from darksynth.noise.values import values_from_vector
from darksynth.training.corpus import CleanCorpus, load_corpus
from darksynth.training.loop import TrainConfig, level_loss, r_squared, train, training_batch, vector_names
from darksynth.training.weights import load_weights
from tests.clean_images import write_tiny_corpus

CONFIG = TrainConfig(
    den=DENConfig(width=4, depth=1),
    steps=4,
    batch=2,
    frames=2,
    crop=32,
    validate_every=2,
    validation_size=4,
)


@pytest.fixture(scope="module")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> CleanCorpus:
    root = write_tiny_corpus(tmp_path_factory.mktemp("corpus"))
    return load_corpus([root / "stills"], [root / "clips"])


@pytest.fixture(scope="module")
def reference_run(corpus: CleanCorpus, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object]]:
    """An uninterrupted 4-step run, shared by the tests that compare against it."""
    out = tmp_path_factory.mktemp("reference") / "den.safetensors"
    return out, train(corpus, corpus, CONFIG, out)


def _weights(path: Path) -> dict[str, torch.Tensor]:
    return load_file(str(path))


def _assert_same_weights(a: Path, b: Path) -> None:
    first, second = _weights(a), _weights(b)
    assert first.keys() == second.keys()
    different = [name for name in first if not torch.equal(first[name], second[name])]
    assert different == []


def test_train_writes_weights_summary_and_checkpoint(reference_run: tuple[Path, dict[str, object]]) -> None:
    out, summary = reference_run
    assert sorted(p.name for p in out.parent.iterdir()) == [
        "den.checkpoint.safetensors",
        "den.json",
        "den.safetensors",
    ]
    written = json.loads(out.with_suffix(".json").read_text())
    assert written["steps"] == 4
    assert written["config"] == CONFIG.to_dict() | {"betas": list(CONFIG.betas)}
    history = written["history"]
    assert [entry["step"] for entry in history] == [2, 4]
    for entry in history:
        assert set(entry["r2"]) == set(vector_names())
        assert len(vector_names()) == 16 and len(vector_names("paper")) == 8
        assert set(entry["single_frame"]["r2"]) == set(vector_names())
        assert entry["samples"] == CONFIG.validation_size
        assert all(value == value for value in entry["r2"].values())  # no NaN
    assert written["final_validation"] == history[-1]
    assert summary["steps"] == 4
    model = load_weights(out)
    assert model.config == CONFIG.den


def test_trained_weights_differ_from_the_initial_ones(
    corpus: CleanCorpus, reference_run: tuple[Path, dict[str, object]], tmp_path: Path
) -> None:
    """Guards the equality tests: a run that did not train at all would also be 'reproducible'."""
    out = tmp_path / "one.safetensors"
    train(corpus, corpus, dataclasses.replace(CONFIG, steps=1, validate_every=1), out)
    four, one = _weights(reference_run[0]), _weights(out)
    assert any(not torch.equal(four[name], one[name]) for name in four)


def test_same_seed_gives_identical_weights_and_another_seed_does_not(
    corpus: CleanCorpus, reference_run: tuple[Path, dict[str, object]], tmp_path: Path
) -> None:
    again = tmp_path / "again" / "den.safetensors"
    again.parent.mkdir()
    train(corpus, corpus, CONFIG, again)
    _assert_same_weights(reference_run[0], again)

    other = tmp_path / "other.safetensors"
    train(corpus, corpus, dataclasses.replace(CONFIG, seed=1), other)
    first, second = _weights(reference_run[0]), _weights(other)
    assert any(not torch.equal(first[name], second[name]) for name in first)


def test_resumed_run_equals_an_uninterrupted_one(
    corpus: CleanCorpus, reference_run: tuple[Path, dict[str, object]], tmp_path: Path
) -> None:
    out = tmp_path / "den.safetensors"
    train(corpus, corpus, dataclasses.replace(CONFIG, steps=2), out)
    summary = train(corpus, corpus, CONFIG, out, resume=True)
    _assert_same_weights(reference_run[0], out)
    reference = json.loads(reference_run[0].with_suffix(".json").read_text())
    assert summary["steps"] == 4
    assert [entry["step"] for entry in summary["history"]] == [2, 4]  # type: ignore[index]
    assert summary["history"] == reference["history"]


def test_resume_without_a_checkpoint_is_an_error(corpus: CleanCorpus, tmp_path: Path) -> None:
    out = tmp_path / "den.safetensors"
    with pytest.raises(DarksynthError, match="no checkpoint to resume from"):
        train(corpus, corpus, CONFIG, out, resume=True)


def test_resume_from_a_checkpoint_of_another_model_shape_is_an_error(corpus: CleanCorpus, tmp_path: Path) -> None:
    out = tmp_path / "den.safetensors"
    train(corpus, corpus, dataclasses.replace(CONFIG, steps=2), out)
    wider = dataclasses.replace(CONFIG, den=DENConfig(width=8, depth=1))
    with pytest.raises(DarksynthError, match="another model shape"):
        train(corpus, corpus, wider, out, resume=True)


def test_r_squared_of_perfect_and_of_mean_predictions() -> None:
    truth = torch.rand(50, 8, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(r_squared(truth, truth), torch.ones(8))
    torch.testing.assert_close(r_squared(truth.mean(0).expand_as(truth), truth), torch.zeros(8), atol=1e-6, rtol=0)


def test_r_squared_by_hand() -> None:
    truth = torch.tensor([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    predicted = torch.tensor([[1.0, 1.0], [2.0, 1.0], [4.0, 1.0]])
    # Column 0: residual 1, total 2 -> 0.5. Column 1 is constant: any error is infinitely bad.
    r2 = r_squared(predicted, truth)
    assert r2[0].item() == pytest.approx(0.5)
    assert r2[1].item() < -1e10


def test_level_target_changes_the_training_and_keeps_it_finite(
    corpus: CleanCorpus, reference_run: tuple[Path, dict[str, object]], tmp_path: Path
) -> None:
    out = tmp_path / "den.safetensors"
    summary = train(corpus, corpus, dataclasses.replace(CONFIG, lambda_level=0.5), out)
    weights = _weights(out)
    assert all(torch.isfinite(tensor).all() for tensor in weights.values())
    different = [name for name in weights if not torch.equal(weights[name], _weights(reference_run[0])[name])]
    assert different
    assert summary["config"]["lambda_level"] == 0.5  # type: ignore[index]


def test_level_loss_is_zero_for_the_true_vector_and_grows_with_a_wrong_level() -> None:
    generator = torch.Generator().manual_seed(5)
    clean = torch.rand(3, 2, 3, 32, 32, generator=generator)
    batch = training_batch(clean, CONFIG, generator, absent_probability=0.0)
    device = torch.device("cpu")
    assert level_loss(batch.values, batch, device).item() == pytest.approx(0.0, abs=1e-12)
    louder = batch.vector.clone()
    louder[:, vector_names(CONFIG.den.noise_model).index("read")] *= 4.0
    louder_values = values_from_vector(louder, CONFIG.den.noise_model)
    assert level_loss(louder_values, batch, device).item() > 0.01
