"""Clean scenes whose tones follow the clean-scene prior, made on the spot, and their noisy darkened versions:
the material of the darkening's round trips."""

from __future__ import annotations

import numpy as np
import torch

from darksynth.light.darkening import Darkening, darken
from darksynth.light.tone_fit import TONE_PRIOR_LOG_QUANTILES
from darksynth.light.tones import PROBABILITIES
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues


def prior_scene(seed: int, size: int = 192, shift: float = 0.0) -> torch.Tensor:
    """(3, S, S) smooth random scene, constant over 4x4 blocks, whose block values follow the prior's tone
    distribution (shifted in log by ``shift``): a natural-like image made on the spot."""
    generator = torch.Generator().manual_seed(seed)
    coarse = torch.rand(1, 3, size // 16, size // 16, generator=generator)
    field = torch.nn.functional.interpolate(coarse, size=(size // 4, size // 4), mode="bicubic", align_corners=False)
    ranks = field.flatten().argsort().argsort().double() / (field.numel() - 1)
    levels = np.concatenate([[0.0], PROBABILITIES, [1.0]])
    tones = np.exp(np.concatenate([[np.log(1e-3)], np.asarray(TONE_PRIOR_LOG_QUANTILES) + shift, [0.0]]))
    values = torch.from_numpy(np.interp(ranks.numpy(), levels, np.clip(tones, 0.0, 1.0))).float()
    return values.reshape(field.shape)[0].repeat_interleave(4, dim=-2).repeat_interleave(4, dim=-1)


def noisy_8bit(clean: torch.Tensor, darkening: Darkening, read: float, seed: int) -> torch.Tensor:
    """``clean`` darkened, with Poisson-Gaussian noise (shot 0.02, ``read``) drawn from ``seed``, on 8-bit levels."""
    values = NoiseValues.from_values({"shot": 0.02, "read": read}, dtype=torch.float32)
    signal = darken(clean, darkening.alpha, darkening.gamma)[None]
    noisy = add_noise(signal, values, generator=torch.Generator().manual_seed(seed))[0]
    return (noisy * 255).round() / 255
