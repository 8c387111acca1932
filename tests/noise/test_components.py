"""The parameter table: each model's parameters, their sizes, ranges and order in the flat vector v."""

from __future__ import annotations

import pytest

from darksynth.noise.components import (
    NOISE_COMPONENTS,
    model_parameters,
    noise_parameter,
    noise_parameters,
    vector_size,
)


def test_the_papers_model_has_eight_values_in_table_order() -> None:
    paper = model_parameters("paper")
    assert vector_size("paper") == 8
    assert tuple(p.name for p in paper) == ("shot", "read", "quantization", "banding", "temporal_banding", "periodic")
    assert [p.size for p in paper] == [1, 1, 1, 1, 1, 3]
    assert [c.name for c in NOISE_COMPONENTS if c.per_clip] == ["temporal_banding"]
    for parameter in noise_parameters():
        low, high = parameter.training_range
        assert parameter.minimum <= low <= high <= parameter.maximum
        assert parameter.minimum <= parameter.neutral <= parameter.maximum
    assert noise_parameter("periodic").size == 3
    # The sRGB model extends the paper's v; the paper's parameters keep their order inside it.
    srgb = model_parameters("srgb")
    assert vector_size() == vector_size("srgb") == 16
    # The shipped sRGB DEN was built for table version 2: its v keeps 15 values, chroma_length is newer.
    assert vector_size("srgb", 2) == 15 and vector_size("paper", 2) == vector_size("paper", 1) == 8
    assert "chroma_length" not in {p.name for p in model_parameters("srgb", 2)}
    assert [p.name for p in srgb if p.noise_model == "paper"] == [p.name for p in paper]
    assert {p.name for p in srgb if p.noise_model == "srgb"} == {
        "channel_gain",
        "correlation_length",
        "channel_correlation",
        "chroma_length",
        "compression",
    }
    assert noise_parameter("channel_gain").neutral == 1.0
    with pytest.raises(KeyError, match="shot"):
        noise_parameter("gain")
