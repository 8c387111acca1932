"""Whether a reference shows the 8-px block grid of a camera's JPEG (where it does, the noise measurement takes the
camera prior's texture dependence: ``NoiseEstimateOptions.jpeg_texture``).

A decoded JPEG steps at its blocks' boundaries, one pixel phase in 8. Per axis: the mean absolute difference of
neighbouring pixels (the channels' mean, 8-bit levels, each capped at :data:`CAP` so that edges do not decide it)
for each phase of the position modulo 8; the score is the largest phase's mean over the median of the six phases
that are neither it nor the one 4 away. The grid is shown where both axes score at least :data:`GRID_SCORE` and the
phase 4 away rises less than :data:`FOUR_PX_RISE` as far (a JPEG's blocks step a little at their middles too; a 4-px
period steps as much at both). On the shared real references it is shown on 82 of polyu's 100 noisy images (in-camera
JPEG of five DSLRs) and on none of sidd, sidd-phones, nam-cc15, DICM, LIME or LOL (docs/spectral-noise.md).

Why it matters: a camera that writes JPEG has denoised and compressed in camera, which keeps noise on texture and
flattens it elsewhere (polyu: the real noise's textured-to-flat std 2.0, the estimate's 1.4 without a texture term).
No single reference shows that dependence; the prior over real cameras expects it given what was measured
(``texture_gain``, ``texture_scale``, :func:`~darksynth.estimation.noise.camera_conditional.expected_texture`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

CAP = 6.0
"""A neighbour difference counts at most this many 8-bit levels."""

GRID_SCORE = 1.3
"""An axis shows the grid when its largest phase is at least this many times the other phases' median..."""

FOUR_PX_RISE = 0.5
"""...and the phase 4 away rises less than this share of the largest's rise above that median."""


@dataclass(frozen=True)
class JpegGrid:
    """What the grid statistic read of one frame: ``shown`` on both axes, and the smaller axis ``score``."""

    shown: bool
    score: float


def _axis_scores(frame: torch.Tensor) -> list[tuple[float, float]]:
    """(score, the phase 4 away over the same median) of the columns' and the rows' phases of a frame (3, H, W)."""
    grey = frame.to(torch.float64).mean(0) * 255.0
    scores = []
    for difference in ((grey[:, 1:] - grey[:, :-1]).abs(), (grey[1:, :] - grey[:-1, :]).abs().T):
        usable = difference.shape[1] // 8 * 8
        if usable < 16:
            return [(1.0, 1.0), (1.0, 1.0)]
        phases = torch.stack([difference[:, phase:usable:8].clamp(max=CAP).mean() for phase in range(8)])
        peak = int(phases.argmax())
        others = torch.stack([phases[p] for p in range(8) if p not in (peak, (peak + 4) % 8)])
        floor = max(float(others.median()), 1e-6)
        scores.append((float(phases[peak]) / floor, float(phases[(peak + 4) % 8]) / floor))
    return scores


def jpeg_grid(frame: torch.Tensor) -> JpegGrid:
    """Whether ``frame`` (3, H, W) in [0, 1] shows a JPEG's 8-px block grid on both axes."""
    scores = _axis_scores(frame)
    shown = all(score >= GRID_SCORE and share - 1.0 < FOUR_PX_RISE * (score - 1.0) for score, share in scores)
    return JpegGrid(shown, min(score for score, _ in scores))
