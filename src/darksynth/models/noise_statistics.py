"""Fixed, differentiable noise statistics of a clip, read by the DEN's head beside its learned features.

Real sRGB noise and the paper's components leave signatures that a small convolutional encoder, trained for
an hour on two CPU cores, finds slowly: column patterns span the whole frame height, and the law of the
variance against the signal needs binning by intensity. These statistics compute those signatures directly
(no parameters), so the head learns to combine them with what the encoder sees:

- pixel noise from vertical differences, which cancel everything constant down a column (banding, periodic),
  binned by the local level so that shot and read noise separate;
- column noise from the column means, high-passed along the row to cancel smooth image content, split into
  the part shared by all frames of the clip (temporal banding) and the rest (banding), and projected on the
  period-4 cosine and sine of periodic noise;
- the frame-to-frame spread of each channel's mean (periodic noise's column-frequency-0 term).

Everything is returned as log10 of a variance-like quantity, which keeps the scales of many decades usable.
"""

from __future__ import annotations

import torch

LEVEL_BINS = 12
"""Intensity bins of the pixel-noise statistics over [0, LEVEL_MAX]."""

LEVEL_MAX = 0.3
"""Upper edge of the last bin: low-light references rarely go brighter; brighter pixels fall in the last bin."""

STATISTICS_SIZE = 3 * LEVEL_BINS + 9
"""Length of the statistics vector of one clip."""

_EPS = 1e-10


def _log(value: torch.Tensor) -> torch.Tensor:
    return torch.log10(value + _EPS)


def pixel_noise_statistics(clip: torch.Tensor) -> torch.Tensor:
    """Per intensity bin: log mean squared and log mean absolute vertical difference, and the bin's share.

    Args:
        clip: (B, T, C, H, W) in [0, 1].

    Returns:
        (B, 3 * LEVEL_BINS).
    """
    difference = (clip[..., 1:, :] - clip[..., :-1, :]).flatten(1)
    level = (0.5 * (clip[..., 1:, :] + clip[..., :-1, :])).flatten(1)
    # Hard bins: the input never needs a gradient, and scatter_add is far cheaper than soft assignment.
    bins = (level * (LEVEL_BINS / LEVEL_MAX)).long().clamp(0, LEVEL_BINS - 1)
    zeros = torch.zeros(clip.shape[0], LEVEL_BINS, device=clip.device, dtype=clip.dtype)
    count = zeros.scatter_add(1, bins, torch.ones_like(difference))
    mean_square = zeros.scatter_add(1, bins, difference.square()) / count.clamp_min(1.0)
    mean_absolute = zeros.scatter_add(1, bins, difference.abs()) / count.clamp_min(1.0)
    share = count / difference.shape[1]
    return torch.cat([_log(mean_square / 2), _log(mean_absolute), _log(share)], dim=-1)


def column_noise_statistics(clip: torch.Tensor) -> torch.Tensor:
    """Column-pattern and channel-offset statistics.

    Args:
        clip: (B, T, C, H, W) in [0, 1].

    Returns:
        (B, 9): log energies of the high-passed column means (all, shared over frames, per frame), their
        period-4 cosine and sine projections (all and shared), the frame-to-frame variance of channel means,
        the pixel-noise floor in the column means (variance / H), and 1 / T.
    """
    frames, height, width = clip.shape[1], clip.shape[-2], clip.shape[-1]
    columns = clip.mean(dim=-2)  # (B, T, C, W)
    # Second difference along the row: cancels content that changes linearly across columns and passes a
    # period-4 wave at full amplitude (its neighbours cancel each other).
    highpass = columns[..., 1:-1] - 0.5 * (columns[..., :-2] + columns[..., 2:])
    shared = highpass.mean(dim=1, keepdim=True)
    own = highpass - shared
    index = torch.arange(1, width - 1, device=clip.device)
    cosine = torch.tensor([1.0, 0.0, -1.0, 0.0], device=clip.device, dtype=clip.dtype)[index % 4]
    sine = torch.tensor([0.0, 1.0, 0.0, -1.0], device=clip.device, dtype=clip.dtype)[index % 4]
    count = max(highpass.shape[-1], 1)

    def projection(pattern: torch.Tensor, wave: torch.Tensor) -> torch.Tensor:
        # Mean square amplitude of the wave in the pattern, averaged over frames and channels.
        return ((pattern * wave).sum(-1) * (2.0 / count)).square().mean(dim=(1, 2)) / 2

    channel_means = clip.mean(dim=(-2, -1))  # (B, T, C)
    frame_spread = (
        channel_means.var(dim=1, unbiased=True).mean(-1) if frames > 1 else torch.zeros_like(channel_means[:, 0, 0])
    )
    vertical = clip[..., 1:, :] - clip[..., :-1, :]
    floor = vertical.square().mean(dim=(1, 2, 3, 4)) / 2 / height
    return torch.stack(
        [
            _log(highpass.square().mean(dim=(1, 2, 3))),
            _log(shared.square().mean(dim=(1, 2, 3))),
            _log(own.square().mean(dim=(1, 2, 3)) * frames / max(frames - 1, 1)),
            _log(projection(highpass, cosine)),
            _log(projection(highpass, sine)),
            _log(projection(shared, cosine) + projection(shared, sine)),
            _log(frame_spread),
            _log(floor),
            torch.full_like(floor, 1.0 / frames),
        ],
        dim=-1,
    )


def noise_statistics(clip: torch.Tensor) -> torch.Tensor:
    """All statistics of a clip (B, T, C, H, W) in [0, 1]: (B, STATISTICS_SIZE)."""
    return torch.cat([pixel_noise_statistics(clip), column_noise_statistics(clip)], dim=-1)
