"""albumentations' noise augmentations as methods of `darksynth evaluate`: what users add to their training today.

Each runs at the ranges albumentations documents as its defaults (2.x), always applied (``p=1``), on the clean
image's 8-bit pixels; none reads the reference (they are not adaptive). albumentations is a dev/optional dependency
of darksynth, imported when such a method is built.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import torch

from darksynth.evaluation.methods.method import NoiseMethod

ALBUMENTATIONS_METHODS: dict[str, tuple[str, ...]] = {
    "albu-gauss": ("GaussNoise",),
    "albu-iso": ("ISONoise",),
    "albu-gauss-jpeg": ("GaussNoise", "ImageCompression"),
}
"""Method name -> the albumentations transforms it chains, each at its documented default ranges: ``GaussNoise``
(``std_range=(0.2, 0.44)`` of full scale, per channel), ``ISONoise`` (``color_shift=(0.01, 0.05)``,
``intensity=(0.1, 0.5)``), ``ImageCompression`` (JPEG, ``quality_range=(99, 100)``)."""


def albumentations_synthesize(transforms: tuple[str, ...]) -> Any:
    """(clean (3, H, W) in [0, 1], parameters (unused), generator) -> the transforms' output on 8-bit levels, in the
    clean image's dtype; the generator seeds albumentations, so a seed gives the same draw."""
    os.environ.setdefault("NO_ALBUMENTATIONS_UPDATE", "1")  # albumentations asks the network for updates otherwise
    import albumentations as A

    compose = A.Compose([getattr(A, name)(p=1.0) for name in transforms])

    def synthesize(clean: torch.Tensor, _: object, generator: torch.Generator) -> torch.Tensor:
        compose.set_random_seed(int(torch.randint(0, 2**31 - 1, (), generator=generator)))
        pixels = (clean.detach().cpu().permute(1, 2, 0).clamp(0.0, 1.0).numpy() * 255.0).round().astype(np.uint8)
        noisy = compose(image=pixels)["image"]
        return torch.from_numpy(np.ascontiguousarray(noisy)).permute(2, 0, 1).to(clean.dtype) / 255.0

    return synthesize


def albumentations_method(name: str) -> NoiseMethod:
    """The method ``name`` of :data:`ALBUMENTATIONS_METHODS`."""
    transforms = ALBUMENTATIONS_METHODS[name]
    return NoiseMethod(
        name=name,
        summary=f"albumentations {' + '.join(transforms)} at its documented default ranges; not adaptive",
        fit=lambda noisy, clean: None,
        synthesize=albumentations_synthesize(transforms),
        details={"transforms": list(transforms)},
    )
