"""The ``starlight`` baseline: Starlight's noise generator (Monakhova et al. 2022) adapted to sRGB.

Physics components with learned scalar parameters (shot, read, row, temporal row, uniform, periodic) plus a
small U-Net that adds a learned residual, trained adversarially on the DEN's self-supervised synthetic data.
See ``docs/starlight.md``.

Public API::

    StarlightGenerator(config)            # forward(clean, generator) -> noisy, (B, C, H, W) or (B, T, C, H, W)
    load_starlight(path=None, device="cpu")  # the shipped weights by default
    save_starlight(path, model)
    train_starlight(corpus, config, holdout=..., out=...)
"""

from __future__ import annotations

from darksynth.baselines.adversarial import PatchDiscriminator, histogram_kl, summary_path
from darksynth.baselines.starlight_model import (
    MODEL_NAME,
    MODEL_VERSION,
    PHYSICS_NAMES,
    StarlightConfig,
    StarlightGenerator,
    default_starlight_path,
    load_starlight,
    save_starlight,
)
from darksynth.baselines.starlight_training import (
    StarlightTrainConfig,
    evaluate_starlight,
    train_starlight,
    validation_batches,
)

__all__ = [
    "MODEL_NAME",
    "MODEL_VERSION",
    "PHYSICS_NAMES",
    "PatchDiscriminator",
    "StarlightConfig",
    "StarlightGenerator",
    "StarlightTrainConfig",
    "default_starlight_path",
    "evaluate_starlight",
    "histogram_kl",
    "load_starlight",
    "save_starlight",
    "summary_path",
    "train_starlight",
    "validation_batches",
]
