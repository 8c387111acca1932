"""Darkening x_d = alpha * x ** (1 / gamma)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from darksynth.light.darkening import darken


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
