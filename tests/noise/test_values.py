"""NoiseValues: the one carrier of noise values, and its views."""

from __future__ import annotations

import json

import pytest
import torch

from darksynth.noise.components import (
    noise_components,
    noise_parameter_names,
    noise_parameters,
    shapes_neutral,
    vector_size,
)
from darksynth.noise.sampling import random_noise_values
from darksynth.noise.values import NoiseValues, model_vector, stacked_values, values_from_vector


def test_missing_parameters_are_neutral_and_unknown_ones_refused() -> None:
    values = NoiseValues.from_values({"shot": 0.05, "periodic": [0.001, 0.002, 0.003]})
    assert tuple(values) == noise_parameter_names()
    for parameter in noise_parameters():
        if parameter.name not in ("shot", "periodic"):
            assert values[parameter.name].tolist() == [parameter.neutral] * parameter.size, parameter.name
    assert values["channel_gain"].tolist() == [1.0, 1.0]
    with pytest.raises(KeyError, match="dark_current"):
        NoiseValues.from_values({"dark_current": 0.1})
    with pytest.raises(ValueError, match="periodic needs 3"):
        NoiseValues.from_values({"periodic": [0.1, 0.2]})
    with pytest.raises(ValueError, match="exactly the table's parameters"):
        NoiseValues({"shot": torch.zeros(1)})


def test_json_view_keeps_profile_numbers_exactly() -> None:
    document = {"shot": 0.06, "read": 0.012, "periodic": [0.002, 0.0021, 0.0022], "compression": 0.35}
    values = NoiseValues.from_values(document)
    written = values.to_json()
    assert json.loads(json.dumps(written)) == written
    assert {name: written[name] for name in document} == document
    assert NoiseValues.from_json(written) == values
    with pytest.raises(ValueError, match="unbatched"):
        NoiseValues.neutral((2,)).to_json()


def test_batches_stack_select_and_compare() -> None:
    a = NoiseValues.from_values({"read": 0.01})
    b = NoiseValues.from_values({"read": 0.02})
    batch = stacked_values([a, b])
    assert batch.batch_shape == (2,)
    assert batch.clip(1) == b and batch.clip(0) != b
    assert stacked_values([batch, batch]).batch_shape == (4,)
    assert batch.map(lambda t: t.max(dim=0).values) == b
    assert a.scalar("read") == 0.01
    with pytest.raises(ValueError, match="scalar view"):
        a.scalar("periodic")
    assert a.replace(read=0.03).scalar("read") == pytest.approx(0.03)
    assert a.to(dtype=torch.float32)["read"].dtype == torch.float32


def test_activity_follows_amplitudes_and_shapes() -> None:
    white = NoiseValues.from_values({"read": 0.01})
    shaped = white.replace(correlation_length=1.0)
    component = noise_components()[0]
    assert component.name == "heteroscedastic"
    assert white.is_active(component) and shapes_neutral(component.parameters, white)
    assert not shapes_neutral(component.parameters, shaped)
    assert not NoiseValues.neutral().is_active(component)
    # Shape parameters alone draw nothing.
    assert not NoiseValues.from_values({"correlation_length": 1.0}).is_active(component)


def test_vector_view_keeps_batch_shape_and_dtype_and_widens_to_the_srgb_model() -> None:
    vector = torch.rand(4, vector_size("paper"), generator=torch.Generator().manual_seed(0))
    values = values_from_vector(vector, "paper")
    assert values.batch_shape == (4,) and values.dtype == vector.dtype
    assert model_vector(values, "srgb").shape == (4, vector_size("srgb"))


def test_vector_round_trip_with_batch_dimensions() -> None:
    vector = torch.rand(4, 2, vector_size(), generator=torch.Generator().manual_seed(0))
    values = values_from_vector(vector)
    assert values["shot"].shape == (4, 2, 1) and values["periodic"].shape == (4, 2, 3)
    assert torch.equal(values["shot"][..., 0], vector[..., 0])
    assert torch.equal(values["periodic"], vector[..., 12:15])
    assert torch.equal(model_vector(values), vector)
    paper_vector = vector[..., :8]
    paper_values = values_from_vector(paper_vector, "paper")
    assert list(paper_values) == list(noise_parameter_names())
    # What the paper's model lacks is neutral: white, uncompressed noise.
    assert torch.equal(paper_values["channel_gain"], torch.ones(4, 2, 2))
    assert torch.equal(paper_values["compression"], torch.zeros(4, 2, 1))
    assert torch.equal(paper_values["periodic"], paper_vector[..., 5:8])
    assert torch.equal(model_vector(paper_values, "paper"), paper_vector)


def test_values_round_trip_through_the_vector() -> None:
    values = random_noise_values(batch_shape=(3,), generator=torch.Generator().manual_seed(1))
    back = values_from_vector(model_vector(values))
    assert list(back) == list(noise_parameter_names())
    for name in noise_parameter_names():
        assert torch.equal(back[name], values[name])


def test_vector_of_wrong_length_is_rejected() -> None:
    with pytest.raises(ValueError, match="16"):
        values_from_vector(torch.zeros(2, 8))
    with pytest.raises(ValueError, match="8"):
        values_from_vector(torch.zeros(2, 7), "paper")
