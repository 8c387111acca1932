"""Exposure flicker: the per-frame gain of a night video's brightness.

Mains-powered lights pulse, and a camera's auto-exposure hunts in the dark, so the brightness of a night video
moves from frame to frame. It is modelled as a gain on the darkened signal, ``g_t = 1 + flicker * z_t``, where z
is a stationary AR(1) sequence of unit variance whose lag-1 correlation is ``flicker_correlation``: a pulse
(correlation near 0) and a slow drift of auto-exposure (near 1) are both one std and one correlation, which the
estimator reads off the still parts of a reference clip. A single image has no flicker.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import torch

MIN_GAIN = 0.05
"""Gains are kept above this: a draw far in the tail must not make a frame negative or black."""


class FlickerGains:
    """The gains of one clip, drawn frame by frame from a generator (the stream's own, so a seed fixes them).

    Args:
        std: ``flicker``, the std of the gain; 0 gives 1 for every frame without drawing anything.
        correlation: ``flicker_correlation``, the lag-1 correlation in [0, 1).
    """

    def __init__(self, std: float, correlation: float) -> None:
        self.std = float(std)
        self.correlation = float(correlation)
        self._state: float | None = None

    @property
    def active(self) -> bool:
        return self.std > 0

    def next(self, generator: torch.Generator | None) -> float:
        """The next frame's gain (1 when there is no flicker)."""
        if not self.active:
            return 1.0
        device = generator.device if generator is not None else None
        draw = float(torch.randn((), generator=generator, device=device, dtype=torch.float64))
        if self._state is None:
            self._state = draw
        else:
            rho = self.correlation
            self._state = rho * self._state + math.sqrt(max(0.0, 1 - rho * rho)) * draw
        return max(MIN_GAIN, 1.0 + self.std * self._state)

    def sequence(self, frames: int, generator: torch.Generator | None) -> torch.Tensor:
        """The gains of ``frames`` frames, float64 (T,)."""
        return torch.tensor([self.next(generator) for _ in range(frames)], dtype=torch.float64)


def flicker_gains(
    clip: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    """Per-frame gains (*batch, T, 1, 1, 1) on the darkened clips (*batch, T, C, H, W); 1 for single frames."""
    batch = clip.shape[:-4]
    frames = clip.shape[-4]
    stds = values["flicker"].reshape(-1).expand(math.prod(batch))
    correlations = values["flicker_correlation"].reshape(-1).expand(stds.shape[0])
    gains = torch.ones(stds.shape[0], frames, dtype=torch.float64)
    if frames > 1:
        for index in range(stds.shape[0]):
            gains[index] = FlickerGains(float(stds[index]), float(correlations[index])).sequence(frames, generator)
    return gains.reshape(*batch, frames, 1, 1, 1).to(device=clip.device, dtype=clip.dtype)
