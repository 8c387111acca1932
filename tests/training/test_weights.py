"""DEN weights on disk: an exact round trip, and every unusable file refused with its path in the message."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
import torch
from safetensors.torch import load_file, save_file

from darksynth.errors import DarksynthError
from darksynth.models.den import DEN, MODEL_NAME, MODEL_VERSION, DENConfig
from darksynth.models.statistics import model_statistics
from darksynth.training.weights import load_weights, read_metadata, save_weights


def _clip() -> torch.Tensor:
    return torch.rand(2, 3, 3, 37, 45, generator=torch.Generator().manual_seed(0))


@pytest.mark.parametrize("settings", [{}, {"variant": "v2", "depth": 2, "head_width": 16}, {"noise_model": "paper"}])
def test_saved_weights_load_into_a_model_with_identical_outputs(
    tmp_path: Path, tiny_model: Callable[..., DEN], settings: dict[str, object]
) -> None:
    model = tiny_model(seed=5, **settings)
    # The statistics' standardisation is state too (buffers, not parameters): it must travel with the weights.
    size = sum(s.size for s in model_statistics(model.noise_model))
    model.set_statistics_scale(torch.randn(10, size, generator=torch.Generator().manual_seed(1)))
    path = tmp_path / "den.safetensors"
    save_weights(path, model, training={"steps": 7})
    loaded = load_weights(path)
    assert loaded.config == model.config
    assert not loaded.training
    assert torch.equal(loaded.statistics_scale, model.statistics_scale)
    assert not torch.equal(loaded.statistics_scale, torch.ones(size))
    with torch.no_grad():
        expected, actual = model(_clip()), loaded(_clip())
    assert torch.equal(actual.normalised, expected.normalised)
    if expected.dark is None:
        assert actual.dark is None
    else:
        assert actual.dark is not None and torch.equal(actual.dark, expected.dark)
    metadata = read_metadata(path)
    assert json.loads(metadata["training"]) == {"steps": 7}
    assert json.loads(metadata["config"]) == model.config.to_dict()


def test_a_differently_seeded_model_gives_other_outputs(tiny_model: Callable[..., DEN]) -> None:
    """Guards the round trip above: identical outputs are not what any two models give."""
    with torch.no_grad():
        assert not torch.equal(tiny_model(seed=5)(_clip()).normalised, tiny_model(seed=6)(_clip()).normalised)


def _tensors(model: DEN) -> dict[str, torch.Tensor]:
    return {name: tensor.detach().contiguous() for name, tensor in model.state_dict().items()}


def _metadata(**changes: str | None) -> dict[str, str]:
    metadata = {
        "model": MODEL_NAME,
        "version": str(MODEL_VERSION),
        "config": json.dumps(DENConfig(width=4, depth=1).to_dict()),
        "training": "{}",
    }
    for key, value in changes.items():
        if value is None:
            metadata.pop(key)
        else:
            metadata[key] = value
    return metadata


def test_hand_written_file_with_correct_metadata_loads(tmp_path: Path, tiny_model: Callable[..., DEN]) -> None:
    """The files of the failure cases below differ from this one only in what each case names."""
    path = tmp_path / "hand.safetensors"
    save_file(_tensors(tiny_model()), str(path), metadata=_metadata())
    assert load_weights(path).config == DENConfig(width=4, depth=1)


def test_version_1_weights_are_read_as_the_papers_model(tmp_path: Path, tiny_model: Callable[..., DEN]) -> None:
    """Weights written before the sRGB model (version 1, no noise_model in the config) keep working."""
    paper = tiny_model(noise_model="paper")
    settings = paper.config.to_dict()
    del settings["noise_model"]
    path = tmp_path / "v1.safetensors"
    save_file(_tensors(paper), str(path), metadata=_metadata(version="1", config=json.dumps(settings)))
    loaded = load_weights(path)
    assert loaded.noise_model == "paper"
    with torch.no_grad():
        assert torch.equal(loaded(_clip()).normalised, paper(_clip()).normalised)
    # sRGB-model tensors under version-1 metadata do not fit the paper's model they claim to be.
    srgb = tmp_path / "v1-srgb.safetensors"
    save_file(_tensors(tiny_model()), str(srgb), metadata=_metadata(version="1", config=json.dumps(settings)))
    with pytest.raises(DarksynthError, match="do not fit"):
        load_weights(srgb)


def test_every_shipped_den_is_the_noise_model_and_variant_it_is_declared_as() -> None:
    from darksynth.training.weights import SHIPPED_WEIGHTS, default_weights_path

    assert set(SHIPPED_WEIGHTS) == {("srgb", "v3"), ("paper", "v3"), ("paper", "v2")}
    for noise_model, variant in SHIPPED_WEIGHTS:
        model = load_weights(default_weights_path(variant, noise_model))
        assert (model.noise_model, model.config.variant) == (noise_model, variant)


@pytest.mark.parametrize(("noise_model", "variant"), [("srgb", "v2"), ("paper", "v1"), ("fancy", "v3")])
def test_an_unshipped_combination_is_one_error_line_naming_the_shipped_ones(noise_model: str, variant: str) -> None:
    from darksynth.training.weights import DENChoice, default_weights_path

    with pytest.raises(DarksynthError) as raised:
        default_weights_path(variant, noise_model)
    message = str(raised.value)
    assert "\n" not in message
    assert message == (
        f"no shipped DEN for noise model {noise_model!r} and variant {variant!r}; shipped: srgb v3, paper v3, paper v2"
    )
    with pytest.raises(DarksynthError, match="no shipped DEN"):
        DENChoice(noise_model=noise_model, variant=variant).path()


def test_a_weights_file_is_chosen_whatever_the_noise_model_and_variant(tmp_path: Path) -> None:
    from darksynth.training.weights import DENChoice, default_weights_path

    own = tmp_path / "mine.safetensors"
    assert DENChoice(own, noise_model="srgb", variant="v2").path() == own
    assert DENChoice().path() == default_weights_path() == default_weights_path("v3", "srgb")
    assert DENChoice(noise_model="paper", variant="v2").path().name == "den_v2.safetensors"


BAD_METADATA = {
    "other-version": (_metadata(version=str(MODEL_VERSION + 1)), "version"),
    "no-version": (_metadata(version=None), "version"),
    "other-model": (_metadata(model="someone-elses-net"), "someone-elses-net"),
    "no-model": (_metadata(model=None), "not darksynth DEN weights"),
    "no-config": (_metadata(config=None), "do not fit"),
    "config-not-json": (_metadata(config="{width: 4"), "do not fit"),
    "config-unknown-field": (_metadata(config=json.dumps({"colours": 3})), "do not fit"),
    "config-other-shape": (_metadata(config=json.dumps(DENConfig(width=8, depth=1).to_dict())), "do not fit"),
}


@pytest.mark.parametrize("case", sorted(BAD_METADATA))
def test_weights_with_wrong_metadata_are_refused_naming_the_file(
    tmp_path: Path, tiny_model: Callable[..., DEN], case: str
) -> None:
    metadata, expected = BAD_METADATA[case]
    path = tmp_path / f"{case}.safetensors"
    save_file(_tensors(tiny_model()), str(path), metadata=metadata)
    with pytest.raises(DarksynthError) as raised:
        load_weights(path)
    message = str(raised.value)
    assert message.startswith(f"{path}: ")
    assert expected in message


@pytest.mark.parametrize("damage", ["garbage", "truncated-data", "truncated-header", "empty", "missing", "folder"])
def test_unreadable_weights_files_are_refused_naming_the_file(
    tmp_path: Path, tiny_model: Callable[..., DEN], damage: str
) -> None:
    good = tmp_path / "good.safetensors"
    save_weights(good, tiny_model())
    data = good.read_bytes()
    path = tmp_path / f"{damage}.safetensors"
    if damage == "garbage":
        path.write_bytes(b"\x89 these are not the weights you are looking for " * 8)
    elif damage == "truncated-data":
        path.write_bytes(data[: len(data) - 100])
    elif damage == "truncated-header":
        path.write_bytes(data[:40])
    elif damage == "empty":
        path.write_bytes(b"")
    elif damage == "folder":
        path.mkdir()
    with pytest.raises(DarksynthError) as raised:
        load_weights(path)
    assert str(raised.value).startswith(f"{path}: ")
    assert "\n" not in str(raised.value)


def test_weights_of_another_shape_give_a_one_line_error(tmp_path: Path, tiny_model: Callable[..., DEN]) -> None:
    path = tmp_path / "other-shape.safetensors"
    save_file(
        _tensors(tiny_model()), str(path), metadata=_metadata(config=json.dumps(DENConfig(width=8, depth=1).to_dict()))
    )
    with pytest.raises(DarksynthError) as raised:
        load_weights(path)
    assert "\n" not in str(raised.value)


def test_saving_replaces_a_file_atomically_and_keeps_only_tensors(
    tmp_path: Path, tiny_model: Callable[..., DEN]
) -> None:
    path = tmp_path / "den.safetensors"
    save_weights(path, tiny_model(seed=1))
    save_weights(path, tiny_model(seed=2))
    assert [p.name for p in tmp_path.iterdir()] == ["den.safetensors"]
    stored = load_file(str(path))
    for name, tensor in tiny_model(seed=2).state_dict().items():
        assert torch.equal(stored[name], tensor)
