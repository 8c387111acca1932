"""noise/texture.py and the spectral component's texture_gain and texture_scale: the law of the texture factor,
and nothing changed without it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.ndimage import gaussian_filter

from darksynth.evaluation.measures.texture_ratio import textured_flat_ratio
from darksynth.light.darkening import Darkening
from darksynth.models.statistics import model_statistics
from darksynth.noise import frame_routes
from darksynth.noise.components import model_parameters, noise_parameter, profile_version
from darksynth.noise.spectral_components import spectral_clips
from darksynth.noise.spectral_kernel import spectral_kernels
from darksynth.noise.texture import (
    DETAIL_BLUR_SIGMA,
    DETAIL_WINDOW_SIGMA,
    block_detail,
    local_detail,
)
from darksynth.noise.values import NoiseValues
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer
from tests.noise.texture_free_outputs import SPECTRAL_VALUES, platform, scene, texture_free_digests

RECORDED = Path(__file__).with_name("texture_free_outputs.json")

WHITE_FLAT_LEVEL = {
    "level_curve": [0.01] * 24,
    "octave_power": [1.0] * 18,
    "octave_correlation": [0.0] * 18,
    "temporal_correlation": [0.0] * 6,
}


def _detail_ramp(height: int = 256, bands: int = 8, band_width: int = 64) -> torch.Tensor:
    """(3, H, bands * band_width): grey 0.4 with a 4-px grating whose amplitude doubles from band to band (the first
    band flat)."""
    x = torch.arange(bands * band_width, dtype=torch.float64)
    amplitude = torch.where(x < band_width, 0.0, 0.0015 * 2.0 ** (x // band_width - 1))
    row = 0.4 + amplitude * torch.sin(2 * math.pi * x / 4.0 + 0.3)
    return row.expand(3, height, -1).clone()


def test_local_detail_is_the_rms_of_the_luminance_high_pass_as_scipy_computes_it() -> None:
    image = 0.3 + 0.1 * torch.rand((3, 40, 56), generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    luminance = image.mean(0).numpy()
    high = luminance - gaussian_filter(luminance, DETAIL_BLUR_SIGMA, mode="nearest", truncate=3.0)
    expected = np.sqrt(gaussian_filter(high**2, DETAIL_WINDOW_SIGMA, mode="nearest", truncate=3.0))
    np.testing.assert_allclose(local_detail(image)[0].numpy(), expected, rtol=1e-9, atol=1e-12)
    blocks = block_detail(image, 8)
    assert blocks.shape == (5, 7)
    assert float(blocks[1, 2]) == pytest.approx(math.sqrt(float(np.mean(high[8:16, 16:24] ** 2))), rel=1e-9)


def test_the_noise_std_follows_one_plus_detail_over_scale_to_the_gain() -> None:
    gain, scale = 1.2, 0.004
    signal = _detail_ramp()
    values = NoiseValues.from_values(WHITE_FLAT_LEVEL | {"texture_gain": gain, "texture_scale": scale})
    noise = spectral_clips(signal[None].float(), values.to(dtype=torch.float32), torch.Generator().manual_seed(4), None)
    expected = (1.0 + local_detail(signal)[0] / scale) ** gain
    assert float(expected[:, 4:48].max()) == pytest.approx(1.0, abs=1e-6)  # the flat band keeps the level curve
    for band in range(8):
        inside = slice(band * 64 + 12, band * 64 + 52)  # away from the band's edges, where the detail changes
        measured = float(noise[0, :, :, inside].double().square().mean().sqrt()) / 0.01
        predicted = float(expected[:, inside].square().mean().sqrt())
        # 3 x 256 x 40 white values: the std of their RMS is about 0.3%.
        assert measured / predicted == pytest.approx(1.0, abs=0.02), band
    assert float(expected[:, 7 * 64 + 12 : 7 * 64 + 52].mean()) > 4.0  # the ramp reaches far beyond 1


def test_texture_gain_zero_draws_the_bits_of_no_texture_in_the_same_run() -> None:
    # Compared within one run: float bits differ between processors, not between two draws on one.
    assert texture_free_digests({"texture_gain": 0.0, "texture_scale": 0.05}) == texture_free_digests()


def test_texture_free_outputs_match_mains_record_for_this_processor() -> None:
    records = json.loads(RECORDED.read_text(encoding="utf-8"))["records"]
    here = platform()
    recorded = next((record["digests"] for record in records if record["platform"] == here), None)
    if recorded is None:
        pytest.skip(f"main's digests were recorded on {[r['platform'] for r in records]}, not on {here}")
    assert texture_free_digests() == recorded


def test_a_texture_scale_alone_changes_nothing_and_a_gain_does() -> None:
    plain = texture_free_digests()
    assert texture_free_digests({"texture_scale": 0.002}) == plain
    textured = texture_free_digests({"texture_gain": 0.8, "texture_scale": 0.01})
    assert all(textured[case] != plain[case] for case in plain)


@pytest.mark.parametrize("compile", [True, False], ids=["compiled", "eager"])
def test_a_texture_gain_draws_stronger_noise_on_texture_through_either_spectral_route(
    monkeypatch: pytest.MonkeyPatch, compile: bool
) -> None:
    # The compiled route with its kernels run eagerly: the compiled ones' values (test_spectral_kernel.py), in a
    # test's time.
    monkeypatch.setattr(frame_routes, "compiled_spectral_kernels", spectral_kernels)
    plain = NoiseValues.from_values(SPECTRAL_VALUES)  # type: ignore[arg-type]
    textured = ClipParameters(plain.replace(texture_gain=1.0, texture_scale=0.003), Darkening(0.3, 1.0))
    stream = ClipSynthesizer(textured, generator=torch.Generator().manual_seed(2), compile=compile)
    route = "compiled spectral" if compile else "spectral"
    assert stream.route_name == route
    clean = (scene(3, 128, 160) * 255.0).round().to(torch.uint8)
    frames = torch.stack([stream(frame) for frame in clean]).double() / 255.0
    assert stream.route_name == route  # drawn by that route, without falling back
    darkened = 0.3 * clean.double() / 255.0
    # The right half holds a fine grating, the left half smooth shading: the noise is stronger on the grating.
    assert textured_flat_ratio(frames - darkened, darkened) > 1.5
    # A texture scale without a gain takes the same route and draws no texture factor.
    untextured = ClipParameters(plain.replace(texture_scale=0.003), Darkening(0.3, 1.0))
    stream = ClipSynthesizer(untextured, generator=torch.Generator().manual_seed(2), compile=compile)
    frames = torch.stack([stream(frame) for frame in clean]).double() / 255.0
    assert stream.route_name == route
    assert textured_flat_ratio(frames - darkened, darkened) < 1.2


def test_the_network_neither_reads_nor_predicts_texture() -> None:
    names = {p.name for p in model_parameters("srgb")}
    assert "level_curve" not in names and not names & {"texture_gain", "texture_scale"}
    assert [s.name for s in model_statistics("srgb")] == [s.name for s in model_statistics("srgb", 5)]
    for name in ("texture_gain", "texture_scale"):
        assert noise_parameter(name).since_version == profile_version() == 6
