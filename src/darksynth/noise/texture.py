"""Noise that follows texture: the local detail of the signal and the factor it puts on the noise's std.

A camera's own processing (denoising, JPEG) flattens noise where the scene is flat and keeps it on texture: on the
polyu pairs the real noise's std is 0.68x the pooled std on flat 32-px blocks and 1.32x on textured ones. The
spectral model's level curve describes flat regions; on texture its std is multiplied by

    m(x) = (1 + d(x) / texture_scale) ** texture_gain,

``d(x)`` the local detail of the signal the noise is added to (the darkened clean frame) at the noise's scales:
the local RMS, over a Gaussian window of :data:`DETAIL_WINDOW_SIGMA` px, of the luminance (mean of the channels)
minus its Gaussian blur of :data:`DETAIL_BLUR_SIGMA` px. Every size is in pixels and fixed, so a crop and a 4K
frame of the same scene get the same factor per pixel; ``m = 1`` on a flat frame. The block measure the fit and the
evaluation read (:func:`block_detail`) is the RMS of the same high-pass over each block.

References: Lebrun, Colom and Morel 2015, "The Noise Clinic" (noise of JPEG images depends on the local content);
docs/spectral-noise.md.
"""

from __future__ import annotations

import functools
import math

import torch
import torch.nn.functional as F

DETAIL_BLUR_SIGMA = 1.5
"""Gaussian blur (px) whose difference to the luminance is the detail: periods under about 10 px, the scales of
the finest octaves, where the noise's power is and where denoisers tell texture from noise."""

DETAIL_WINDOW_SIGMA = 3.0
"""Gaussian window (px) of the detail's local RMS: a few pixels, so the factor follows a texture's outline
without flickering between a grating's crests and troughs."""

TEXTURE_BLOCK = 32
"""Side (px) of the blocks whose detail and noise std the fit and the evaluation compare."""

TEXTURE_SHARE = 0.30
"""The share of blocks, most and least textured, whose noise std the textured-to-flat ratio compares."""


@functools.lru_cache(maxsize=8)
def _gaussian_taps(sigma: float, device: torch.device, dtype: torch.dtype) -> torch.Tensor:
    radius = max(1, math.ceil(3.0 * sigma))
    offsets = torch.arange(-radius, radius + 1, dtype=torch.float64)
    taps = torch.exp(-0.5 * (offsets / sigma) ** 2)
    return (taps / taps.sum()).to(device, dtype)


def _blur(planes: torch.Tensor, sigma: float) -> torch.Tensor:
    """Separable Gaussian blur of (N, 1, H, W) planes, edges replicated (any frame size, even one of a few px)."""
    if planes.device.type == "cpu" and planes.dtype == torch.float32:
        return _blur_opencv(planes, sigma)
    taps = _gaussian_taps(sigma, planes.device, planes.dtype)
    radius = taps.numel() // 2
    height, width = planes.shape[-2:]
    # Weighted shifted views: torch's conv2d on a single channel takes a slow general path (10x slower here).
    padded = F.pad(planes, (radius, radius, 0, 0), mode="replicate")
    rows = sum(weight * padded[..., offset : offset + width] for offset, weight in enumerate(taps.tolist()))
    padded = F.pad(torch.as_tensor(rows), (0, 0, radius, radius), mode="replicate")
    blurred = sum(weight * padded[..., offset : offset + height, :] for offset, weight in enumerate(taps.tolist()))
    return torch.as_tensor(blurred)


def _blur_opencv(planes: torch.Tensor, sigma: float) -> torch.Tensor:
    """:func:`_blur` on the CPU by OpenCV's vectorised separable filter, the same taps: a 1080p frame's detail took
    140 ms as shifted sums, a textured frame 2.4x an untextured one's whole synthesis."""
    import cv2  # only this path needs it; importing it costs start-up time

    taps = _gaussian_taps(sigma, torch.device("cpu"), torch.float64).numpy()
    result = torch.empty_like(planes)
    for index in range(planes.shape[0]):
        plane = planes[index, 0].contiguous().numpy()
        result[index, 0] = torch.from_numpy(
            cv2.sepFilter2D(plane, cv2.CV_32F, taps, taps, borderType=cv2.BORDER_REPLICATE)
        )
    return result


def detail_highpass(signal: torch.Tensor) -> torch.Tensor:
    """The luminance (mean of the channels) of ``signal`` (..., C, H, W) minus its :data:`DETAIL_BLUR_SIGMA` blur,
    shaped (..., 1, H, W)."""
    luminance = signal.mean(dim=-3, keepdim=True)
    planes = luminance.reshape(-1, 1, *luminance.shape[-2:])
    return (planes - _blur(planes, DETAIL_BLUR_SIGMA)).reshape(luminance.shape)


def local_detail(signal: torch.Tensor) -> torch.Tensor:
    """``d(x)``: the local RMS over a :data:`DETAIL_WINDOW_SIGMA` Gaussian window of :func:`detail_highpass`,
    (..., 1, H, W) on the [0, 1] scale of ``signal`` (..., C, H, W)."""
    highpass = detail_highpass(signal)
    planes = highpass.square().reshape(-1, 1, *highpass.shape[-2:])
    return _blur(planes, DETAIL_WINDOW_SIGMA).clamp_min(0.0).sqrt().reshape(highpass.shape)


def texture_modulation(signal: torch.Tensor, gain: float, scale: float) -> torch.Tensor:
    """``m(x) = (1 + d(x) / scale) ** gain`` (..., 1, H, W) for ``signal`` (..., C, H, W): the factor on the noise's
    std; ``gain`` is ``texture_gain`` (>= 0), ``scale`` ``texture_scale`` (> 0, a detail level on [0, 1])."""
    return (1.0 + local_detail(signal) / scale).pow(gain)


def block_detail(signal: torch.Tensor, block: int = TEXTURE_BLOCK) -> torch.Tensor:
    """The RMS of :func:`detail_highpass` over each whole ``block``-px block of ``signal`` (..., C, H, W):
    (..., H // block, W // block), blocks in row-major order (the frame's last partial row and column left out)."""
    highpass = detail_highpass(signal)[..., 0, :, :]
    return block_mean(highpass.square(), block).sqrt()


def block_mean(planes: torch.Tensor, block: int = TEXTURE_BLOCK) -> torch.Tensor:
    """The mean of (..., H, W) over each whole ``block``-px block: (..., H // block, W // block)."""
    rows, columns = planes.shape[-2] // block, planes.shape[-1] // block
    cropped = planes[..., : rows * block, : columns * block]
    return cropped.reshape(*planes.shape[:-2], rows, block, columns, block).mean(dim=(-3, -1))


def textured_and_flat(detail: torch.Tensor, share: float = TEXTURE_SHARE) -> tuple[torch.Tensor, torch.Tensor]:
    """Boolean masks (like ``detail``, one value per block) of the ``share`` most and least textured blocks: at
    least one block each (the same block when there is only one)."""
    flat_detail = detail.flatten()
    count = max(1, round(share * flat_detail.numel()))
    order = torch.argsort(flat_detail, stable=True)
    textured = torch.zeros_like(flat_detail, dtype=torch.bool)
    flat = torch.zeros_like(flat_detail, dtype=torch.bool)
    textured[order[-count:]] = True
    flat[order[:count]] = True
    return textured.view(detail.shape), flat.view(detail.shape)
