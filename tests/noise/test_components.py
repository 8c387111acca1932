"""The parameter table, the flat vector v, and per-clip parameter draws from a profile."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
import torch

import darksynth
from darksynth.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening
from darksynth.noise.components import (
    NOISE_COMPONENTS,
    model_parameters,
    noise_parameter,
    noise_parameter_names,
    noise_parameters,
    vector_size,
)
from darksynth.noise.sampling import random_noise_values
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, default_profile_path, load_profile
from darksynth.synthesize import draw_clip_parameters

ProfileFactory = Callable[..., Profile]


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
    assert vector_size() == vector_size("srgb") == 15
    assert [p.name for p in srgb if p.noise_model == "paper"] == [p.name for p in paper]
    assert {p.name for p in srgb if p.noise_model == "srgb"} == {
        "channel_gain",
        "correlation_length",
        "channel_correlation",
        "compression",
    }
    assert noise_parameter("channel_gain").neutral == 1.0
    with pytest.raises(KeyError, match="shot"):
        noise_parameter("gain")


def test_vector_round_trip_with_batch_dimensions() -> None:
    vector = torch.rand(4, 2, vector_size(), generator=torch.Generator().manual_seed(0))
    values = NoiseValues.from_vector(vector)
    assert values["shot"].shape == (4, 2, 1) and values["periodic"].shape == (4, 2, 3)
    assert torch.equal(values["shot"][..., 0], vector[..., 0])
    assert torch.equal(values["periodic"], vector[..., 11:14])
    assert torch.equal(values.vector(), vector)
    paper_vector = vector[..., :8]
    paper_values = NoiseValues.from_vector(paper_vector, "paper")
    assert list(paper_values) == list(noise_parameter_names())
    # What the paper's model lacks is neutral: white, uncompressed noise.
    assert torch.equal(paper_values["channel_gain"], torch.ones(4, 2, 2))
    assert torch.equal(paper_values["compression"], torch.zeros(4, 2, 1))
    assert torch.equal(paper_values["periodic"], paper_vector[..., 5:8])
    assert torch.equal(paper_values.vector("paper"), paper_vector)


def test_values_round_trip_through_the_vector() -> None:
    values = random_noise_values(batch_shape=(3,), generator=torch.Generator().manual_seed(1))
    back = NoiseValues.from_vector(values.vector())
    assert list(back) == list(noise_parameter_names())
    for name in noise_parameter_names():
        assert torch.equal(back[name], values[name])


def test_vector_of_wrong_length_is_rejected() -> None:
    with pytest.raises(ValueError, match="15"):
        NoiseValues.from_vector(torch.zeros(2, 8))
    with pytest.raises(ValueError, match="8"):
        NoiseValues.from_vector(torch.zeros(2, 7), "paper")


def test_random_noise_values_stay_in_training_ranges() -> None:
    values = random_noise_values(batch_shape=(5000,), generator=torch.Generator().manual_seed(2))
    for parameter in noise_parameters():
        low, high = parameter.training_range
        drawn = values[parameter.name]
        assert drawn.shape == (5000, parameter.size)
        assert (drawn >= low).all() and (drawn <= high).all()
        # 5000 uniform draws miss 2% of the width at an end with probability 0.98^5000 ~ 1e-44.
        assert drawn.min().item() - low < 0.02 * (high - low)
        assert high - drawn.max().item() < 0.02 * (high - low)


def test_fixed_profile_values_are_reproduced_exactly() -> None:
    profile = load_profile(default_profile_path())
    generator = torch.Generator().manual_seed(3)
    state = generator.get_state()
    parameters = draw_clip_parameters(profile, generator=generator)
    assert parameters.noise == profile.noise
    assert parameters.darkening == profile.darkening
    # Nothing was drawn, so the generator is untouched.
    assert torch.equal(generator.get_state(), state)


def test_darkening_none_gives_no_darkening_and_an_explicit_one_is_kept() -> None:
    profile = load_profile(default_profile_path())
    assert draw_clip_parameters(profile, darkening=None).darkening is None
    assert draw_clip_parameters(profile, darkening=Darkening(0.5, 2.0)).darkening == Darkening(0.5, 2.0)
    record = darksynth.synthesize(torch.full((3, 8, 8), 0.5), profile, darkening=None).parameters
    assert isinstance(record, dict) and record["darkening"] is None


def test_ranges_are_sampled_inside_and_cover_them(make_profile: ProfileFactory) -> None:
    ranges = {
        "shot": [(0.02, 0.08)],
        "periodic": [(0.0, 0.01), (0.005, 0.02), (0.01, 0.03)],
        "alpha": [(0.1, 0.25)],
        "gamma": [(0.3, 0.9)],
    }
    profile = make_profile(darkening=Darkening(0.2, 0.7), ranges=ranges, shot=0.05, read=0.01)
    generator = torch.Generator().manual_seed(4)
    draws = [draw_clip_parameters(profile, generator=generator) for _ in range(1000)]
    samples: dict[str, list[tuple[float, ...]]] = {
        "shot": [tuple(d.noise["shot"].tolist()) for d in draws],
        "periodic": [tuple(d.noise["periodic"].tolist()) for d in draws],
        "alpha": [(d.darkening.alpha,) for d in draws if d.darkening],
        "gamma": [(d.darkening.gamma,) for d in draws if d.darkening],
    }
    for name, pairs in ranges.items():
        columns = list(zip(*samples[name], strict=True))
        assert len(columns) == len(pairs) and len(columns[0]) == 1000
        for column, (low, high) in zip(columns, pairs, strict=True):
            assert all(low <= v <= high for v in column), name
            # 1000 uniform draws miss 1% of the width at an end with probability 0.99^1000 ~ 4e-5.
            assert min(column) - low < 0.01 * (high - low)
            assert high - max(column) < 0.01 * (high - low)
    # Parameters without a range keep the profile's value in every draw.
    assert all(d.noise["read"].tolist() == [0.01] for d in draws)
    assert all(d.noise["banding"].tolist() == [0.0] for d in draws)
    # Successive clips get independent draws.
    shots = torch.tensor([s[0] for s in samples["shot"]], dtype=torch.float64)
    assert abs(torch.corrcoef(torch.stack([shots[:-1], shots[1:]]))[0, 1].item()) < 5.0 / math.sqrt(999)


def test_profile_without_darkening_draws_from_the_papers_ranges(make_profile: ProfileFactory) -> None:
    profile = make_profile()
    generator = torch.Generator().manual_seed(5)
    draws = [draw_clip_parameters(profile, generator=generator).darkening for _ in range(500)]
    assert all(d is not None for d in draws)
    alphas = [d.alpha for d in draws if d]
    gammas = [d.gamma for d in draws if d]
    assert ALPHA_RANGE[0] <= min(alphas) and max(alphas) <= ALPHA_RANGE[1]
    assert GAMMA_RANGE[0] <= min(gammas) and max(gammas) <= GAMMA_RANGE[1]
    assert len(set(alphas)) == 500


def test_synthesize_records_and_uses_the_drawn_values(make_profile: ProfileFactory) -> None:
    profile = make_profile(ranges={"shot": [(0.02, 0.06)]}, shot=0.04)
    clean = torch.full((2, 1, 3, 128, 128), 0.5)
    result = darksynth.synthesize(clean, profile, darkening=None, generator=torch.Generator().manual_seed(6))
    assert isinstance(result.parameters, list) and len(result.parameters) == 2

    generator = torch.Generator().manual_seed(6)
    expected_first = draw_clip_parameters(profile, darkening=None, generator=generator)
    assert result.parameters[0] == expected_first.to_json()

    assert isinstance(result.image, torch.Tensor)
    n = result.image[0].numel()
    shots = [record["noise"]["shot"] for record in result.parameters]
    assert shots[0] != shots[1]
    for clip, shot in enumerate(shots):
        assert 0.02 <= shot <= 0.06
        # The recorded shot is the one applied: the output variance is shot^2 * 0.5 within 5 standard errors
        # (no clipping: the std is at most 0.042, 12 of them from either bound).
        expected = shot**2 * 0.5
        assert abs(result.image[clip].var().item() - expected) < 5.0 * expected * math.sqrt(2.0 / (n - 1))


def test_fixed_gamma_is_kept_exactly_when_only_alpha_has_a_range(make_profile: ProfileFactory) -> None:
    profile = make_profile(darkening=Darkening(0.2, 0.7), ranges={"alpha": [(0.1, 0.3)]})
    parameters = draw_clip_parameters(profile, generator=torch.Generator().manual_seed(7))
    assert parameters.darkening is not None
    assert parameters.darkening.gamma == 0.7


def test_log_level_prior_draws_levels_log_uniformly_and_leaves_the_rest_uniform() -> None:
    values = random_noise_values(batch_shape=(20000,), generator=torch.Generator().manual_seed(9), log_levels=True)
    for parameter in noise_parameters():
        drawn = values[parameter.name].double()
        low, high = parameter.training_range
        if parameter.log_floor is None:
            # Uniform: the median is the middle (standard error of a median of 20000 uniforms: 0.0035 of the width).
            assert abs(float(drawn.median()) - (low + high) / 2) < 0.02 * (high - low), parameter.name
            continue
        floor = parameter.log_floor
        assert (drawn >= floor).all() and (drawn <= high).all()
        logs = drawn.log()
        # log-uniform over [log floor, log high]: mean in the middle, variance (width^2 / 12).
        width = math.log(high) - math.log(floor)
        assert abs(float(logs.mean()) - (math.log(floor) + math.log(high)) / 2) < 0.02 * width, parameter.name
        assert abs(float(logs.var()) / (width**2 / 12) - 1) < 0.05, parameter.name
