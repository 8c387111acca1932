"""noise/sampling.py: the random_* draws of noise values and of darkening values within their ranges."""

from __future__ import annotations

import math

import torch

from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE
from darksynth.noise.components import model_parameters
from darksynth.noise.sampling import random_darkening_values, random_noise_values


def test_random_noise_values_stay_in_training_ranges() -> None:
    values = random_noise_values(
        batch_shape=(5000,), generator=torch.Generator().manual_seed(2), noise_model="spectral"
    )
    for parameter in model_parameters("spectral"):
        low, high = parameter.training_range
        drawn = values[parameter.name]
        assert drawn.shape == (5000, parameter.size)
        assert (drawn >= low).all() and (drawn <= high).all()
        # 5000 uniform draws miss 2% of the width at an end with probability 0.98^5000 ~ 1e-44.
        assert drawn.min().item() - low < 0.02 * (high - low)
        assert high - drawn.max().item() < 0.02 * (high - low)


def test_log_level_prior_draws_levels_log_uniformly_and_leaves_the_rest_uniform() -> None:
    values = random_noise_values(
        batch_shape=(20000,), generator=torch.Generator().manual_seed(9), log_levels=True, noise_model="spectral"
    )
    for parameter in model_parameters("spectral"):
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


def test_random_darkening_values_stay_inside_and_cover_the_paper_ranges() -> None:
    alpha, gamma = random_darkening_values(batch_shape=(10000,), generator=torch.Generator().manual_seed(2))
    assert alpha.shape == gamma.shape == (10000,)
    for values, (low, high) in ((alpha, ALPHA_RANGE), (gamma, GAMMA_RANGE)):
        assert (values >= low).all() and (values <= high).all()
        # For 10000 uniform draws the gap between the minimum and the bound exceeds 1% of the width with
        # probability 0.99^10000 ~ 1e-44, so both ends must come within 1% of the width.
        width = high - low
        assert values.min().item() - low < 0.01 * width
        assert high - values.max().item() < 0.01 * width
        # Uniform: the mean is the midpoint within 5 standard errors width / sqrt(12 n).
        assert abs(values.mean().item() - (low + high) / 2) < 5.0 * width / (12.0 * 10000) ** 0.5
    assert ALPHA_RANGE == (0.05, 0.3)
    assert GAMMA_RANGE == (0.1, 1.0)
    # alpha and gamma are drawn independently.
    correlation = torch.corrcoef(torch.stack([alpha, gamma]).double())[0, 1].item()
    assert abs(correlation) < 5.0 / 100.0


def test_random_darkening_values_are_reproducible() -> None:
    first = random_darkening_values(batch_shape=(4,), generator=torch.Generator().manual_seed(3))
    second = random_darkening_values(batch_shape=(4,), generator=torch.Generator().manual_seed(3))
    third = random_darkening_values(batch_shape=(4,), generator=torch.Generator().manual_seed(4))
    assert torch.equal(first[0], second[0]) and torch.equal(first[1], second[1])
    assert not torch.equal(first[0], third[0])
