"""The composer f(v): noise_sum / add_noise, and zero noise through synthesize and ClipSynthesizer."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

import darksynth
from darksynth.darkening import Darkening, darken
from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.heteroscedastic import heteroscedastic_noise
from darksynth.noise.periodic import periodic_noise
from darksynth.noise.quantization import quantization_noise
from darksynth.noise.simulate import add_noise, noise_sum
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.synthesize import ClipParameters, ClipSynthesizer

ProfileFactory = Callable[..., Profile]
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


def test_synthesize_zero_noise_float_input_is_exactly_the_darkened_input(make_profile: ProfileFactory) -> None:
    profile = make_profile(darkening=Darkening(ALPHA, GAMMA))
    clean = _ramp_clip()[0]
    result = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(6))
    assert result.image.dtype == torch.float32
    assert torch.equal(result.image, darken(clean, ALPHA, GAMMA))


def test_synthesize_zero_noise_uint8_input_is_the_rounded_darkened_input(make_profile: ProfileFactory) -> None:
    profile = make_profile(darkening=Darkening(ALPHA, GAMMA))
    clean = torch.arange(256, dtype=torch.uint8).reshape(1, 16, 16).expand(3, 16, 16).contiguous()
    result = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(7))
    assert result.image.dtype == torch.uint8
    reference = np.rint(ALPHA * np.power(np.arange(256) / 255.0, 1.0 / GAMMA) * 255.0).astype(np.uint8)
    assert torch.equal(result.image, torch.from_numpy(reference).reshape(1, 16, 16).expand(3, 16, 16))


def test_synthesize_zero_noise_clip_batch_float(make_profile: ProfileFactory) -> None:
    profile = make_profile(darkening=Darkening(ALPHA, GAMMA))
    clips = torch.rand(2, 3, 3, 8, 8, generator=torch.Generator().manual_seed(8))
    result = darksynth.synthesize(clips, profile, generator=torch.Generator().manual_seed(8))
    assert torch.equal(result.image, darken(clips, ALPHA, GAMMA))
    assert isinstance(result.parameters, list) and len(result.parameters) == 2


def test_clip_synthesizer_zero_noise_gives_the_darkened_frame() -> None:
    parameters = ClipParameters(noise=NoiseValues.neutral(), darkening=Darkening(ALPHA, GAMMA))
    synthesizer = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(9))
    frame = _ramp_clip()[0]
    for _ in range(3):
        assert torch.equal(synthesizer(frame), darken(frame, ALPHA, GAMMA))
    frame8 = (frame * 255).round().to(torch.uint8)
    reference = np.rint(ALPHA * np.power(frame8.double().numpy() / 255.0, 1.0 / GAMMA) * 255.0)
    assert torch.equal(synthesizer(frame8), torch.from_numpy(reference.astype(np.uint8)))


def test_synthesize_with_noise_is_reproducible_and_seed_dependent(make_profile: ProfileFactory) -> None:
    profile = make_profile(darkening=Darkening(ALPHA, GAMMA), **ALL_ON)
    clean = torch.randint(0, 256, (3, 32, 48), dtype=torch.uint8, generator=torch.Generator().manual_seed(10))
    for image in (clean, clean.float() / 255):
        a = darksynth.synthesize(image, profile, generator=torch.Generator().manual_seed(11)).image
        b = darksynth.synthesize(image, profile, generator=torch.Generator().manual_seed(11)).image
        c = darksynth.synthesize(image, profile, generator=torch.Generator().manual_seed(12)).image
        assert torch.equal(a, b)
        assert not torch.equal(a, c)
