"""synthesize() and ClipSynthesizer: per-clip parameter draws from a profile, zero noise, reproducibility, and
frame-by-frame streaming with components held over the clip."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import torch

import darksynth
from darksynth.errors import DarksynthError
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening, darken
from darksynth.noise.spectral import level_std
from darksynth.noise.values import NoiseValues
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import AUGMENTING, ClipParameters, ClipRecipe, draw_clip_parameters
from darksynth.synthesize import ClipSynthesizer
from tests.conftest import ProfileFactory
from tests.noise.test_simulate import ALL_ON, ALPHA, GAMMA, _ramp_clip


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


@pytest.mark.parametrize("dtype", [torch.uint8, torch.float32])
def test_a_frame_size_change_within_a_clip_redraws_the_held_patterns_with_one_log_line(
    dtype: torch.dtype, caplog: pytest.LogCaptureFixture
) -> None:
    """A stream that changes size goes on: same law at the new size (temporal banding held again, now at the new
    width), the general composer from then on, one warning per change."""
    parameters = _parameters(temporal_banding=0.02, read=0.01)
    synthesizer = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(7))
    scale, grey = (255, 128) if dtype == torch.uint8 else (1, 0.5)
    small = torch.full((3, 64, 48), grey, dtype=dtype)
    large = torch.full((3, 96, 80), grey, dtype=dtype)
    with caplog.at_level(logging.WARNING, logger="darksynth.synthesize"):
        synthesizer(small)
        outputs = [synthesizer(large).double() / scale for _ in range(6)]
    assert all(out.shape == large.shape for out in outputs)
    warnings = [r.getMessage() for r in caplog.records if "frame size changed" in r.getMessage()]
    assert len(warnings) == 1 and "3x64x48 to 3x96x80" in warnings[0]
    assert synthesizer.route_name == "composer" and synthesizer.held["temporal_banding"].shape[-1] == 80
    # The held column pattern is the same in every frame at the new size: its column means agree across frames
    # far better than the per-pixel noise alone would make them (std 0.01 / sqrt(96) per column mean).
    column_means = torch.stack([out.mean(dim=-2) for out in outputs])
    assert float(column_means.std(dim=0).mean()) < 0.5 * float(column_means.std(dim=-1).mean())
    assert abs(float(column_means.std(dim=-1).mean()) - 0.02) < 0.006


def test_non_frame_input_is_rejected() -> None:
    synthesizer = ClipSynthesizer(_parameters())
    with pytest.raises(ValueError, match=r"\(C, H, W\)"):
        synthesizer(torch.zeros(1, 3, 8, 8))


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


def test_a_drawn_cameras_level_is_the_noise_the_output_shows(make_profile: ProfileFactory) -> None:
    # A flat grey image with no other component: each channel's noise std is the drawn level curve at 0.5 (128 x 128
    # pixels of noise with coarse octaves: the measured std stays within 5 % of it, 10 % allowed).
    # Cameras drawn with a JPEG stage are passed over: JPEG takes some of the noise the curve adds.
    flat = torch.full((3, 128, 128), 0.5)
    curves = set()
    for seed in range(40):
        result = darksynth.synthesize(
            flat, make_profile(), generator=torch.Generator().manual_seed(seed), darkening=None, camera="dslr"
        )
        assert isinstance(result.parameters, dict) and isinstance(result.image, torch.Tensor)
        assert result.parameters["camera"] == {"source": "dslr", "given_profile": False}
        noise = result.parameters["noise"]
        if noise["compression"] != 0.0:
            continue
        if len(curves) == 4:
            break
        curve = torch.tensor(noise["level_curve"], dtype=torch.float64)
        expected = level_std(torch.full((3, 1, 1), 0.5, dtype=torch.float64), curve).reshape(3)
        measured = (result.image.double() - 0.5).std(dim=(1, 2))
        assert torch.allclose(measured, expected, rtol=0.1), (measured, expected)
        curves.add(tuple(noise["level_curve"]))
    assert len(curves) == 4


def test_synthesize_with_a_camera_follows_the_recipe(make_profile: ProfileFactory) -> None:
    profile = make_profile(darkening=Darkening(ALPHA, GAMMA), **ALL_ON)
    clean = torch.randint(0, 256, (3, 32, 48), dtype=torch.uint8, generator=torch.Generator().manual_seed(3))
    result = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(4), camera="phone")
    generator = torch.Generator().manual_seed(4)
    chosen = ClipRecipe(profile, jitter=AUGMENTING, camera="phone").choose(generator, clean)
    replayed = darksynth.synthesize(clean, profile, generator=generator, parameters=chosen)
    assert torch.equal(result.image, replayed.image) and result.parameters == chosen.to_json()
    plain = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(4))
    assert isinstance(plain.parameters, dict) and "camera" not in plain.parameters
    assert not torch.equal(plain.image, result.image)
    with pytest.raises(DarksynthError, match="unknown camera 'phones'"):
        darksynth.synthesize(clean, profile, camera="phones")
