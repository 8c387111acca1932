"""Physically motivated darkening of a clean image: x_d = alpha * x ** (1 / gamma)."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from darksynth.tensors import per_clip

ALPHA_RANGE: tuple[float, float] = (0.05, 0.3)
"""The paper's training range of the exposure scale alpha."""

GAMMA_RANGE: tuple[float, float] = (0.1, 1.0)
"""The paper's training range of gamma; the exponent 1 / gamma lies in [1, 10]."""


@dataclass(frozen=True)
class Darkening:
    """Exposure scale ``alpha`` in (0, 1] and tone exponent ``gamma`` > 0 of x_d = alpha * x ** (1 / gamma)."""

    alpha: float
    gamma: float


def darken(clean: torch.Tensor, alpha: torch.Tensor | float, gamma: torch.Tensor | float) -> torch.Tensor:
    """Darken a clean clip.

    Args:
        clean: clean clip (*batch, T, C, H, W), values in [0, 1].
        alpha: exposure scale (a number or one value per clip); the paper draws it from [0.05, 0.3].
        gamma: tone exponent (a number or one value per clip); the paper draws it from [0.1, 1].

    Returns:
        The darkened clip, values in [0, alpha].

    References:
        Lin, Morris et al. 2025, Towards a general-purpose zero-shot synthetic low-light image and video
        pipeline (after Lore et al. 2017 and Lv et al. 2021).
    """
    alpha_t = per_clip(alpha, clean, device=clean.device)
    gamma_t = per_clip(gamma, clean, device=clean.device)
    return alpha_t * clean.clamp(0.0, 1.0).pow(1.0 / gamma_t)
