"""The closed-form noise level (mean variance of f(v) over a clip) against drawn noise, and its gradient."""

from __future__ import annotations

import math

import torch

from darksynth.models.den import denormalise
from darksynth.noise.components import model_parameters, vector_size
from darksynth.noise.level import mean_noise_variance
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues


def _batch_values(batch: int, **set_values: list[float]) -> NoiseValues:
    return NoiseValues.from_values(set_values, batch_shape=(batch,))


def test_mean_variance_matches_drawn_noise_on_a_textured_clip() -> None:
    generator = torch.Generator().manual_seed(11)
    # A ramp plus texture, different per channel, so the per-channel means matter.
    ramp = torch.linspace(0.02, 0.4, 192, dtype=torch.float64).view(1, 1, 1, 1, 192)
    dark = (ramp * torch.tensor([0.6, 1.0, 1.3], dtype=torch.float64).view(1, 1, 3, 1, 1)).expand(1, 3, 3, 160, 192)
    dark = (dark + 0.02 * torch.rand(dark.shape, generator=generator, dtype=torch.float64)).contiguous()
    values = _batch_values(
        1,
        shot=[0.12],
        read=[0.015],
        channel_gain=[1.4, 0.8],
        correlation_length=[0.9],
        channel_correlation=[0.5, 0.3, 0.5],
        banding=[0.01],
        temporal_banding=[0.008],
    )
    noise = noise_sum(dark, values, generator=generator)
    expected = float(mean_noise_variance(values, dark)[0])
    measured = float(noise.var())
    # Banding has only 3 x 192 (per-clip) and 3 x 3 x 192 (per-frame) draws: a looser bound than pixel noise.
    assert abs(measured / expected - 1.0) < 0.08, (measured, expected)


def test_mean_variance_grows_with_shot_only_on_bright_clips() -> None:
    values = _batch_values(2, shot=[0.1], read=[0.01])
    dark = torch.stack([torch.full((1, 3, 8, 8), 0.01), torch.full((1, 3, 8, 8), 0.5)]).double()
    variance = mean_noise_variance(values, dark)
    assert torch.allclose(variance, torch.tensor([0.1**2 * 0.01 + 0.01**2, 0.1**2 * 0.5 + 0.01**2]).double())


def test_level_has_finite_gradients_through_the_log_scale_head() -> None:
    """The level loss differentiates through denormalise; linear entries must not poison it with NaN."""
    normalised = torch.rand(4, vector_size("srgb"), generator=torch.Generator().manual_seed(2), requires_grad=True)
    vector = denormalise(normalised, "srgb", log_levels=True)
    parts = torch.split(vector, [p.size for p in model_parameters("srgb")], dim=-1)
    values = {p.name: part for p, part in zip(model_parameters("srgb"), parts, strict=True)}
    dark = torch.rand(4, 2, 3, 16, 16, generator=torch.Generator().manual_seed(3))
    mean_noise_variance(values, dark).log().sum().backward()
    assert normalised.grad is not None
    assert torch.isfinite(normalised.grad).all()
    assert math.isfinite(float(normalised.grad.abs().sum())) and float(normalised.grad.abs().sum()) > 0
