"""The composer f(v): noise_sum / add_noise."""

from __future__ import annotations

import torch

from darksynth.light.darkening import darken
from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.heteroscedastic import heteroscedastic_noise
from darksynth.noise.periodic import periodic_noise
from darksynth.noise.quantization import quantization_noise
from darksynth.noise.simulate import add_noise, noise_sum
from darksynth.noise.values import NoiseValues

ALPHA, GAMMA = 0.2, 0.7
ALL_ON = {
    "shot": 0.06,
    "read": 0.012,
    "quantization": 0.004,
    "banding": 0.004,
    "temporal_banding": 0.003,
    "periodic": [0.002, 0.003, 0.004],
}


def _tensors(noise: dict[str, float | list[float]]) -> NoiseValues:
    return NoiseValues.from_values(noise, dtype=torch.float32)


def _zeros() -> NoiseValues:
    return NoiseValues.neutral(dtype=torch.float32)


def _ramp_clip() -> torch.Tensor:
    ramp = torch.linspace(0.0, 1.0, 40 * 56).reshape(40, 56)
    return torch.stack([ramp, ramp.flip(0), ramp.T.reshape(40, 56)]).unsqueeze(0)  # (1, 3, 40, 56)


def test_zero_parameters_give_back_the_signal_and_draw_nothing() -> None:
    signal = darken(_ramp_clip(), ALPHA, GAMMA)
    generator = torch.Generator().manual_seed(0)
    state = generator.get_state()
    assert torch.equal(noise_sum(signal, _zeros(), generator=generator), torch.zeros_like(signal))
    assert torch.equal(add_noise(signal, _zeros(), generator=generator), signal)
    # Inactive components consume no random numbers.
    assert torch.equal(generator.get_state(), state)


def test_noise_sum_equals_the_components_drawn_columns_first() -> None:
    signal = darken(torch.rand(2, 3, 24, 32, generator=torch.Generator().manual_seed(1)), ALPHA, GAMMA)
    values = _tensors(ALL_ON)
    composed = noise_sum(signal, values, generator=torch.Generator().manual_seed(2))

    generator = torch.Generator().manual_seed(2)
    shape = signal.shape
    reference = banding_noise(shape, 0.004, generator=generator)
    reference = reference + temporal_banding_noise(shape, 0.003, generator=generator)
    reference = reference + periodic_noise(shape, torch.tensor([0.002, 0.003, 0.004]), generator=generator)
    reference = reference + heteroscedastic_noise(signal, 0.06, 0.012, generator=generator)
    reference = reference + quantization_noise(shape, 0.004, generator=generator)
    # Equal up to the order of the float additions: the draws happened in this order.
    torch.testing.assert_close(composed, reference, rtol=0.0, atol=1e-7)


def test_add_noise_clips_to_unit_range() -> None:
    signal = _ramp_clip()
    values = _tensors({"shot": 1.0, "read": 0.5})
    generator = torch.Generator().manual_seed(3)
    noisy = add_noise(signal, values, generator=generator)
    unclipped = signal + noise_sum(signal, values, generator=torch.Generator().manual_seed(3))
    assert noisy.min().item() == 0.0 and noisy.max().item() == 1.0
    assert (unclipped < 0).any() and (unclipped > 1).any()
    assert torch.equal(noisy, unclipped.clamp(0.0, 1.0))


def test_same_seed_same_output_different_seed_different_output() -> None:
    signal = darken(_ramp_clip(), ALPHA, GAMMA)
    values = _tensors(ALL_ON)
    a = add_noise(signal, values, generator=torch.Generator().manual_seed(4))
    b = add_noise(signal, values, generator=torch.Generator().manual_seed(4))
    c = add_noise(signal, values, generator=torch.Generator().manual_seed(5))
    assert torch.equal(a, b)
    assert not torch.equal(a, c)
    # Different seeds differ at almost every pixel, not just somewhere.
    assert (a != c).float().mean().item() > 0.9
