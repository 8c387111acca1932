"""Whether a reference shows column patterns, and the column components set absent when it does not.

The network never predicts exactly zero: on a reference without stripes it gives small banding and periodic
values that draw faint vertical stripes. Whether the reference shows column patterns at all is measured on the
reference itself (:func:`column_presence`), and :func:`decide_columns` sets the column components absent
(neutral, without ranges) when it does not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import torch

from darksynth.noise.components import noise_components
from darksynth.noise.values import NoiseValues

COLUMN_RATIO = 2.0
"""Column components count as present when the reference's high-passed column means vary at least this many
times as much as its high-passed row means scaled to the same number of pixels (:func:`column_presence`): a
ratio of 2 is a column pattern with sqrt(3) times the std that noise and content give the column means."""


@dataclass(frozen=True)
class ColumnPresence:
    """Whether a reference shows column patterns beyond what noise and content give its column means.

    Attributes:
        column_std: robust std (1.4826 MAD) of the column means high-passed along x, pooled over frames and
            channels, on the [0, 1] scale.
        null_std: the same statistic of the row means high-passed along y, times sqrt(W / H): what pixel noise
            and content alone give means of H pixels (a column pattern adds nothing to row means).
        ratio: column_std / null_std.
        excess_std: the std of a column pattern that would explain the excess, sqrt(column_std^2 - null_std^2)
            / sqrt(1.5) (the second difference multiplies the variance of independent column offsets by 1.5),
            0 when there is none: a measurement of the banding's strength beside the network's.
        shared_ratio: for a clip, the same ratio on the mean over frames (where temporal banding is); None for
            one frame.
    """

    column_std: float
    null_std: float
    ratio: float
    shared_ratio: float | None

    @property
    def excess_std(self) -> float:
        return math.sqrt(max(self.column_std**2 - self.null_std**2, 0.0) / 1.5)

    @property
    def present(self) -> bool:
        return self.ratio >= COLUMN_RATIO


def _highpassed_spread(means: torch.Tensor) -> float:
    """Robust std of the second difference along the last axis (cancels content changing linearly along it)."""
    highpass = (means[..., 1:-1] - 0.5 * (means[..., :-2] + means[..., 2:])).flatten()
    if highpass.numel() == 0:
        return 0.0
    return 1.4826 * float((highpass - highpass.median()).abs().median())


def _ratio(columns: float, null: float) -> float:
    if null > 0:
        return columns / null
    return math.inf if columns > 0 else 0.0


def column_presence(reference: torch.Tensor, frames: Sequence[int] | None = None) -> ColumnPresence:
    """Measure column patterns on a reference (T, C, H, W) in [0, 1], on the given ``frames`` (default all).

    Banding, temporal banding and periodic noise are constant down each column: they survive in the column
    means, high-passed along x, at full strength, where pixel noise is reduced to its std / sqrt(H). The row
    means, high-passed along y, see the same pixel noise (reduced by sqrt(W), rescaled here to sqrt(H)) and the
    same kind of scene content, but no column pattern: they are the null. The median absolute deviation keeps
    a few vertical edges of the scene (a door frame) from counting as banding.
    """
    height, width = reference.shape[-2], reference.shape[-1]
    scale = math.sqrt(width / height)
    chosen = range(reference.shape[0]) if frames is None else frames
    # Frame by frame: selecting frames by index would copy them (0.2 s for four 1080p frames).
    column_means = torch.stack([reference[i].mean(dim=-2) for i in chosen])  # (T, C, W)
    row_means = torch.stack([reference[i].mean(dim=-1) for i in chosen])  # (T, C, H)
    column_std = _highpassed_spread(column_means)
    null_std = _highpassed_spread(row_means) * scale
    shared_ratio = None
    if column_means.shape[0] > 1:
        shared_ratio = _ratio(_highpassed_spread(column_means.mean(0)), _highpassed_spread(row_means.mean(0)) * scale)
    return ColumnPresence(column_std, null_std, _ratio(column_std, null_std), shared_ratio)


def decide_columns(
    reference: torch.Tensor,
    frames: list[int],
    noise: NoiseValues,
) -> tuple[NoiseValues, dict[str, Any]]:
    """Set the column components absent (neutral; the caller drops their ranges, named in the record's
    ``set_absent``) when the reference shows no column pattern.

    The network never predicts exactly zero: on a reference without stripes it gives small banding and periodic
    values that draw faint vertical stripes. The presence is measured on the whole reference instead
    (:func:`column_presence`). Returns the values and the record of what was tested and decided (the profile's
    ``meta["columns"]``).
    """
    names = [p.name for c in noise_components() if c.structure == "column" for p in c.parameters]
    presence = column_presence(reference, frames)
    absent = not presence.present
    record: dict[str, Any] = {
        "test": "robust std of the column means high-passed along x over that of the row means high-passed "
        f"along y, scaled to H pixels; present at a ratio of {COLUMN_RATIO} or more",
        "ratio": round(presence.ratio, 3),
        "column_std_8bit": round(presence.column_std * 255, 4),
        "null_std_8bit": round(presence.null_std * 255, 4),
        "excess_std_8bit": round(presence.excess_std * 255, 4),
        "decision": "absent" if absent else "present",
        "frames_measured": frames,
    }
    if presence.shared_ratio is not None:
        record["shared_ratio"] = round(presence.shared_ratio, 3)
    if not absent:
        return noise, record
    record["set_absent"] = names
    record["network_values"] = {name: [round(float(v), 5) for v in noise[name].tolist()] for name in names}
    neutral = {p.name: p.neutral for c in noise_components() if c.structure == "column" for p in c.parameters}
    return noise.replace(**neutral), record
