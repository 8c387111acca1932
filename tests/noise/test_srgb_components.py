"""The sRGB model's components in the parameter table: statistics of what they draw, with fixed seeds.

Per-channel gains, spatial correlation and channel correlations shape the heteroscedastic noise; compression
is an output stage. Each is checked for the law it promises (variance per channel, autocorrelation, channel
correlation, 8-bit JPEG output), at two image sizes where size could matter, and through both the composer
and the frame-by-frame synthesizer that ``apply`` uses.
"""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.light.darkening import Darkening
from darksynth.noise.correlated import (
    jpeg_compress,
    jpeg_compress_clips,
    jpeg_quality,
    kernel_autocorrelation,
    structured_normal,
    valid_channel_correlation,
)
from darksynth.noise.heteroscedastic import heteroscedastic_noise
from darksynth.noise.simulate import add_noise, noise_sum
from darksynth.noise.values import NoiseValues
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer


def _values(**set_values: float | list[float]) -> NoiseValues:
    return NoiseValues.from_values(set_values, dtype=torch.float32)


def _lag_correlation(noise: torch.Tensor, lag: int) -> float:
    """Autocorrelation along x at ``lag`` of (..., H, W) zero-mean noise."""
    product = noise[..., :-lag] * noise[..., lag:]
    return float(product.mean() / noise.square().mean())


def _channel_correlations(noise: torch.Tensor) -> list[float]:
    """Red-green, green-blue, red-blue correlation of (..., 3, H, W) noise."""
    flat = noise.transpose(0, -3).reshape(3, -1).double()
    matrix = torch.corrcoef(flat)
    return [float(matrix[0, 1]), float(matrix[1, 2]), float(matrix[0, 2])]


@pytest.mark.parametrize("size", [128, 256])
def test_structured_noise_has_the_gains_correlations_and_length_asked_for(size: int) -> None:
    length, pairs, gains = 0.9, [0.5, 0.3, 0.6], [1.4, 0.8]
    noise = structured_normal(
        (2, 2, 3, size, size),
        torch.tensor([length, length]),
        torch.tensor([pairs, pairs]),
        torch.tensor([gains, gains]),
        generator=torch.Generator().manual_seed(0),
        dtype=torch.float64,
    )
    n = 4 * size * size  # values per channel
    # Variance per channel is the gain squared (green is the reference, gain 1). The values are correlated
    # over about (2.5 l)^2 pixels, so the effective count is n / 5; 5 standard errors of the variance.
    variances = noise.transpose(0, 2).reshape(3, -1).var(dim=1).tolist()
    tolerance = 5 * math.sqrt(2 / (n / 5))
    for variance, gain in zip(variances, [gains[0], 1.0, gains[1]], strict=True):
        assert abs(variance / gain**2 - 1.0) < tolerance, variances
    # Channel correlations as asked; the gains scale each channel and leave them unchanged.
    for measured, expected in zip(_channel_correlations(noise), pairs, strict=True):
        assert abs(measured - expected) < 0.03
    # Spatial autocorrelation follows the kernel's theory at lags 1 and 2, whatever the image size.
    for lag in (1, 2):
        assert abs(_lag_correlation(noise, lag) - kernel_autocorrelation(length, lag)) < 0.03


def test_each_clip_of_a_batch_gets_its_own_structure() -> None:
    noise = structured_normal(
        (2, 1, 3, 192, 192),
        torch.tensor([0.0, 1.5]),
        torch.tensor([[0.0, 0.0, 0.0], [0.7, 0.7, 0.7]]),
        torch.tensor([[1.0, 1.0], [1.0, 1.0]]),
        generator=torch.Generator().manual_seed(1),
        dtype=torch.float64,
    )
    assert abs(_lag_correlation(noise[0], 1)) < 0.02
    assert _lag_correlation(noise[1], 1) > 0.75
    assert max(abs(c) for c in _channel_correlations(noise[0])) < 0.03
    assert min(_channel_correlations(noise[1])) > 0.65


def test_grey_clips_get_the_spatial_correlation_only() -> None:
    noise = structured_normal(
        (1, 1, 1, 192, 192),
        torch.tensor([1.0]),
        torch.tensor([[0.5, 0.5, 0.5]]),
        torch.tensor([[2.0, 2.0]]),
        generator=torch.Generator().manual_seed(2),
        dtype=torch.float64,
    )
    assert abs(float(noise.var()) - 1.0) < 0.1
    assert abs(_lag_correlation(noise, 1) - kernel_autocorrelation(1.0, 1)) < 0.03


def test_inconsistent_channel_correlations_are_made_valid() -> None:
    consistent = valid_channel_correlation([0.5, 0.3, 0.6])
    assert consistent[0, 1] == 0.5 and consistent[1, 2] == 0.3 and consistent[0, 2] == 0.6
    # Red-green and green-blue strongly positive but red-blue strongly negative cannot all hold.
    repaired = valid_channel_correlation([0.9, 0.9, -0.45])
    assert torch.allclose(repaired.diagonal(), torch.ones(3, dtype=torch.float64))
    assert float(torch.linalg.eigvalsh(repaired).min()) > 0
    torch.linalg.cholesky(repaired)


def test_heteroscedastic_variance_law_holds_per_channel_with_structure() -> None:
    """var = gain_c^2 (shot^2 x + read^2) on flat fields at three levels, correlated noise included."""
    shot, read, gains = 0.1, 0.02, [1.5, 0.7]
    values = _values(shot=shot, read=read, channel_gain=gains, correlation_length=0.8, channel_correlation=[0.4] * 3)
    for level in (0.05, 0.2, 0.5):
        signal = torch.full((4, 3, 160, 160), level, dtype=torch.float64)
        noise = noise_sum(signal, values, generator=torch.Generator().manual_seed(3))
        for channel, gain in enumerate([gains[0], 1.0, gains[1]]):
            expected = gain**2 * (shot**2 * level + read**2)
            measured = float(noise[:, channel].var())
            # About 4 * 160^2 / 5 effective values; 5 standard errors of a variance.
            assert abs(measured / expected - 1.0) < 5 * math.sqrt(2 / (4 * 160 * 160 / 5)), (level, channel)


def test_neutral_structure_draws_exactly_the_papers_white_noise() -> None:
    signal = torch.rand(2, 3, 40, 56, generator=torch.Generator().manual_seed(4)) * 0.3
    white = heteroscedastic_noise(signal[None], 0.06, 0.012, generator=torch.Generator().manual_seed(5))[0]
    neutral = noise_sum(signal, _values(shot=0.06, read=0.012), generator=torch.Generator().manual_seed(5))
    assert torch.equal(white, neutral)


def test_jpeg_strength_maps_to_quality_and_zero_means_none() -> None:
    assert jpeg_quality(0.0) is None
    assert jpeg_quality(0.3) == 70
    assert jpeg_quality(0.95) == 5
    assert jpeg_quality(0.001) == 100


def test_compression_stage_compresses_each_clip_at_its_strength() -> None:
    generator = torch.Generator().manual_seed(6)
    clips = (0.3 + 0.05 * torch.randn(3, 2, 3, 48, 64, generator=generator)).clamp(0, 1)
    clips = (clips * 255).round() / 255
    out = jpeg_compress_clips(clips, torch.tensor([0.0, 0.3, 0.6]))
    assert torch.equal(out[0], clips[0])
    assert torch.equal(out[1], jpeg_compress(clips[1], 70))
    assert torch.equal(out[2], jpeg_compress(clips[2], 40))
    # Stronger compression removes more of the fine-scale noise energy.
    fine = [float((c[..., 1:] - c[..., :-1]).square().mean()) for c in out]
    assert fine[0] > fine[1] > fine[2]


def test_add_noise_with_compression_gives_8_bit_levels() -> None:
    signal = torch.full((1, 2, 3, 64, 64), 0.2)
    noisy = add_noise(signal, _values(read=0.03, compression=0.4), generator=torch.Generator().manual_seed(7))
    levels = noisy * 255
    assert torch.equal(levels, levels.round())
    white = add_noise(signal, _values(read=0.03), generator=torch.Generator().manual_seed(7))
    assert not torch.equal(noisy, (white * 255).round() / 255)


@pytest.mark.parametrize("dtype", [torch.uint8, torch.float32])
def test_streaming_synthesizer_draws_the_structure(dtype: torch.dtype) -> None:
    """apply's frame-by-frame path (8-bit and float) gives correlated, per-channel, compressed noise."""
    noise = NoiseValues.from_values(
        {"read": 0.04, "correlation_length": 1.2, "channel_gain": 1.5, "channel_correlation": 0.6}
    )
    synthesizer = ClipSynthesizer(
        ClipParameters(noise=noise, darkening=None), generator=torch.Generator().manual_seed(8)
    )
    level = 0.3
    frame = torch.full((3, 192, 192), level)
    frame = (frame * 255).round().to(torch.uint8) if dtype == torch.uint8 else frame
    scale = 255.0 if dtype == torch.uint8 else 1.0
    outputs = torch.stack([synthesizer(frame) for _ in range(2)]).double() / scale
    assert synthesizer.parameters.noise.to_json()["correlation_length"] == 1.2
    residual = outputs - outputs.mean(dim=(-2, -1), keepdim=True)
    assert abs(_lag_correlation(residual, 1) - kernel_autocorrelation(1.2, 1)) < 0.05
    assert min(_channel_correlations(residual)) > 0.5
    red_over_green = float(residual[:, 0].std() / residual[:, 1].std())
    assert abs(red_over_green - 1.5) < 0.1
    # Compression on top: 8-bit levels, and a different image from the uncompressed one.
    noise = noise.replace(compression=0.5)
    compressed = ClipSynthesizer(
        ClipParameters(noise=noise, darkening=Darkening(0.5, 1.0)), generator=torch.Generator().manual_seed(8)
    )(frame)
    assert compressed.dtype == dtype
    if dtype != torch.uint8:
        assert torch.equal(compressed * 255, (compressed * 255).round())


def test_chroma_length_coarsens_colour_noise_and_keeps_the_channel_covariance() -> None:
    """Colour blotches over a finer grain: the non-principal components get the longer kernel; the per-pixel
    covariance G R G stays exact."""
    pairs, gains, length, chroma = [0.5, 0.4, 0.6], (1.3, 1.1), 0.5, 1.5
    shape = (1, 2, 3, 256, 256)
    generator = torch.Generator().manual_seed(21)
    noise = structured_normal(
        shape,
        torch.tensor([length]),
        torch.tensor([pairs]),
        torch.tensor([gains]),
        generator=generator,
        dtype=torch.float64,
        chroma_lengths=torch.tensor([chroma]),
    )[0]
    flat = noise.permute(1, 0, 2, 3).reshape(3, -1)
    scale = torch.tensor([gains[0], 1.0, gains[1]], dtype=torch.float64)
    expected = valid_channel_correlation(pairs) * scale[:, None] * scale[None, :]
    torch.testing.assert_close(torch.cov(flat), expected, atol=0.03, rtol=0.0)
    # Project on the principal components: the main one has the brightness length, the others the longer one.
    _, vectors = torch.linalg.eigh(expected)
    components = torch.einsum("ji,tjhw->tihw", vectors, noise)
    colour, brightness = components[:, :2], components[:, 2:]
    assert abs(_lag_correlation(brightness, 1) - kernel_autocorrelation(length, 1)) < 0.03
    longer = math.sqrt(length**2 + chroma**2)
    assert abs(_lag_correlation(colour, 1) - kernel_autocorrelation(longer, 1)) < 0.03
    assert _lag_correlation(colour, 1) > _lag_correlation(brightness, 1) + 0.2


def test_chroma_length_zero_draws_exactly_the_previous_structure() -> None:
    args = (torch.tensor([0.8]), torch.tensor([[0.3, 0.2, 0.5]]), torch.tensor([[1.2, 0.9]]))
    shape = (1, 1, 3, 40, 48)
    before = structured_normal(shape, *args, generator=torch.Generator().manual_seed(3))
    after = structured_normal(shape, *args, generator=torch.Generator().manual_seed(3), chroma_lengths=torch.zeros(1))
    assert torch.equal(before, after)
