"""Signal-dependent (shot) plus signal-independent (read) Gaussian noise."""

from __future__ import annotations

import torch

from darksynth.tensors import per_clip


def heteroscedastic_variance(
    signal: torch.Tensor, shot: torch.Tensor | float, read: torch.Tensor | float
) -> torch.Tensor:
    """Variance of the heteroscedastic noise at each pixel: shot^2 * x + read^2 (arguments as
    :func:`heteroscedastic_std`)."""
    shot_t = per_clip(shot, signal, device=signal.device)
    read_t = per_clip(read, signal, device=signal.device)
    # The variance, not the standard deviation, is linear in x (Poisson photon counts); negative inputs
    # would make it undefined, so the signal is clamped at black.
    return shot_t.square() * signal.clamp_min(0.0) + read_t.square()


def heteroscedastic_std(signal: torch.Tensor, shot: torch.Tensor | float, read: torch.Tensor | float) -> torch.Tensor:
    """Standard deviation of the heteroscedastic noise at each pixel: sqrt(shot^2 * x + read^2).

    Args:
        signal: darkened clean clip x, (*batch, T, C, H, W), values in [0, 1].
        shot: shot-noise level (a number or one value per clip); the variance grows as shot^2 * x.
        read: read-noise standard deviation (a number or one value per clip).

    Returns:
        The per-pixel standard deviation, shaped like ``signal``.

    References:
        Foi, Trimeche, Katkovnik, Egiazarian 2008, Practical Poissonian-Gaussian noise modeling and fitting
        for single-image raw-data.
    """
    return torch.sqrt(heteroscedastic_variance(signal, shot, read))


def heteroscedastic_noise(
    signal: torch.Tensor,
    shot: torch.Tensor | float,
    read: torch.Tensor | float,
    *,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """Draw n ~ N(0, shot^2 * x + read^2) independently at every pixel.

    Args:
        signal: darkened clean clip x, (*batch, T, C, H, W), values in [0, 1].
        shot: shot-noise level (a number or one value per clip).
        read: read-noise standard deviation (a number or one value per clip).
        generator: source of randomness; the global generator when None.

    Returns:
        Noise shaped like ``signal``.
    """
    standard = torch.randn(signal.shape, generator=generator, device=signal.device, dtype=signal.dtype)
    return heteroscedastic_std(signal, shot, read) * standard
