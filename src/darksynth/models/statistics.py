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

from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from darksynth.noise.component_types import NoiseModel, StatisticsName
from darksynth.noise.components import model_parameters

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


# The multi-scale statistics, for the sRGB noise model.
# Real sRGB noise is spatially correlated, differs per channel, is correlated across channels and is often
# JPEG-compressed (docs/srgb-noise.md). The paper's statistics above read only neighbouring-pixel differences
# pooled over channels, which see a fraction of correlated noise. These read the noise at three scales, per
# channel, across channels, and JPEG's 8x8 grid and chroma subsampling.

SCALES = (1, 2, 4)
"""Block sizes the second differences are measured at: correlated noise loses less energy with the scale."""

MULTISCALE_STATISTICS_SIZE = len(SCALES) * 2 * 3 + len(SCALES) * 2 + 2 * 3 + 2 + 1
"""Length of :func:`multiscale_noise_statistics`' vector: per scale, direction and channel (18), per scale and
direction (6), channel correlations at two scales (6), JPEG block grid along x and y (2), chroma subsampling (1)."""


def _second_differences(frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Second differences along y and x of (N, C, H, W): cancel content that changes linearly."""
    along_y = frames[..., 1:-1, :] - 0.5 * (frames[..., :-2, :] + frames[..., 2:, :])
    along_x = frames[..., :, 1:-1] - 0.5 * (frames[..., :, :-2] + frames[..., :, 2:])
    return along_y, along_x


def _channel_correlations(along_y: torch.Tensor, along_x: torch.Tensor, batch: int) -> torch.Tensor:
    """Red-green, green-blue, red-blue correlation of second differences, (B, 3)."""
    channels = along_y.shape[1]
    flat = torch.cat([along_y.flatten(2), along_x.flatten(2)], dim=-1)  # (N, C, P)
    flat = flat.reshape(batch, -1, channels, flat.shape[-1]).transpose(1, 2).flatten(2)  # (B, C, T * P)
    if channels != 3:
        return torch.zeros(batch, 3, device=flat.device, dtype=flat.dtype)
    energy = flat.square().sum(-1)
    pairs = ((0, 1), (1, 2), (0, 2))
    return torch.stack(
        [(flat[:, i] * flat[:, j]).sum(-1) / (energy[:, i] * energy[:, j]).sqrt().clamp_min(_EPS) for i, j in pairs],
        dim=-1,
    )


def _block_grid_strength(first_differences: torch.Tensor, batch: int) -> torch.Tensor:
    """log(largest / mean energy) of first differences by position modulo 8 along the last axis, (B,): JPEG's
    8x8 blocks put extra energy at one phase, wherever the crop starts."""
    length = first_differences.shape[-1] // 8 * 8
    if length == 0:
        return torch.zeros(batch, device=first_differences.device, dtype=first_differences.dtype)
    energy = first_differences[..., :length].square()
    by_phase = energy.reshape(batch, -1, length // 8, 8).mean(dim=(1, 2))  # (B, 8)
    return _log(by_phase.max(-1).values) - _log(by_phase.mean(-1))


def multiscale_noise_statistics(clip: torch.Tensor) -> torch.Tensor:
    """Multi-scale, per-channel, cross-channel and compression statistics of a clip (B, T, C, H, W) in [0, 1].

    Returns:
        (B, MULTISCALE_STATISTICS_SIZE): log median |second difference| per scale (1, 2, 4 px blocks), direction (y,
        x) and channel; log mean square of the same per scale and direction; channel correlations of the
        second differences at scales 1 and 2; JPEG block-grid strength along y and x; and the drop of chroma
        against luma energy from scale 1 to 2 (4:2:0 subsampling removes fine chroma).
    """
    batch, frames, channels, height, width = clip.shape
    frames_flat = clip.reshape(batch * frames, channels, height, width)
    medians, squares, correlations = [], [], []
    luma_chroma = []
    for scale in SCALES:
        pooled = F.avg_pool2d(frames_flat, scale) if scale > 1 else frames_flat
        if min(pooled.shape[-2:]) < 3:
            pooled = F.pad(pooled, (1, 1, 1, 1), mode="replicate")
        along_y, along_x = _second_differences(pooled)
        for part in (along_y, along_x):
            per_frame = part.reshape(batch, frames, channels, -1).transpose(1, 2)  # (B, C, T, P)
            per_clip = per_frame.flatten(2)
            # A median of every 5th value of each frame: robust to edges like the full median, at a fraction of
            # its cost, and the same set of values whatever the order of the frames.
            medians.append(_log(per_frame[..., ::5].flatten(2).abs().median(dim=-1).values))
            squares.append(_log(per_clip.square().mean(dim=(1, 2))))
        if scale in (1, 2):
            correlations.append(_channel_correlations(along_y, along_x, batch))
            if channels == 3:
                luma = pooled.mean(1, keepdim=True)
                chroma = pooled - luma
                ly, lx = _second_differences(luma)
                cy, cx = _second_differences(chroma)
                luma_energy = (ly.square().mean(dim=(1, 2, 3)) + lx.square().mean(dim=(1, 2, 3))).reshape(batch, -1)
                chroma_energy = (cy.square().mean(dim=(1, 2, 3)) + cx.square().mean(dim=(1, 2, 3))).reshape(batch, -1)
                luma_chroma.append(_log(chroma_energy.mean(-1)) - _log(luma_energy.mean(-1)))
    subsampling = luma_chroma[0] - luma_chroma[1] if len(luma_chroma) == 2 else torch.zeros(batch, device=clip.device)
    grid = torch.stack(
        [
            _block_grid_strength((frames_flat[..., 1:, :] - frames_flat[..., :-1, :]).transpose(-1, -2), batch),
            _block_grid_strength(frames_flat[..., 1:] - frames_flat[..., :-1], batch),
        ],
        dim=-1,
    )
    return torch.cat(
        [torch.cat(medians, dim=-1), torch.stack(squares, dim=-1), *correlations, grid, subsampling[:, None]], dim=-1
    )


@dataclass(frozen=True)
class EstimatorStatistics:
    """A fixed statistics vector of noisy clips that the estimator's head reads; parameters of the table name
    the statistics that reveal them (:attr:`darksynth.noise.components.Parameter.statistics`)."""

    name: str
    size: int
    compute: Callable[[torch.Tensor], torch.Tensor]
    """clips (B, T, C, H, W) in [0, 1] -> (B, size)."""


PAPER_STATISTICS = EstimatorStatistics("paper", STATISTICS_SIZE, noise_statistics)
"""What reveals the paper's components: level-binned pixel noise and column patterns."""

MULTISCALE_STATISTICS = EstimatorStatistics("multiscale", MULTISCALE_STATISTICS_SIZE, multiscale_noise_statistics)
"""What reveals the sRGB structure: multi-scale, per-channel and cross-channel noise, JPEG grid, chroma."""


STATISTICS: dict[StatisticsName, EstimatorStatistics] = {"paper": PAPER_STATISTICS, "multiscale": MULTISCALE_STATISTICS}
"""The statistics each parameter of the table names (:attr:`darksynth.noise.component_types.Parameter.statistics`)."""


def model_statistics(noise_model: NoiseModel = "srgb", version: int | None = None) -> tuple[EstimatorStatistics, ...]:
    """The statistics the network of a noise model reads: those its parameters name, in table order."""
    names: list[StatisticsName] = []
    for parameter in model_parameters(noise_model, version):
        if parameter.statistics is not None and parameter.statistics not in names:
            names.append(parameter.statistics)
    return tuple(STATISTICS[name] for name in names)
