"""The oracle fit of the table's sRGB model recovers the values that made a synthetic pair through add_noise."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.evaluation.methods.classical import PoissonGaussian
from darksynth.evaluation.srgb_fit import (
    WHITE,
    OracleComponents,
    compression_of_quality,
    correct_levels,
    fit_srgb_noise,
    synthesize_image,
    values_of_law,
)
from darksynth.noise.components import noise_parameter
from darksynth.noise.correlated import jpeg_quality
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels
from tests.evaluation.test_classical import smooth_scene

KNOWN = NoiseValues.from_values(
    {
        "shot": 0.045,
        "read": 0.008,
        "channel_gain": [1.3, 0.8],
        "correlation_length": 0.9,
        "channel_correlation": [0.5, 0.3, 0.6],
    }
)


@pytest.fixture(scope="module")
def clean() -> torch.Tensor:
    return to_8bit_levels(smooth_scene(256))


def _list(values: NoiseValues, name: str) -> list[float]:
    return [float(v) for v in values[name].tolist()]


def test_round_trip_without_jpeg(clean: torch.Tensor) -> None:
    noisy = synthesize_image(clean, KNOWN, torch.Generator().manual_seed(0))
    fitted = fit_srgb_noise(noisy, clean, OracleComponents(jpeg=False))
    assert fitted.scalar("shot") == pytest.approx(0.045, rel=0.1)
    assert fitted.scalar("correlation_length") == pytest.approx(0.9, abs=0.15)
    assert _list(fitted, "channel_gain") == pytest.approx([1.3, 0.8], abs=0.05)
    assert _list(fitted, "channel_correlation") == pytest.approx([0.5, 0.3, 0.6], abs=0.05)
    assert fitted.scalar("compression") == 0.0


def test_level_correction_keeps_a_right_fit(clean: torch.Tensor) -> None:
    noisy = synthesize_image(clean, KNOWN, torch.Generator().manual_seed(1))
    fitted = fit_srgb_noise(noisy, clean, OracleComponents(candidates=(None,)))
    assert fitted.scalar("shot") == pytest.approx(0.045, rel=0.1)
    assert _list(fitted, "channel_gain") == pytest.approx([1.3, 0.8], abs=0.05)
    assert fitted.scalar("correlation_length") == pytest.approx(0.9, abs=0.15)


def test_white_noise_fits_white(clean: torch.Tensor) -> None:
    white = NoiseValues.from_values({"shot": 0.045, "read": 0.008})
    noisy = synthesize_image(clean, white, torch.Generator().manual_seed(1))
    fitted = fit_srgb_noise(noisy, clean, OracleComponents(jpeg=False))
    assert fitted.scalar("correlation_length") < 0.3
    assert _list(fitted, "channel_correlation") == pytest.approx([0.0, 0.0, 0.0], abs=0.05)
    assert _list(fitted, "channel_gain") == pytest.approx([1.0, 1.0], abs=0.05)


def test_one_rho_is_the_mean_of_the_pairs(clean: torch.Tensor) -> None:
    noisy = synthesize_image(clean, KNOWN, torch.Generator().manual_seed(0))
    pairs = _list(fit_srgb_noise(noisy, clean, OracleComponents(jpeg=False)), "channel_correlation")
    single = _list(fit_srgb_noise(noisy, clean, OracleComponents(pairwise=False, jpeg=False)), "channel_correlation")
    assert single == pytest.approx([sum(pairs) / 3] * 3, abs=1e-12)
    assert single[0] == pytest.approx(0.467, abs=0.05)


def test_left_out_components_stay_neutral(clean: torch.Tensor) -> None:
    noisy = synthesize_image(clean, KNOWN.replace(compression=0.3), torch.Generator().manual_seed(0))
    fitted = fit_srgb_noise(noisy, clean, WHITE)
    assert fitted.scalar("correlation_length") == 0.0
    assert _list(fitted, "channel_correlation") == [0.0, 0.0, 0.0]
    assert fitted.scalar("compression") == 0.0
    assert fitted.scalar("shot") > 0.0 and _list(fitted, "channel_gain") != [1.0, 1.0]


def test_jpeg_search_finds_compression(clean: torch.Tensor) -> None:
    clean = clean[:, :160, :160]
    candidates = (None, 60, 95)
    compressed = KNOWN.replace(correlation_length=0.6, compression=0.4)
    noisy = synthesize_image(clean, compressed, torch.Generator().manual_seed(2))
    fitted = fit_srgb_noise(noisy, clean, OracleComponents(candidates=candidates))
    assert jpeg_quality(fitted.scalar("compression")) == 60
    uncompressed = synthesize_image(clean, KNOWN.replace(correlation_length=0.0), torch.Generator().manual_seed(2))
    found = fit_srgb_noise(uncompressed, clean, OracleComponents(candidates=candidates)).scalar("compression")
    assert jpeg_quality(found) in (None, 95)


def test_quality_maps_to_the_tables_compression() -> None:
    assert compression_of_quality(None) == 0.0
    for quality in (60, 70, 95):
        assert jpeg_quality(compression_of_quality(quality)) == quality
    assert compression_of_quality(1) == noise_parameter("compression").maximum


def test_gains_keep_each_channels_mean_level_and_are_clipped_to_the_table() -> None:
    clean = torch.full((3, 8, 8), 0.4, dtype=torch.float64)
    law = PoissonGaussian(a=(4e-3, 1e-3, 1e-3), b=(1e-4, 1e-4, 0.0))
    values = values_of_law(law, clean)
    assert values.scalar("shot") == pytest.approx(math.sqrt(1e-3))
    assert values.scalar("read") == pytest.approx(0.01)
    red, blue = _list(values, "channel_gain")
    assert red == pytest.approx(math.sqrt((4e-3 * 0.4 + 1e-4) / (1e-3 * 0.4 + 1e-4)))
    assert blue == pytest.approx(math.sqrt((1e-3 * 0.4) / (1e-3 * 0.4 + 1e-4)))
    loud = values_of_law(PoissonGaussian(a=(1.0, 1e-3, 1e-3), b=(0.0, 0.0, 0.0)), clean)
    assert _list(loud, "channel_gain")[0] == noise_parameter("channel_gain").maximum


def test_identical_channel_noise_is_clipped_to_the_tables_correlation(clean: torch.Tensor) -> None:
    grey = clean[1:2].expand(3, -1, -1)
    noise = 0.03 * torch.randn(grey.shape[-2:], generator=torch.Generator().manual_seed(4), dtype=grey.dtype)
    noisy = to_8bit_levels(grey + noise)
    fitted = fit_srgb_noise(noisy, grey, OracleComponents(spatial=False, jpeg=False))
    assert _list(fitted, "channel_correlation") == [noise_parameter("channel_correlation").maximum] * 3


def test_level_correction_moves_green_into_shot_and_read_and_keeps_the_gains(clean: torch.Tensor) -> None:
    clean = clean[:, :128, :128]
    noisy = synthesize_image(clean, KNOWN, torch.Generator().manual_seed(5))
    too_loud = KNOWN.replace(shot=2 * 0.045, read=2 * 0.008)
    corrected, _ = correct_levels(too_loud, noisy - clean, clean, 0, spatial=False)
    assert corrected.scalar("shot") == pytest.approx(0.045, rel=0.1)
    assert corrected.scalar("read") == pytest.approx(0.008, rel=0.1)
    assert _list(corrected, "channel_gain") == pytest.approx([1.3, 0.8], abs=0.05)
    assert corrected.scalar("correlation_length") == 0.9


@pytest.mark.parametrize("chroma", [0.0, 1.5])
def test_chroma_length_round_trip(clean: torch.Tensor, chroma: float) -> None:
    """The colour part's own length is recovered from the principal components; none where there is none."""
    known = KNOWN.replace(correlation_length=0.7, chroma_length=chroma)
    noisy = synthesize_image(clean, known, torch.Generator().manual_seed(5))
    fitted = fit_srgb_noise(noisy, clean, OracleComponents(jpeg=False))
    assert fitted.scalar("correlation_length") == pytest.approx(0.7, abs=0.15)
    assert fitted.scalar("chroma_length") == pytest.approx(chroma, abs=0.35)
    assert fit_srgb_noise(noisy, clean, OracleComponents(jpeg=False, chroma=False)).scalar("chroma_length") == 0.0
