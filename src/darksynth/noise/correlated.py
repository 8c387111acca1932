"""sRGB noise structure beyond the paper's white model: per-channel gains, spatial and cross-channel
correlation, JPEG compression; the functions the table's components (:mod:`darksynth.noise.components`) draw
with.

Real sRGB noise (docs/results.md, docs/srgb-noise.md) is not white: demosaicing, in-camera denoising and JPEG
spread each pixel's noise over its neighbours (its std is up to 1.8x what neighbouring-pixel differences see)
and across the colour channels (correlation 0.2-0.7, different per pair). The functions here shape unit
noise; the heteroscedastic component scales it by its std. All are pure: randomness only from an explicit
``torch.Generator``; images and noise are float tensors on the [0, 1] scale, of any size; parameters are in
pixels or dimensionless, so they do not depend on the image size.

Equations (``z`` white standard normal, ``x`` the clean image, ``c`` the channel; the table's parameters in
brackets):

* spatial correlation: ``z' = (k * k^T * z) / sum k^2``, ``k`` a normalised Gaussian of std ``l`` pixels
  (``correlation_length``) along x and along y; ``var z' = 1`` exactly, and the autocorrelation at lag ``d``
  is ``sum_i k[i] k[i + d] / sum_i k[i]^2`` (about ``exp(-d^2 / (4 l^2))``);
* cross-channel correlation and gains: ``z'' = G L z'`` over the channel axis, ``L L^T = R``, ``R`` with ones
  on the diagonal and the red-green, green-blue, red-blue coefficients (``channel_correlation``) elsewhere,
  ``G = diag(g_r, 1, g_b)`` (``channel_gain``);
* noisy image: ``y = Q_q(x + sqrt(shot^2 x + read^2) z'')``, ``Q_q`` Pillow's 8-bit JPEG encoder at quality
  ``q = round(100 (1 - c))`` (``compression`` c; none for c = 0).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence

import numpy as np
import torch
from PIL import Image

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


def filter_valid(noise: torch.Tensor, kernel: torch.Tensor) -> torch.Tensor:
    """Separable 'valid' convolution by a symmetric 1-D ``kernel`` along x and along y over the last two axes of
    (..., H, W): (..., H - K + 1, W - K + 1).

    Written as a sum of shifted slices, each multiplied by its tap: for these short kernels (3-17 taps) it is
    10-20x faster on a CPU than ``conv2d`` with one input channel (275 ms against 12 ms for a 1080p RGB frame and
    5 taps, benchmarks/bench_apply.py's machine), with the same result to the bit there.
    """
    taps = [float(t) for t in kernel.tolist()]
    width = noise.shape[-1] - len(taps) + 1
    along_x = noise[..., :, :width] * taps[0]
    for offset, tap in enumerate(taps[1:], start=1):
        along_x.add_(noise[..., :, offset : offset + width], alpha=tap)
    height = along_x.shape[-2] - len(taps) + 1
    both = along_x[..., :height, :] * taps[0]
    for offset, tap in enumerate(taps[1:], start=1):
        both.add_(along_x[..., offset : offset + height, :], alpha=tap)
    return both


def correlated_normal(
    shape: Sequence[int],
    generator: torch.Generator,
    correlation_length: float,
    *,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str = "cpu",
) -> torch.Tensor:
    """Unit-variance Gaussian noise of ``shape`` (..., H, W), spatially correlated by a Gaussian kernel.

    White noise is drawn with a margin of the kernel radius on each side and filtered without padding, so
    the result is stationary up to the borders and its per-pixel variance is exactly 1 (the filtered noise is
    divided by ``sum k^2``). ``correlation_length`` is the kernel's std in pixels, the same along x and y
    (the table's ``correlation_length``); a length of 0 gives white noise.
    """
    kernel = gaussian_kernel1d(correlation_length, dtype=dtype, device=device)
    *lead, height, width = shape
    padded = (*lead, height + kernel.numel() - 1, width + kernel.numel() - 1)
    white = torch.randn(padded, generator=generator, dtype=dtype, device=device)
    if kernel.numel() == 1:
        return white
    energy = kernel.square().sum()
    # sqrt(sum k_x^2 sum k_y^2) with k_x = k_y, written as before the lengths were tied so that a seed draws
    # bit-identical noise across versions.
    return filter_valid(white, kernel) / (energy * energy).sqrt()


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
    chroma_lengths: torch.Tensor | None = None,
) -> torch.Tensor:
    """Zero-mean Gaussian noise for clips ``shape`` (*batch, T, C, H, W) with the sRGB structure of each clip.

    Per clip: spatially correlated by a Gaussian kernel of std ``lengths`` px (variance kept at 1, see
    :func:`correlated_normal`), then, for colour clips (C = 3), mixed across channels so that red-green,
    green-blue and red-blue have the ``correlations`` (*batch, 3) and scaled by ``gains`` (*batch, 2): the std
    of red and of blue relative to green. Grey clips get the spatial correlation only. Drawn on the
    generator's device (the global generator's when None).

    ``chroma_lengths`` (*batch,): where above 0, the colour noise is coarser than its brightness noise, as
    in-camera chroma denoising and 4:2:0 subsampling make it. The channel covariance S = G R G is split into its
    principal components (S = V diag(lambda) V^T); the main one (brightness-like for positively correlated
    channels) is drawn with the kernel of ``lengths``, the other two (colour) with a kernel of std
    sqrt(length^2 + chroma_length^2), each at unit variance, and mixed by V diag(sqrt(lambda)): the per-pixel
    covariance stays exactly S. At 0 the draw is the one above, bit for bit.
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
    flat_chroma = (
        [0.0] * len(flat_lengths)
        if chroma_lengths is None
        else (chroma_lengths.expand(batch).reshape(-1).tolist() if batch else [float(chroma_lengths)])
    )
    clips = []
    for length, pairs, (red, blue), chroma in zip(
        flat_lengths, flat_correlations, flat_gains, flat_chroma, strict=True
    ):
        lengths_of_components, mixing = unit_noise_factors(channels, length, chroma, pairs, (red, blue))
        if channels == 3 and chroma > 0.0:
            clips.append(_luma_chroma_normal(frame_shape, generator, lengths_of_components, mixing, dtype))
            continue
        unit = correlated_normal(frame_shape, generator, float(length), dtype=dtype, device=device)
        if channels == 3:
            unit = torch.einsum("ij,tjhw->tihw", mixing.to(device=device, dtype=dtype), unit)
        clips.append(unit)
    return torch.stack(clips).reshape(*batch, *frame_shape)


def unit_noise_factors(
    channels: int, length: float, chroma: float, pairs: Sequence[float], gains: tuple[float, float]
) -> tuple[list[float], torch.Tensor]:
    """How :func:`structured_normal` makes one clip's unit noise: the kernel length of each of its independent
    unit-variance components, and the (C, N) float64 matrix that mixes the N components into the C channels.

    Grey: one component of ``length``, mixing [[1]]. Colour without chroma length: three components of
    ``length``, mixed by the Cholesky factor of the channel correlation scaled by the gains. Colour with a chroma
    length: the principal components of the channel covariance S = G R G, the two colour ones first with the
    kernel of std sqrt(length^2 + chroma^2), the main one last with ``length``, mixed by V diag(sqrt(lambda)).
    In every case the mixing M gives the per-pixel channel covariance M M^T = S. The fused sRGB kernel
    (:mod:`darksynth.noise.kernel8`) draws the same components from the same factors.
    """
    if channels != 3:
        return [float(length)], torch.ones(1, 1, dtype=torch.float64)
    scale = torch.tensor([gains[0], 1.0, gains[1]], dtype=torch.float64)
    if chroma <= 0.0:
        factor = torch.linalg.cholesky(valid_channel_correlation(pairs))
        return [float(length)] * 3, factor * scale[:, None]
    covariance = valid_channel_correlation(pairs) * scale[:, None] * scale[None, :]
    eigenvalues, eigenvectors = torch.linalg.eigh(covariance)  # ascending: the main component is the last
    colour_length = math.sqrt(length**2 + chroma**2)
    return [colour_length, colour_length, float(length)], eigenvectors * eigenvalues.clamp_min(0.0).sqrt()[None, :]


def normalised_taps(lengths: Sequence[float], *, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """(N, K) taps, one row per component: :func:`gaussian_kernel1d` of each length divided by the square root of
    its energy (so that filtering white noise along x and y keeps its variance at 1), zero-padded on both sides
    to the longest kernel."""
    kernels = [gaussian_kernel1d(length) for length in lengths]
    size = max(kernel.numel() for kernel in kernels)
    taps = torch.zeros(len(kernels), size, dtype=torch.float64)
    for row, kernel in enumerate(kernels):
        margin = (size - kernel.numel()) // 2
        taps[row, margin : margin + kernel.numel()] = kernel / kernel.square().sum().sqrt()
    return taps.to(dtype)


def _luma_chroma_normal(
    frame_shape: tuple[int, ...],
    generator: torch.Generator,
    lengths: Sequence[float],
    mixing: torch.Tensor,
    dtype: torch.dtype,
) -> torch.Tensor:
    """One clip (T, 3, H, W) of :func:`structured_normal` with coarser colour noise (see there), from its
    :func:`unit_noise_factors`."""
    device = generator.device
    frames, _, height, width = frame_shape
    colour = correlated_normal((frames, 2, height, width), generator, lengths[0], dtype=dtype, device=device)
    brightness = correlated_normal((frames, 1, height, width), generator, lengths[2], dtype=dtype, device=device)
    components = torch.cat([colour, brightness], dim=1)
    return torch.einsum("ij,tjhw->tihw", mixing.to(device=device, dtype=dtype), components)
