"""Synthetic training examples: clean clips -> darkened -> noisy 8-bit, with the v that made them."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from darksynth.darkening import darken
from darksynth.io.arrays import to_8bit_levels
from darksynth.noise.components import NOISE_COMPONENTS, values_to_vector
from darksynth.noise.sampling import random_darkening_values, random_noise_values
from darksynth.noise.simulate import add_noise


@dataclass
class TrainingBatch:
    """Network input, its targets, and the darkening used."""

    noisy: torch.Tensor  # (B, T, C, H, W), 8-bit levels / 255, as a real reference arrives
    dark: torch.Tensor  # (B, T, C, H, W), the darkened clean clips
    vector: torch.Tensor  # (B, NOISE_VECTOR_SIZE), the true v


def synthesize_batch(
    clean: torch.Tensor, *, generator: torch.Generator | None = None, absent_probability: float = 0.15
) -> TrainingBatch:
    """Darken clean clips with alpha, gamma from the paper's ranges, add f(v) with v from the training ranges.

    Each component is switched off for a clip with probability ``absent_probability``, so the network also
    learns what the absence of a component looks like (real references rarely show all five).
    """
    batch = clean.shape[0]
    alpha, gamma = random_darkening_values(batch_shape=(batch,), generator=generator, device=clean.device)
    dark = darken(clean, alpha, gamma)
    noisy, values = random_noisy_version(dark, generator=generator, absent_probability=absent_probability)
    return TrainingBatch(noisy=noisy, dark=dark, vector=values_to_vector(values))


def random_noisy_version(
    dark: torch.Tensor, *, generator: torch.Generator | None = None, absent_probability: float = 0.15
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Dark clips (B, T, C, H, W) made noisy with v drawn from the training ranges, on 8-bit levels.

    Each component is switched off for a clip with probability ``absent_probability``.

    Returns:
        The noisy clips and the values drawn, each (B, size) by parameter name.
    """
    batch = dark.shape[0]
    values = random_noise_values(batch_shape=(batch,), generator=generator, device=dark.device)
    for component in NOISE_COMPONENTS:
        present = torch.rand(batch, 1, generator=generator, device=dark.device) >= absent_probability
        for parameter in component.parameters:
            values[parameter.name] = values[parameter.name] * present
    return to_8bit_levels(add_noise(dark, values, generator=generator)), values
