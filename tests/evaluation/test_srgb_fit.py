"""The oracle fit of the extended sRGB model recovers the parameters that made a synthetic pair."""

from __future__ import annotations

import pytest
import torch

from darksynth.evaluation.classical import PoissonGaussian
from darksynth.evaluation.methods import build_method
from darksynth.evaluation.srgb_fit import SrgbNoise, fit_srgb_noise, synthesize_srgb
from darksynth.tensors import to_8bit_levels


def smooth_scene(size: int) -> torch.Tensor:
    """A smooth (3, H, W) scene covering levels 0.1-0.9."""
    y, x = torch.meshgrid(
        torch.linspace(0, 1, size, dtype=torch.float64), torch.linspace(0, 1, size, dtype=torch.float64), indexing="ij"
    )
    ramp = 0.1 + 0.8 * (0.7 * x + 0.3 * y)
    return torch.stack([ramp, ramp.flip(-1), 0.5 + 0.3 * torch.sin(3 * x) * torch.cos(2 * y)])


KNOWN = SrgbNoise(
    law=PoissonGaussian(a=(2e-3, 1.5e-3, 2.5e-3), b=(4e-5, 6e-5, 3e-5)),
    correlation_length=1.2,
    correlation_length_y=0.7,
    rho=0.5,
)


@pytest.fixture(scope="module")
def clean() -> torch.Tensor:
    return to_8bit_levels(smooth_scene(256))


def test_round_trip_without_jpeg(clean: torch.Tensor) -> None:
    noisy = synthesize_srgb(clean, KNOWN, torch.Generator().manual_seed(0))
    fitted = fit_srgb_noise(noisy, clean, jpeg=False)
    assert abs(fitted.correlation_length - 1.2) < 0.15
    assert abs(fitted.correlation_length_y - 0.7) < 0.15
    assert abs(fitted.rho - 0.5) < 0.05
    for got, want in zip(fitted.law.a, KNOWN.law.a, strict=True):
        assert abs(got - want) < 0.25 * want
    assert fitted.jpeg_quality is None and fitted.gains == (1.0, 1.0, 1.0)


def test_white_noise_fits_white(clean: torch.Tensor) -> None:
    white = SrgbNoise(law=KNOWN.law)
    noisy = synthesize_srgb(clean, white, torch.Generator().manual_seed(1))
    fitted = fit_srgb_noise(noisy, clean, jpeg=False)
    assert fitted.correlation_length < 0.3 and fitted.correlation_length_y < 0.3
    assert abs(fitted.rho) < 0.05


def test_jpeg_search_finds_compression(clean: torch.Tensor) -> None:
    clean = clean[:, :160, :160]
    strong = SrgbNoise(law=KNOWN.law, correlation_length=0.6, correlation_length_y=0.6, rho=0.3, jpeg_quality=60)
    noisy = synthesize_srgb(clean, strong, torch.Generator().manual_seed(2))
    candidates = (None, 60, 95)
    fitted = fit_srgb_noise(noisy, clean, candidates=candidates)
    assert fitted.jpeg_quality == 60
    uncompressed = synthesize_srgb(clean, SrgbNoise(law=KNOWN.law, rho=0.3), torch.Generator().manual_seed(2))
    assert fit_srgb_noise(uncompressed, clean, candidates=candidates).jpeg_quality in (None, 95)


@pytest.mark.parametrize(
    "name", ["srgb-oracle", "pg-corr-oracle", "pg-rho-oracle", "srgb-nojpeg-oracle", "srgb-gains-oracle"]
)
def test_methods_are_oracles_with_8bit_outputs(name: str, clean: torch.Tensor) -> None:
    method = build_method(name)
    assert method.oracle
    clean = clean[:, :96, :96]
    noisy = synthesize_srgb(clean, KNOWN, torch.Generator().manual_seed(3))
    synthetic = method.synthesize(clean, method.fit(noisy, clean), torch.Generator().manual_seed(0))
    assert synthetic.shape == clean.shape
    assert torch.equal(synthetic * 255, (synthetic * 255).round())
