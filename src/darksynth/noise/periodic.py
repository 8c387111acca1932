"""Periodic column noise built from three Fourier modes of the frame's columns."""

from __future__ import annotations

import math

import torch

from darksynth.tensors import CLIP_DIMS, check_clip_shape

# cos(pi * w / 2) and sin(pi * w / 2) at integer columns, exactly: the mode at W/4 cycles per frame width.
_QUARTER_COS = (1.0, 0.0, -1.0, 0.0)
_QUARTER_SIN = (0.0, 1.0, 0.0, -1.0)


def periodic_basis(width: int, *, device: torch.device | str | None = None) -> torch.Tensor:
    """The three column patterns of periodic noise, each with unit mean square over a period.

    Row 0 is the constant (column frequency 0). Rows 1 and 2 are sqrt(2) cos and -sqrt(2) sin of a wave of
    one cycle per 4 columns, which is column frequency W/4 and, as its complex conjugate, 3W/4 of a W-wide
    frame. In Fourier terms the frame's column spectrum is non-zero only at 0, W/4 and 3W/4, with the
    coefficient at W/4 equal to (a + i b) W / sqrt(2) and its conjugate at 3W/4, so the pattern is real.

    Args:
        width: number of columns W.
        device: device of the result.

    Returns:
        Tensor (3, W).
    """
    phase = torch.arange(width, device=device) % 4
    cos = torch.tensor(_QUARTER_COS, device=device)[phase]
    sin = torch.tensor(_QUARTER_SIN, device=device)[phase]
    return torch.stack([torch.ones(width, device=device), math.sqrt(2.0) * cos, -math.sqrt(2.0) * sin])


def periodic_noise(
    shape: torch.Size | tuple[int, ...],
    sigmas: torch.Tensor,
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Draw periodic column noise for every frame and channel.

    For each frame and channel, three standard normal coefficients g are drawn and the row pattern is
    ``sigma1 g1 + sigma2 g2 sqrt(2) cos(pi w / 2) - sigma3 g3 sqrt(2) sin(pi w / 2)``. Each term's
    mean square over columns is its sigma^2 whatever the frame size: the authors' code normalises an
    inverse FFT by the patch size, so its amplitude shrinks as patches grow, and takes the modulus, which
    rectifies the wave; neither is done here. The pattern is constant down the columns (vertical frequency
    0) and redrawn every frame.

    Args:
        shape: clip shape (*batch, T, C, H, W).
        sigmas: tensor (..., 3): the standard deviations (sigma_p1, sigma_p2, sigma_p3) of the modes at column
            frequencies 0, W/4 (cosine) and 3W/4 (sine), either shaped (3,) or (*batch, 3).
        generator: source of randomness; the global generator when None.
        device: device of the result.

    Returns:
        A row pattern shaped (*batch, T, C, 1, W).

    References:
        Monakhova, Richter, Waller, Fowlkes 2022, Dancing under the stars: video denoising in starlight.
    """
    check_clip_shape(shape)
    dev = torch.device(device) if device is not None else torch.device("cpu")
    *frames, _height, width = shape
    coefficients = torch.randn((*frames, 3), generator=generator, device=dev)
    sigmas = sigmas.to(device=dev, dtype=torch.float32)
    batch = tuple(shape[: len(shape) - CLIP_DIMS])
    if sigmas.dim() > 1:
        if tuple(sigmas.shape) != (*batch, 3):
            raise ValueError(f"periodic sigmas must be shaped (3,) or {(*batch, 3)}, got {tuple(sigmas.shape)}")
        # (*batch, 3) -> (*batch, 1, 1, 3) so that it meets the (T, C) dimensions of the coefficients.
        sigmas = sigmas.reshape(*batch, 1, 1, 3)
    return ((coefficients * sigmas) @ periodic_basis(width, device=dev)).unsqueeze(-2)
