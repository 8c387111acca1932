"""The record of one noise-synthesis method that `darksynth evaluate` compares (:mod:`.catalogue` builds them by
name): how it fits its parameters to a real pair and synthesises noise with them."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import torch

Fit = Callable[[torch.Tensor, torch.Tensor], Any]
Synthesize = Callable[[torch.Tensor, Any, torch.Generator], torch.Tensor]


@dataclass(frozen=True)
class NoiseMethod:
    """A named way to make synthetic noise.

    Attributes:
        fit: (noisy, clean) -> parameters; zero-shot methods must not read ``clean``.
        synthesize: (clean, parameters, generator) -> synthetic noisy image on 8-bit levels.
    """

    name: str
    summary: str
    fit: Fit
    synthesize: Synthesize
    oracle: bool = False
    details: dict[str, Any] = field(default_factory=dict)
    for_set: Callable[[str], NoiseMethod] | None = None
    """The method as it runs on the set of pairs named so, for a method that draws on the prior over real cameras:
    its prior fitted without that set (and the sets of the same cameras), so no set judges a prior that saw it."""

    read_octaves: Callable[[], Mapping[str, int] | None] | None = None
    """For a method that reads its spectrum from the noisy image: after a fit, how many octaves of the spectral
    model (from the finest, per component: ``brightness``, ``colour``) that image set, the rest being its prior
    (the estimate's ``meta.spectrum.read_octaves``); None where the fit does not say."""

    def on_set(self, set_name: str) -> NoiseMethod:
        """The method to run on the set ``set_name``."""
        return self.for_set(set_name) if self.for_set is not None else self
