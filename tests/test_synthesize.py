"""ClipSynthesizer: frame-by-frame streaming with components held over the clip."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import darksynth
from darksynth.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.profile import default_profile_path, load_profile
from darksynth.synthesize import ClipParameters, ClipSynthesizer, draw_clip_parameters


def _parameters(darkening: Darkening | None = None, **nonzero: float) -> ClipParameters:
    return ClipParameters(noise=NoiseValues.from_values(nonzero), darkening=darkening)


def _grey_frames() -> dict[str, torch.Tensor]:
    return {"uint8": torch.full((3, 24, 256), 128, dtype=torch.uint8), "float": torch.full((3, 24, 256), 0.5)}


@pytest.mark.parametrize("kind", ["uint8", "float"])
def test_temporal_banding_is_identical_in_every_frame_of_a_stream(kind: str) -> None:
    frame = _grey_frames()[kind]
    synthesizer = ClipSynthesizer(_parameters(temporal_banding=0.03), generator=torch.Generator().manual_seed(1))
    outputs = [synthesizer(frame) for _ in range(5)]
    for output in outputs[1:]:
        assert torch.equal(output, outputs[0])
    first = outputs[0].double()
    # The held pattern is real: constant down columns, varying across columns with std sigma (5 standard
    # errors sigma / sqrt(2 n) over the 3 x 256 column offsets; one 8-bit level of rounding is allowed for).
    assert torch.equal(first, first[:, :1, :].expand_as(first))
    scale = 255.0 if kind == "uint8" else 1.0
    std = first[:, 0, :].std().item() / scale
    assert abs(std - 0.03) < 5.0 * 0.03 / math.sqrt(2 * 3 * 256) + 0.5 / 255.0

    # A second stream (a new clip) draws a new pattern.
    other = ClipSynthesizer(_parameters(temporal_banding=0.03), generator=synthesizer.generator)(frame)
    assert not torch.equal(other, outputs[0])


@pytest.mark.parametrize("kind", ["uint8", "float"])
def test_per_frame_banding_differs_between_frames(kind: str) -> None:
    frame = _grey_frames()[kind]
    synthesizer = ClipSynthesizer(_parameters(banding=0.03), generator=torch.Generator().manual_seed(2))
    a, b = synthesizer(frame).double(), synthesizer(frame).double()
    assert torch.equal(a, a[:, :1, :].expand_as(a))
    assert torch.equal(b, b[:, :1, :].expand_as(b))
    rows_a, rows_b = a[:, 0, :].flatten(), b[:, 0, :].flatten()
    # Independent draws per frame: correlation of the two frames' column offsets is 0 within 5 standard errors.
    correlation = torch.corrcoef(torch.stack([rows_a, rows_b]))[0, 1].item()
    assert abs(correlation) < 5.0 / math.sqrt(rows_a.numel())


def test_uint16_frame_goes_through_the_float_path_and_stays_uint16() -> None:
    frame = torch.full((3, 32, 48), 32768, dtype=torch.uint16)
    quiet = ClipSynthesizer(_parameters(Darkening(0.2, 0.7)), generator=torch.Generator().manual_seed(3))
    output = quiet(frame)
    assert output.dtype == torch.uint16
    expected = round(0.2 * (32768 / 65535) ** (1 / 0.7) * 65535)
    assert (output.to(torch.int32) - expected).abs().max().item() <= 1

    noisy = ClipSynthesizer(_parameters(Darkening(0.2, 0.7), read=0.01), generator=torch.Generator().manual_seed(3))
    values = noisy(frame).to(torch.int32).double()
    n = values.numel()
    # Mean at the darkened level within 5 standard errors; std 0.01 of full scale within 5 standard errors.
    assert abs(values.mean().item() - expected) < 5.0 * 0.01 * 65535 / math.sqrt(n)
    assert abs(values.std().item() / 65535 - 0.01) < 5.0 * 0.01 / math.sqrt(2 * (n - 1))


def test_uint16_through_synthesize_and_numpy() -> None:
    profile = load_profile(default_profile_path())
    array = np.full((16, 24, 3), 40000, dtype=np.uint16)
    result = darksynth.synthesize(array, profile, generator=torch.Generator().manual_seed(4))
    assert isinstance(result.image, np.ndarray)
    assert result.image.dtype == np.uint16 and result.image.shape == array.shape
    darkened = 0.2 * (40000 / 65535) ** (1 / 0.7) * 65535
    # Quantization adds q/2 = 0.002 on average. The image mean has a standard error of about 0.0015 of full
    # scale (mostly the periodic DC mode: one draw per channel, std 0.002 / sqrt(3)); 0.01 is over 5 of them.
    assert abs(result.image.mean() - darkened - 0.002 * 65535) < 0.01 * 65535


def test_synthesize_uint8_clip_equals_streaming_frame_by_frame() -> None:
    profile = load_profile(default_profile_path())
    clip = torch.randint(0, 256, (4, 3, 24, 40), dtype=torch.uint8, generator=torch.Generator().manual_seed(5))
    batch = darksynth.synthesize(clip, profile, generator=torch.Generator().manual_seed(6))

    generator = torch.Generator().manual_seed(6)
    parameters = draw_clip_parameters(profile, generator=generator)
    synthesizer = ClipSynthesizer(parameters, generator=generator)
    streamed = torch.stack([synthesizer(frame) for frame in clip])
    assert torch.equal(batch.image, streamed)
    assert batch.parameters == parameters.to_json()


def test_frame_size_change_within_a_clip_is_rejected() -> None:
    synthesizer = ClipSynthesizer(_parameters(temporal_banding=0.01), generator=torch.Generator().manual_seed(7))
    synthesizer(torch.zeros(3, 8, 16))
    with pytest.raises(ValueError, match="frame size changed"):
        synthesizer(torch.zeros(3, 8, 32))


def test_non_frame_input_is_rejected() -> None:
    synthesizer = ClipSynthesizer(_parameters())
    with pytest.raises(ValueError, match=r"\(C, H, W\)"):
        synthesizer(torch.zeros(1, 3, 8, 8))
