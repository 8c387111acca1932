"""Fast paths are declared in the table, chosen by what the values need, and fall back loudly."""

from __future__ import annotations

import logging

import pytest
import torch

from darksynth.light.darkening import Darkening, darken
from darksynth.noise import frame_routes, fused_8bit
from darksynth.noise.frame_routes import ClipState, ComposerRoute
from darksynth.noise.fused_8bit import FAST_PATH
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.spectral_8bit import read_levels, read_levels_by_index
from darksynth.noise.values import NoiseValues, covered_by
from darksynth.profile import Profile
from darksynth.recipe import ClipParameters, draw_clip_parameters
from darksynth.synthesize import ClipSynthesizer, synthesize

PAPER = {"shot": 0.05, "read": 0.01, "quantization": 0.004, "banding": 0.003, "temporal_banding": 0.002}


@pytest.mark.parametrize(
    ("extra", "covered"),
    [
        ({}, True),
        ({"periodic": 0.002}, True),
        ({"channel_gain": [1.3, 1.0]}, False),
        ({"correlation_length": 0.8}, False),
        ({"channel_correlation": [0.3, 0.0, 0.0]}, False),
        ({"compression": 0.3}, False),
    ],
)
def test_the_fused_kernel_covers_what_the_table_declares(extra: dict[str, object], covered: bool) -> None:
    values = NoiseValues.from_values(PAPER | extra)  # type: ignore[arg-type]
    assert covered_by(values, FAST_PATH) is covered
    synthesizer = ClipSynthesizer(ClipParameters(values, None), generator=torch.Generator().manual_seed(0))
    assert (synthesizer.route_name == "fused") is covered


def test_fused_and_general_paths_draw_the_same_law() -> None:
    """8-bit frames take the fused kernel, float frames the general composer: same mean and variance."""
    values = NoiseValues.from_values({"shot": 0.06, "read": 0.012, "quantization": 0.004, "banding": 0.003})
    parameters = ClipParameters(values, Darkening(0.4, 1.0))
    frame8 = torch.full((3, 256, 256), 200, dtype=torch.uint8)
    fused = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(1))
    general = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(1))
    assert fused.route_name == "fused"
    out8 = torch.stack([fused(frame8) for _ in range(4)]).double() / 255.0
    out_float = torch.stack([general(frame8.float() / 255.0) for _ in range(4)]).double()
    # The general path keeps floats: round it as the 8-bit path does before comparing.
    out_float = (out_float * 255.0).round() / 255.0
    level = 0.4 * 200 / 255
    expected_var = 0.06**2 * level + 0.012**2 + 0.004**2 / 12 + 0.003**2 + 1 / (12 * 255**2)
    for out in (out8, out_float):
        assert abs(float(out.mean()) - (level + 0.002)) < 0.002
        assert abs(float(out.var()) / expected_var - 1.0) < 0.05


def test_a_failing_compiled_kernel_falls_back_once_with_a_log_line(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def broken(*args: object) -> torch.Tensor:
        raise RuntimeError("no working C compiler")

    monkeypatch.setattr(frame_routes, "compiled_pixel_kernel", lambda: broken)
    parameters = ClipParameters(NoiseValues.from_values({"read": 0.02}), None)
    frame = torch.full((3, 32, 32), 100, dtype=torch.uint8)
    with caplog.at_level(logging.WARNING, logger="darksynth.synthesize"):
        compiled = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2), compile=True)
        frames = [compiled(frame) for _ in range(3)]
    eager = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2))
    assert all(torch.equal(a, eager(frame)) for a in frames)
    warnings = [r for r in caplog.records if "compiled 8-bit kernel failed" in r.getMessage()]
    assert len(warnings) == 1 and "no working C compiler" in warnings[0].getMessage()
    assert fused_8bit.pixel_kernel_8bit is not broken


SRGB = {
    "shot": 0.05,
    "read": 0.01,
    "quantization": 0.004,
    "channel_gain": [1.3, 0.8],
    "correlation_length": 1.0,
    "channel_correlation": [0.5, 0.3, 0.2],
    "chroma_length": 1.0,
    "banding": 0.002,
}


def test_srgb_values_drawn_for_a_clip_take_the_spectral_path() -> None:
    """A version-3 profile's clip parameters are the translated spectral values: the spectral 8-bit path draws
    them, compiled or not; given untranslated to a synthesizer they take the general composer, which translates."""
    profile = Profile(noise=NoiseValues.from_values(SRGB))  # type: ignore[arg-type]
    drawn = draw_clip_parameters(profile, darkening=None)
    assert ClipSynthesizer(drawn).route_name == "spectral"
    assert ClipSynthesizer(drawn, compile=True).route_name == "compiled spectral"
    untranslated = ClipSynthesizer(ClipParameters(profile.noise, None))
    assert untranslated.route_name == "composer"


SPECTRAL = {
    "level_curve": [0.004, 0.006, 0.008, 0.009, 0.01, 0.011, 0.012, 0.012] * 3,
    "octave_power": [0.5, 0.3, 0.3] * 3 + [2.0, 20.0, 8.0] * 3,
    "octave_correlation": [0.3, -0.2, 0.1] * OCTAVES,
    "quantization": 0.002,
}


@pytest.mark.parametrize(
    ("values", "taken"),
    [
        (SPECTRAL, True),
        (SPECTRAL | {"compression": 0.2, "banding": 0.002}, True),
        (SPECTRAL | {"shot": 0.02}, True),  # white heteroscedastic noise, by its law, in the composer's order
        (SPECTRAL | {"shot": 0.02, "channel_gain": [1.2, 0.9]}, False),  # structured: the spectral model's own
        (SPECTRAL | {"level_curve": [0.0] * 24, "compression": 0.2}, False),  # no spectrum: an sRGB profile
        (PAPER, False),
        (SRGB, False),
    ],
    ids=["spectral", "spectral-jpeg-columns", "spectral-shot", "spectral-structured-shot", "no-curve", "paper", "srgb"],
)
def test_the_spectral_path_is_taken_for_spectral_profiles_only(values: dict[str, object], taken: bool) -> None:
    parameters = ClipParameters(NoiseValues.from_values(values), None)  # type: ignore[arg-type]
    assert (ClipSynthesizer(parameters).route_name == "spectral") is taken


@pytest.mark.parametrize(
    ("extra", "channels"),
    [
        ({}, 3),
        ({"banding": 0.003, "temporal_banding": 0.002, "periodic": [0.001, 0.002, 0.001]}, 3),
        ({"compression": 0.3}, 3),
        ({"temporal_correlation": [0.8, 0.6, 0.5, 0.5, 0.4, 0.3]}, 3),
        ({"banding": 0.003}, 1),
        ({"texture_gain": 0.6, "texture_scale": 0.004, "banding": 0.002}, 3),
        ({"texture_gain": 0.6, "texture_scale": 0.004, "compression": 0.2}, 3),
        ({"shot": 0.03, "read": 0.004, "banding": 0.002}, 3),
        ({"read": 0.003, "texture_gain": 0.6, "texture_scale": 0.004, "compression": 0.2}, 3),
    ],
    ids=["plain", "columns", "jpeg", "temporal", "grey", "texture", "texture-jpeg", "white", "white-texture-jpeg"],
)
def test_the_spectral_path_draws_the_general_composers_bits(extra: dict[str, object], channels: int) -> None:
    """The 8-bit tables of the darkened level and of the curve's std, read per pixel, against the composer's
    per-pixel darkening and curve, same generator: the same frames, bit for bit, over a stream."""
    parameters = ClipParameters(NoiseValues.from_values(SPECTRAL | extra), Darkening(0.3, 0.7))  # type: ignore[arg-type]
    frames = torch.randint(
        0, 256, (3, channels, 72, 136), dtype=torch.uint8, generator=torch.Generator().manual_seed(0)
    )
    fast = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(5))
    values = parameters.noise.to("cpu", torch.float32)
    general = ComposerRoute(
        ClipState(values, torch.device("cpu"), torch.Generator().manual_seed(5)), parameters.darkening
    )
    assert fast.route_name == "spectral"
    for frame in frames:
        assert torch.equal(fast(frame), general(frame))
    assert not torch.equal(fast(frames[0]), fast(frames[0]))  # new noise every frame


def test_the_level_tables_read_by_opencv_and_by_torch_indexing_agree() -> None:
    frame = torch.randint(0, 256, (3, 33, 47), dtype=torch.uint8, generator=torch.Generator().manual_seed(0))
    table = torch.rand(3, 256, generator=torch.Generator().manual_seed(1))
    expected = torch.stack([table[channel][frame[channel].long()] for channel in range(3)])
    assert torch.equal(read_levels(frame, table, torch.empty(3, 33, 47)), expected)
    assert torch.equal(read_levels_by_index(frame, table, torch.empty(3, 33, 47)), expected)


@pytest.mark.parametrize("compression", [0.0, 0.3])
def test_a_float_image_of_8bit_levels_takes_the_spectral_path_with_the_composers_bits(compression: float) -> None:
    values = NoiseValues.from_values(SPECTRAL | {"compression": compression, "banding": 0.002})  # type: ignore[arg-type]
    profile = Profile(noise=values, darkening=Darkening(0.3, 0.7))
    levels = torch.randint(0, 256, (3, 40, 56), dtype=torch.uint8, generator=torch.Generator().manual_seed(0))
    image = levels.float() / 255.0
    taken = synthesize(image, profile, generator=torch.Generator().manual_seed(2)).image
    generator = torch.Generator().manual_seed(2)
    parameters = draw_clip_parameters(profile, generator=generator)
    assert parameters.darkening is not None
    signal = darken(image[None], parameters.darkening.alpha, parameters.darkening.gamma)
    composed = add_noise(signal, parameters.noise.to(dtype=torch.float32), generator=generator)[0]
    assert isinstance(taken, torch.Tensor) and taken.dtype == torch.float32
    assert torch.equal(taken, composed)
    # Off the 8-bit levels the composer runs; the law is the same.
    off_grid = synthesize(image + 1e-4, profile, generator=torch.Generator().manual_seed(2)).image
    assert isinstance(off_grid, torch.Tensor)
    assert (off_grid - taken).abs().mean() < 0.02
