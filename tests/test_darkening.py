"""Darkening x_d = alpha * x ** (1 / gamma) and the random draws of alpha and gamma."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.darkening import ALPHA_RANGE, GAMMA_RANGE, darken
from darksynth.noise.sampling import random_darkening_values


@pytest.mark.parametrize(("alpha", "gamma"), [(0.2, 0.7), (0.05, 0.1), (0.3, 1.0), (1.0, 0.5)])
def test_darken_matches_float64_reference_on_a_ramp(alpha: float, gamma: float) -> None:
    ramp = torch.linspace(0.0, 1.0, 1001).reshape(1, 1, 1, 1001)
    reference = alpha * np.power(np.linspace(0.0, 1.0, 1001), 1.0 / gamma)
    result = darken(ramp, alpha, gamma)
    np.testing.assert_allclose(result.flatten().double().numpy(), reference, rtol=2e-6, atol=1e-12)
    assert result.max().item() == pytest.approx(alpha, rel=1e-6)
    assert result.min().item() == 0.0


def test_identity_when_alpha_and_gamma_are_one() -> None:
    clip = torch.rand(2, 3, 16, 16, generator=torch.Generator().manual_seed(0))
    assert torch.equal(darken(clip, 1.0, 1.0), clip)


def test_per_clip_tensors_broadcast() -> None:
    clips = torch.rand(2, 3, 2, 3, 8, 8, generator=torch.Generator().manual_seed(1))
    alpha = torch.tensor([[0.1, 0.2, 0.3], [0.05, 0.15, 0.25]])
    gamma = torch.tensor([[0.2, 0.5, 1.0], [0.1, 0.4, 0.9]])
    result = darken(clips, alpha, gamma)
    for i in range(2):
        for j in range(3):
            expected = darken(clips[i, j], alpha[i, j].item(), gamma[i, j].item())
            torch.testing.assert_close(result[i, j], expected, rtol=1e-6, atol=0.0)


def test_per_clip_tensor_of_wrong_shape_is_rejected() -> None:
    with pytest.raises(ValueError, match="batch shape"):
        darken(torch.rand(2, 1, 3, 4, 4), torch.tensor([0.1, 0.2, 0.3]), 1.0)


def test_input_outside_unit_range_is_clamped() -> None:
    clip = torch.tensor([-0.5, 1.5]).reshape(1, 1, 1, 2)
    torch.testing.assert_close(darken(clip, 0.2, 0.5).flatten(), torch.tensor([0.0, 0.2]))


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
