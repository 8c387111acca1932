"""Statistics of the functions that shape the sRGB noise (spatial kernel, channel mixing, JPEG), with fixed
seeds; drawn through the table's composer where a whole noisy image is needed."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.noise.correlated import (
    correlated_normal,
    gaussian_kernel1d,
    jpeg_compress,
    kernel_autocorrelation,
    structured_normal,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues


def lag_correlation(noise: torch.Tensor, lag: int, axis: int) -> float:
    noise = noise - noise.mean()
    length = noise.shape[axis]
    product = noise.narrow(axis, 0, length - lag) * noise.narrow(axis, lag, length - lag)
    return float(product.mean() / noise.square().mean())


def test_kernel_is_normalised_and_white_for_zero_length() -> None:
    assert torch.equal(gaussian_kernel1d(0.0), torch.ones(1, dtype=torch.float64))
    kernel = gaussian_kernel1d(1.3)
    assert math.isclose(float(kernel.sum()), 1.0, rel_tol=1e-12)
    assert kernel.numel() == 2 * math.ceil(3 * 1.3) + 1
    with pytest.raises(ValueError, match="correlation length"):
        gaussian_kernel1d(-1.0)


@pytest.mark.parametrize("length", [0.0, 0.6, 1.5])
def test_filter_preserves_variance(length: float) -> None:
    noise = correlated_normal((3, 256, 256), torch.Generator().manual_seed(1), length, dtype=torch.float64)
    assert noise.shape == (3, 256, 256)
    assert abs(float(noise.var()) - 1.0) < 0.03


@pytest.mark.parametrize("length", [0.6, 1.0, 2.0])
def test_lag_autocorrelation_matches_the_kernel(length: float) -> None:
    noise = correlated_normal((2, 256, 256), torch.Generator().manual_seed(2), length, dtype=torch.float64)
    for lag in (1, 2):
        theory = kernel_autocorrelation(length, lag)
        assert abs(lag_correlation(noise, lag, -1) - theory) < 0.03
        assert abs(lag_correlation(noise, lag, -2) - theory) < 0.03
    # the continuous limit: exp(-d^2 / (4 l^2))
    if length >= 1.0:
        assert abs(kernel_autocorrelation(length, 1) - math.exp(-1 / (4 * length**2))) < 0.01


def test_one_length_correlates_x_and_y_alike() -> None:
    noise = correlated_normal((1, 256, 256), torch.Generator().manual_seed(3), 2.0, dtype=torch.float64)
    theory = kernel_autocorrelation(2.0, 1)
    assert abs(lag_correlation(noise, 1, -1) - theory) < 0.03
    assert abs(lag_correlation(noise, 1, -2) - theory) < 0.03


def test_noise_of_any_size_and_batch_has_unit_variance_up_to_its_borders() -> None:
    noise = correlated_normal((2, 3, 17, 9), torch.Generator().manual_seed(0), 1.2)
    assert noise.shape == (2, 3, 17, 9) and noise.dtype == torch.float32
    # 600 independent draws of a small odd-sized frame: every pixel, the corners too, has variance 1, and
    # neighbours are correlated as the kernel says.
    many = correlated_normal((600, 17, 9), torch.Generator().manual_seed(1), 1.2, dtype=torch.float64)
    per_pixel = many.var(dim=0)
    assert float((per_pixel - 1).abs().max()) < 0.25
    assert abs(float(per_pixel.mean()) - 1) < 0.03
    assert abs(lag_correlation(many, 1, -1) - kernel_autocorrelation(1.2, 1)) < 0.03


@pytest.mark.parametrize("rho", [0.0, 0.3, 0.66])
def test_equal_pair_correlations_give_every_pair_rho_and_keep_unit_variance(rho: float) -> None:
    mixed = structured_normal(
        (1, 3, 200, 200),
        torch.tensor(0.0),
        torch.tensor([rho, rho, rho]),
        torch.tensor([1.0, 1.0]),
        generator=torch.Generator().manual_seed(4),
        dtype=torch.float64,
    )[0]
    matrix = torch.corrcoef(mixed.reshape(3, -1))
    for i, j in ((0, 1), (0, 2), (1, 2)):
        assert abs(float(matrix[i, j]) - rho) < 0.02
    assert torch.allclose(mixed.reshape(3, -1).var(dim=1), torch.ones(3, dtype=torch.float64), atol=0.03)


def test_jpeg_quality_lowers_fine_scale_energy() -> None:
    clean = torch.full((1, 3, 128, 128), 0.5)
    noisy = add_noise(clean, NoiseValues.from_values({"read": 0.03}), generator=torch.Generator().manual_seed(6))[0]

    def fine_energy(image: torch.Tensor) -> float:
        return float((image[..., :, 1:] - image[..., :, :-1]).square().mean())

    energies = [fine_energy(jpeg_compress(noisy, q)) for q in (95, 75, 40)]
    assert fine_energy(noisy) > energies[0] > energies[1] > energies[2]
    compressed = jpeg_compress(noisy[None], 75)
    assert compressed.shape == (1, 3, 128, 128) and compressed.dtype == noisy.dtype
    assert torch.equal(compressed * 255, (compressed * 255).round())


def test_structured_compressed_noise_is_reproducible_and_8bit() -> None:
    clean = torch.rand((1, 3, 40, 32), generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    values = NoiseValues.from_values(
        {
            "shot": 0.03,
            "read": 0.01,
            "correlation_length": 0.8,
            "channel_correlation": [0.4, 0.3, 0.5],
            "compression": 0.3,
        }
    )
    first = add_noise(clean, values, generator=torch.Generator().manual_seed(9))
    second = add_noise(clean, values, generator=torch.Generator().manual_seed(9))
    assert torch.equal(first, second)
    assert torch.equal(first * 255, (first * 255).round())
    assert not torch.equal(first, add_noise(clean, values, generator=torch.Generator().manual_seed(10)))
