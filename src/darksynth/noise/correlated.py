"""sRGB noise components beyond the paper's white model: per-channel gains, spatial and cross-channel
correlation, JPEG compression.

Real sRGB noise (docs/results.md, docs/srgb-noise.md) is not white: demosaicing, in-camera denoising and JPEG
spread each pixel's noise over its neighbours (its std is up to 1.8x what neighbouring-pixel differences see)
and across the colour channels (correlation 0.3-0.66). The functions here model that on top of a heteroscedastic
(Poisson-Gaussian) law. All are pure: randomness only from an explicit ``torch.Generator``; images and noise
are float tensors ``(..., C, H, W)`` on the [0, 1] scale, of any size and on any device; parameters are in
pixels or dimensionless, so they do not depend on the image size.

Equations (``z`` white standard normal, ``x`` the clean image, ``c`` the channel):

* per-channel heteroscedastic std: ``s_c(x) = g_c * sqrt(a_c x + b_c)`` (gains ``g_c``);
* spatial correlation: ``z' = (k_y * k_x * z) / sqrt(sum k_x^2 * sum k_y^2)``, ``k`` a normalised Gaussian of
  std ``correlation_length`` pixels (separate x and y lengths allowed); ``var z' = 1`` exactly, and the
  autocorrelation at lag ``d`` is ``sum_i k[i] k[i + d] / sum_i k[i]^2`` (about ``exp(-d^2 / (4 l^2))``);
* cross-channel correlation: ``z'' = L z'`` over the channel axis, ``L L^T = R``, ``R`` with ones on the
  diagonal and ``rho`` elsewhere (valid for ``-1/(C-1) < rho < 1``);
* noisy image: ``y = Q_q(x + s(x) z'')``, ``Q_q`` Pillow's 8-bit JPEG encoder at quality ``q`` (or just
  clipping and rounding to 8 bits when there is no compression).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

from darksynth.tensors import to_8bit_levels

KERNEL_RADIUS_STDS = 3.0
"""The Gaussian kernel is cut at this many standard deviations (at least one pixel each side)."""


def gaussian_kernel1d(
    length: float, *, dtype: torch.dtype = torch.float64, device: torch.device | str = "cpu"
) -> torch.Tensor:
    """Normalised (sum 1) 1-D Gaussian of std ``length`` pixels; ``[1.]`` for a length of zero (white noise)."""
    if length < 0.0 or not math.isfinite(length):
        raise ValueError(f"correlation length must be finite and >= 0, got {length}")
    if length == 0.0:
        return torch.ones(1, dtype=dtype, device=device)
    radius = max(1, math.ceil(KERNEL_RADIUS_STDS * length))
    offsets = torch.arange(-radius, radius + 1, dtype=dtype, device=device)
    kernel = torch.exp(-0.5 * (offsets / length) ** 2)
    return kernel / kernel.sum()


def kernel_autocorrelation(length: float, lag: int) -> float:
    """Theoretical autocorrelation at ``lag`` pixels of white noise filtered by :func:`gaussian_kernel1d`."""
    kernel = gaussian_kernel1d(length)
    if lag >= kernel.numel():
        return 0.0
    return float((kernel[: kernel.numel() - lag] * kernel[lag:]).sum() / kernel.square().sum())


def _filter_valid(noise: torch.Tensor, kernel_x: torch.Tensor, kernel_y: torch.Tensor) -> torch.Tensor:
    """Separable 'valid' convolution over the last two axes of (..., H, W)."""
    shape = noise.shape
    flat = noise.reshape(-1, 1, shape[-2], shape[-1])
    flat = F.conv2d(flat, kernel_x.view(1, 1, 1, -1))
    flat = F.conv2d(flat, kernel_y.view(1, 1, -1, 1))
    return flat.reshape(*shape[:-2], flat.shape[-2], flat.shape[-1])


def correlated_normal(
    shape: Sequence[int],
    generator: torch.Generator,
    correlation_length: float,
    correlation_length_y: float | None = None,
    *,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str = "cpu",
) -> torch.Tensor:
    """Unit-variance Gaussian noise of ``shape`` (..., H, W), spatially correlated by a Gaussian kernel.

    White noise is drawn with a margin of the kernel radius on each side and filtered without padding, so
    the result is stationary up to the borders and its per-pixel variance is exactly 1 (the filtered noise is
    divided by ``sqrt(sum k_x^2 * sum k_y^2)``). ``correlation_length`` is the kernel's std in pixels along x,
    ``correlation_length_y`` along y (the same as x when None). Lengths of 0 give white noise.
    """
    length_y = correlation_length if correlation_length_y is None else correlation_length_y
    kernel_x = gaussian_kernel1d(correlation_length, dtype=dtype, device=device)
    kernel_y = gaussian_kernel1d(length_y, dtype=dtype, device=device)
    *lead, height, width = shape
    padded = (*lead, height + kernel_y.numel() - 1, width + kernel_x.numel() - 1)
    white = torch.randn(padded, generator=generator, dtype=dtype, device=device)
    if kernel_x.numel() == 1 and kernel_y.numel() == 1:
        return white
    scale = (kernel_x.square().sum() * kernel_y.square().sum()).sqrt()
    return _filter_valid(white, kernel_x, kernel_y) / scale


def channel_correlation_matrix(rho: float, channels: int = 3) -> torch.Tensor:
    """The (C, C) correlation matrix with ones on the diagonal and ``rho`` elsewhere (float64)."""
    if not -1.0 / (channels - 1) < rho < 1.0:
        raise ValueError(f"rho must lie in (-1/{channels - 1}, 1) for a valid correlation matrix, got {rho}")
    return torch.full((channels, channels), rho, dtype=torch.float64).fill_diagonal_(1.0)


def mix_channels(noise: torch.Tensor, rho: float) -> torch.Tensor:
    """Correlate the channels (axis -3) of unit-variance, channel-independent noise: ``L z`` with
    ``L L^T = R(rho)``. Each channel keeps variance 1 and every pair of channels gets correlation ``rho``."""
    if rho == 0.0:
        return noise
    channels = noise.shape[-3]
    factor = torch.linalg.cholesky(channel_correlation_matrix(rho, channels)).to(noise.dtype).to(noise.device)
    return torch.einsum("ij,...jhw->...ihw", factor, noise)


def heteroscedastic_std(
    clean: torch.Tensor, a: Sequence[float], b: Sequence[float], gains: Sequence[float] | None = None
) -> torch.Tensor:
    """Per-pixel std ``g_c sqrt(a_c x + b_c)`` of a per-channel Poisson-Gaussian law with per-channel gains."""
    channels = clean.shape[-3]

    def column(values: Sequence[float]) -> torch.Tensor:
        if len(values) != channels:
            raise ValueError(f"expected {channels} per-channel values, got {len(values)}")
        return torch.tensor(list(values), dtype=clean.dtype, device=clean.device).view(channels, 1, 1)

    std = (column(a) * clean.clamp_min(0.0) + column(b)).clamp_min(0.0).sqrt()
    return std if gains is None else std * column(gains)


def apply_channel_gains(noise: torch.Tensor, gains: Sequence[float]) -> torch.Tensor:
    """Scale each channel (axis -3) of a noise map by its gain."""
    channels = noise.shape[-3]
    if len(gains) != channels:
        raise ValueError(f"expected {channels} gains, got {len(gains)}")
    return noise * torch.tensor(list(gains), dtype=noise.dtype, device=noise.device).view(channels, 1, 1)


def jpeg_compress(image: torch.Tensor, quality: int) -> torch.Tensor:
    """Encode and decode (..., C, H, W) [0, 1] images, C = 3 (colour) or 1 (grey), with Pillow's JPEG encoder
    at ``quality`` (1-100, in memory; Pillow's default 4:2:0 chroma subsampling). The result lies on 8-bit
    levels, with the input's dtype and device. Not differentiable: the image goes through numpy and uint8."""
    if not 1 <= quality <= 100:
        raise ValueError(f"JPEG quality must be in 1..100, got {quality}")
    channels = image.shape[-3]
    if channels not in (1, 3):
        raise ValueError(f"JPEG compression needs 3 or 1 channels, got {channels}")
    mode = "RGB" if channels == 3 else "L"
    pixels = (image.detach().clamp(0.0, 1.0) * 255.0).round().to(torch.uint8).cpu()
    flat = pixels.reshape(-1, *pixels.shape[-3:])
    decoded = []
    for single in flat:
        buffer = io.BytesIO()
        array = single.permute(1, 2, 0).numpy()
        Image.fromarray(array if channels == 3 else array[..., 0], mode=mode).save(
            buffer, format="JPEG", quality=quality
        )
        buffer.seek(0)
        array = np.asarray(Image.open(buffer).convert(mode), dtype=np.uint8).reshape(array.shape)
        decoded.append(torch.from_numpy(array.copy()).permute(2, 0, 1))
    out = torch.stack(decoded).reshape(pixels.shape)
    return out.to(device=image.device, dtype=image.dtype) / 255.0


def correlated_noise(
    clean: torch.Tensor,
    generator: torch.Generator,
    *,
    a: Sequence[float],
    b: Sequence[float],
    gains: Sequence[float] | None = None,
    correlation_length: float = 0.0,
    correlation_length_y: float | None = None,
    rho: float = 0.0,
) -> torch.Tensor:
    """The noise map ``s(x) * L (k * z)``: heteroscedastic, spatially and chromatically correlated."""
    unit = correlated_normal(
        clean.shape,
        generator,
        correlation_length,
        correlation_length_y,
        dtype=clean.dtype,
        device=clean.device,
    )
    return heteroscedastic_std(clean, a, b, gains) * mix_channels(unit, rho)


def add_correlated_noise(
    clean: torch.Tensor,
    generator: torch.Generator,
    *,
    a: Sequence[float],
    b: Sequence[float],
    gains: Sequence[float] | None = None,
    correlation_length: float = 0.0,
    correlation_length_y: float | None = None,
    rho: float = 0.0,
    jpeg_quality: int | None = None,
) -> torch.Tensor:
    """``Q_q(x + noise)``: the extended sRGB model's noisy image on 8-bit levels (JPEG when a quality is given;
    then not differentiable)."""
    noisy = clean + correlated_noise(
        clean,
        generator,
        a=a,
        b=b,
        gains=gains,
        correlation_length=correlation_length,
        correlation_length_y=correlation_length_y,
        rho=rho,
    )
    if jpeg_quality is not None:
        return jpeg_compress(noisy, jpeg_quality)
    return to_8bit_levels(noisy)


def jpeg_quality(compression: float) -> int | None:
    """The JPEG quality of a compression strength c in [0, 1): round(100 (1 - c)), None (no JPEG) for c = 0."""
    if compression <= 0.0:
        return None
    return max(1, min(100, round(100.0 * (1.0 - compression))))


def jpeg_compress_clips(clips: torch.Tensor, compression: torch.Tensor) -> torch.Tensor:
    """JPEG-compress every frame of clips (*batch, T, C, H, W) in [0, 1], each clip at its own strength
    (``compression`` shaped like the batch, see :func:`jpeg_quality`); clips of strength 0 pass unchanged."""
    batch = clips.shape[: clips.dim() - 4]
    flat = clips.reshape(-1, *clips.shape[-4:])
    strengths = compression.expand(batch).reshape(-1).tolist() if batch else [float(compression)]
    out = [
        clip if jpeg_quality(c) is None else jpeg_compress(clip, jpeg_quality(c) or 100)
        for clip, c in zip(flat, strengths, strict=True)
    ]
    return torch.stack(out).reshape(clips.shape)


def valid_channel_correlation(pairs: Sequence[float]) -> torch.Tensor:
    """The (3, 3) correlation matrix of the red-green, green-blue and red-blue coefficients ``pairs``, made
    positive definite when the three are inconsistent (eigenvalues raised to 1e-3, diagonal rescaled to 1),
    float64. Consistent coefficients come back unchanged."""
    rg, gb, rb = (float(v) for v in pairs)
    matrix = torch.tensor([[1.0, rg, rb], [rg, 1.0, gb], [rb, gb, 1.0]], dtype=torch.float64)
    eigenvalues, eigenvectors = torch.linalg.eigh(matrix)
    if bool((eigenvalues >= 1e-3).all()):
        return matrix
    repaired: torch.Tensor = eigenvectors @ torch.diag(eigenvalues.clamp_min(1e-3)) @ eigenvectors.T
    scale = repaired.diagonal().rsqrt()
    return repaired * scale[:, None] * scale[None, :]


def structured_normal(
    shape: Sequence[int],
    lengths: torch.Tensor,
    correlations: torch.Tensor,
    gains: torch.Tensor,
    *,
    generator: torch.Generator | None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """Zero-mean Gaussian noise for clips ``shape`` (*batch, T, C, H, W) with the sRGB structure of each clip.

    Per clip: spatially correlated by a Gaussian kernel of std ``lengths`` px (variance kept at 1, see
    :func:`correlated_normal`), then, for colour clips (C = 3), mixed across channels so that red-green,
    green-blue and red-blue have the ``correlations`` (*batch, 3) and scaled by ``gains`` (*batch, 2): the std
    of red and of blue relative to green. Grey clips get the spatial correlation only. Drawn on the
    generator's device (the global generator's when None).
    """
    if generator is None:
        generator = torch.default_generator
    device = generator.device
    batch = tuple(shape[: len(shape) - 4])
    frame_shape = tuple(shape[-4:])
    channels = frame_shape[1]
    flat_lengths = lengths.expand(batch).reshape(-1).tolist() if batch else [float(lengths)]
    flat_correlations = correlations.expand(*batch, 3).reshape(-1, 3).tolist()
    flat_gains = gains.expand(*batch, 2).reshape(-1, 2).tolist()
    clips = []
    for length, pairs, (red, blue) in zip(flat_lengths, flat_correlations, flat_gains, strict=True):
        unit = correlated_normal(frame_shape, generator, float(length), dtype=dtype, device=device)
        if channels == 3:
            factor = torch.linalg.cholesky(valid_channel_correlation(pairs))
            factor = factor * torch.tensor([red, 1.0, blue], dtype=torch.float64)[:, None]
            unit = torch.einsum("ij,tjhw->tihw", factor.to(device=device, dtype=dtype), unit)
        clips.append(unit)
    return torch.stack(clips).reshape(*batch, *frame_shape)
