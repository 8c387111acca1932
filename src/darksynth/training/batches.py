"""Synthetic training examples: clean clips -> darkened -> noisy 8-bit, with the v that made them."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from darksynth.light.darkening import darken
from darksynth.noise.components import NoiseModel, model_parameters, noise_components
from darksynth.noise.sampling import random_darkening_values, random_noise_values
from darksynth.noise.simulate import add_noise
from darksynth.noise.structure_translation import spectral_tensors
from darksynth.noise.values import NoiseValues, model_vector
from darksynth.tensors import to_8bit_levels

BRIGHT_ALPHA_RANGE = (0.3, 1.0)
BRIGHT_GAMMA_RANGE = (0.5, 1.0)
"""Darkening of the bright share of training clips: the real pairs' noisy images have mean levels of 0.3-0.4
(docs/results.md), above what the paper's alpha <= 0.3 produces."""


@dataclass
class TrainingBatch:
    """Network input, its targets, and the darkening used."""

    noisy: torch.Tensor  # (B, T, C, H, W), 8-bit levels / 255, as a real reference arrives
    dark: torch.Tensor  # (B, T, C, H, W), the darkened clean clips
    values: NoiseValues  # (B,): the true noise values (those outside the noise model neutral)
    noise_model: NoiseModel

    @property
    def vector(self) -> torch.Tensor:
        """The true v of the noise model, (B, vector_size(noise_model)): the network's target."""
        return model_vector(self.values, self.noise_model)


def synthesize_batch(
    clean: torch.Tensor,
    *,
    generator: torch.Generator | None = None,
    absent_probability: float = 0.15,
    noise_model: NoiseModel = "srgb",
    bright_fraction: float = 0.0,
    log_levels: bool = False,
) -> TrainingBatch:
    """Darken clean clips with alpha, gamma from the paper's ranges, add f(v) with v from the training ranges.

    Each component is switched off for a clip with probability ``absent_probability``, so the network also
    learns what the absence of a component looks like (real references rarely show all five). A
    ``bright_fraction`` of the clips is darkened less, alpha and gamma from :data:`BRIGHT_ALPHA_RANGE` and
    :data:`BRIGHT_GAMMA_RANGE`: real references are often brighter than the paper's ranges allow.
    ``log_levels`` draws the noise levels log-uniformly (see :func:`random_noise_values`).
    """
    batch = clean.shape[0]
    alpha, gamma = random_darkening_values(batch_shape=(batch,), generator=generator, device=clean.device)
    if bright_fraction > 0.0:
        bright_alpha, bright_gamma = random_darkening_values(
            BRIGHT_ALPHA_RANGE, BRIGHT_GAMMA_RANGE, (batch,), generator=generator, device=clean.device
        )
        bright = torch.rand(batch, generator=generator, device=clean.device) < bright_fraction
        alpha, gamma = torch.where(bright, bright_alpha, alpha), torch.where(bright, bright_gamma, gamma)
    dark = darken(clean, alpha, gamma)
    noisy, values = random_noisy_version(
        dark, generator=generator, absent_probability=absent_probability, noise_model=noise_model, log_levels=log_levels
    )
    return TrainingBatch(noisy=noisy, dark=dark, values=values, noise_model=noise_model)


def random_noisy_version(
    dark: torch.Tensor,
    *,
    generator: torch.Generator | None = None,
    absent_probability: float = 0.15,
    noise_model: NoiseModel = "srgb",
    log_levels: bool = False,
) -> tuple[torch.Tensor, NoiseValues]:
    """Dark clips (B, T, C, H, W) made noisy with v of a noise model drawn from the training ranges, on
    8-bit levels.

    Each component is switched off (its parameters neutral) for a clip with probability
    ``absent_probability``; a parameter with a ``training_off_probability`` is also switched off alone with
    that probability (white, uncompressed noise stays in the training data).

    The sRGB structure is drawn as the spectral model draws it
    (:func:`darksynth.noise.structure_translation.spectral_tensors`), as ``apply`` draws a profile's.

    Returns:
        The noisy clips and the values drawn, each (B, size) by parameter name (every parameter of the table;
        those outside the model neutral): the network's vocabulary, not their translation.
    """
    batch = dark.shape[0]
    drawn = random_noise_values(
        batch_shape=(batch,), generator=generator, device=dark.device, noise_model=noise_model, log_levels=log_levels
    )
    switched: dict[str, torch.Tensor | float] = {}
    in_model = {p.name for p in model_parameters(noise_model)}
    for component in noise_components():
        if not any(p.name in in_model for p in component.parameters):
            continue
        present = torch.rand(batch, 1, generator=generator, device=dark.device) >= absent_probability
        for parameter in component.parameters:
            if parameter.name not in in_model:
                continue
            keep = present
            if parameter.training_off_probability is not None:
                alone = torch.rand(batch, 1, generator=generator, device=dark.device)
                keep = keep & (alone >= parameter.training_off_probability)
            switched[parameter.name] = torch.where(keep, drawn[parameter.name], parameter.neutral)
    values = drawn.replace(**switched)
    noisy = add_noise(dark, NoiseValues(spectral_tensors(values)), generator=generator)
    return to_8bit_levels(noisy), values
