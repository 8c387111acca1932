"""Reference -> crops or clips -> DEN -> robust aggregate -> noise profile.

The estimate of every crop is a full v; the profile holds their median (robust to crops where content,
clipping or a light source misleads the network) and, as ``ranges``, the 10th to 90th percentile across crops,
so that ``apply`` can reproduce the spread the reference shows. The darkening (alpha, gamma) is read from the
reference's tone distribution (:mod:`darksynth.darkening_estimate`); for a clip, its ``ranges`` are the 10th
to 90th percentile of the per-frame estimates.

Two things are measured on the reference itself rather than taken from the network: whether it shows column
patterns at all (:func:`column_presence`; without them the column components are set absent, since the network
never predicts exactly zero), and how much noise the profile would add on it (the "nearly noise-free" warning).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from darksynth.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening
from darksynth.darkening_estimate import (
    ALPHA_BOUNDS,
    GAMMA_BOUNDS,
    PROBABILITIES,
    DarkeningEstimate,
    estimate_darkening_pooled_and_per_frame,
    estimate_darkening_spread,
)
from darksynth.errors import DarksynthError
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.discover import classify_input, scan_folder
from darksynth.io.images import read_image
from darksynth.io.video import iter_video_frames
from darksynth.models.den import DEN
from darksynth.noise.components import NoiseModel, model_parameters, noise_components, noise_parameter
from darksynth.noise.level import mean_noise_variance
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.refine import ANALYSIS_FRAMES, refine_profile

CROP = 128
"""Side of the square crops; the network was trained on crops of this size."""

MIN_SIDE = 32
"""References smaller than this on either side are refused: the column statistics need some extent."""

MAX_FRAMES = 16
"""Frames read from a video or frame folder: enough for temporal statistics, bounded in memory and time."""

CLIP_FRAMES = 4
"""Frames per clip given to the network (it was trained on clips of 4 and single frames)."""

BRIGHT_MEAN = 0.35
"""A reference whose mean level is above this is not low-light; its estimate is less reliable."""

COLUMN_RATIO = 2.0
"""Column components count as present when the reference's high-passed column means vary at least this many
times as much as its high-passed row means scaled to the same number of pixels (:func:`column_presence`): a
ratio of 2 is a column pattern with sqrt(3) times the std that noise and content give the column means."""

MEASURED_FRAMES = 4
"""Frames (evenly spread) on which the column presence and the profile's noise level are measured."""

NOISE_FREE_STD = 0.5 / 255
"""Below this noise std (half an 8-bit level) on the reference, a profile is nearly noise-free: a pixel on an
8-bit level rounds back to it in 68% of the draws (|n| < 0.5 level, one std)."""


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


def spread_frames(total: int, count: int) -> list[int]:
    """Indices of up to ``count`` frames evenly spread over ``total`` (first and last included)."""
    return np.unique(np.linspace(0, total - 1, count).round().astype(int)).tolist()  # type: ignore[no-any-return]


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


@dataclass(frozen=True)
class EstimateOptions:
    """How ``estimate`` reads and runs on a reference file (the network is chosen by the caller).

    Attributes:
        clip: a folder is the frames of one clip (without it, a folder is refused).
        device: torch device the network runs on.
        max_frames: frames read from a video or frame folder.
        batch: crops per forward pass.
    """

    clip: bool = False
    device: str = "cpu"
    max_frames: int = MAX_FRAMES
    batch: int = 16
    refine: bool = True
    """After the sRGB network, refine the noise on the reference itself by analysis by synthesis
    (:func:`darksynth.refine.refine_profile`, docs/refine.md): on the real pairs it divides the histogram KL of
    the network's estimate by 1.7-4.8 (docs/results.md); ``--no-refine`` keeps the network's values (the ablation)."""


def estimate_file(path: Path, network: DEN, options: EstimateOptions) -> Estimate:
    """Read a reference file or frame folder and estimate its profile (the ``estimate`` job)."""
    frames = load_reference(path, clip=options.clip, max_frames=options.max_frames)
    return estimate(
        frames, network, source=str(path), batch=options.batch, device=options.device, refine=options.refine
    )


@dataclass
class Estimate:
    """A profile and what was learned on the way: per-crop values and warnings."""

    profile: Profile
    per_crop: NoiseValues
    """The network's estimate for each crop, batched (N,)."""
    warnings: list[str] = field(default_factory=list)


def _as_rgb(pixels: np.ndarray) -> torch.Tensor:
    tensor = hwc_to_chw(pixels)
    return tensor.expand(3, -1, -1) if tensor.shape[0] == 1 else tensor


def _to_unit_float(frames: list[torch.Tensor]) -> torch.Tensor:
    # Stack the integer frames first and convert once: one pass over the clip instead of one per frame.
    stacked = torch.stack(frames)
    scale = 65535.0 if stacked.dtype == torch.uint16 else 255.0
    if stacked.dtype == torch.uint16:
        stacked = stacked.to(torch.int32)
    return stacked.to(torch.float32).div_(scale)


def load_reference(path: Path, *, clip: bool = False, max_frames: int = MAX_FRAMES) -> torch.Tensor:
    """Read a reference as frames (T, 3, H, W) in [0, 1].

    An image gives one frame; a video its first ``max_frames`` frames; a folder, with ``clip``, its images in
    name order (the first ``max_frames``).

    Raises:
        DarksynthError: unreadable, a folder without ``clip``, frames of different sizes, or too small.
    """
    kind = classify_input(path)
    frames: list[torch.Tensor] = []
    if kind == "image":
        frames = [_as_rgb(read_image(path).pixels)]
    elif kind == "video":
        for frame in iter_video_frames(path):
            frames.append(_as_rgb(frame))
            if len(frames) == max_frames:
                break
        if not frames:
            raise DarksynthError(f"{path}: the video has no decodable frames")
    else:
        if not clip:
            raise DarksynthError(f"{path}: a folder is a reference only as a clip of frames; add --clip")
        for name in scan_folder(path).images[:max_frames]:
            image = _as_rgb(read_image(path / name).pixels)
            if frames and image.shape != frames[0].shape:
                raise DarksynthError(
                    f"{path / name}: frame size {tuple(image.shape[1:])} differs from {tuple(frames[0].shape[1:])}"
                )
            frames.append(image)
    reference = _to_unit_float(frames)
    if min(reference.shape[-2:]) < MIN_SIDE:
        raise DarksynthError(
            f"{path}: {reference.shape[-1]}x{reference.shape[-2]} is smaller than the estimator's minimum "
            f"{MIN_SIDE}x{MIN_SIDE}"
        )
    return reference


def crop_grid(
    reference: torch.Tensor, *, crop: int = CROP, clip_frames: int = CLIP_FRAMES, max_crops: int = 48
) -> torch.Tensor:
    """Crops covering the reference, as clips (N, T, 3, S, S).

    Crops lie on a regular grid over the frame, left edges at multiples of 4 (the phase of periodic noise is
    measured from column 0), with up to ``clip_frames`` consecutive frames each, in windows over the clip.
    """
    frames, _, height, width = reference.shape
    side = min(crop, height, width - width % 4 if width >= 4 else width)
    t = min(clip_frames, frames)
    windows = list(range(0, frames - t + 1, t)) or [0]
    rows = max(1, math.ceil(height / side))
    columns = max(1, math.ceil(width / side))
    # np.unique: a frame only slightly larger than the crop would otherwise get the same crop twice.
    tops = np.unique(np.linspace(0, height - side, rows).round().astype(int))
    lefts = np.unique((np.linspace(0, width - side, columns) // 4 * 4).astype(int))
    crops = [
        reference[start : start + t, :, top : top + side, left : left + side]
        for start in windows
        for top in tops
        for left in lefts
    ]
    if len(crops) > max_crops:
        keep = np.linspace(0, len(crops) - 1, max_crops).round().astype(int)
        crops = [crops[i] for i in keep]
    return torch.stack(crops)


@torch.no_grad()
def estimate(
    reference: torch.Tensor,
    network: DEN,
    *,
    source: str = "",
    batch: int = 16,
    device: torch.device | str = "cpu",
    refine: bool = True,
) -> Estimate:
    """Estimate a noise profile from reference frames (T, 3, H, W) in [0, 1].

    Args:
        refine: for a network of the sRGB model, refine its values on the reference itself
            (:func:`darksynth.refine.refine_profile`); skipped, with a warning, on a reference smaller than
            :data:`REFINE_MIN_SIDE`. The paper's model is never refined (the refinement moves the sRGB structure).
    """
    crops = crop_grid(reference)
    network = network.to(device).eval()
    per_crop = NoiseValues.stack(
        [network(crops[i : i + batch].to(device)).values.to("cpu") for i in range(0, len(crops), batch)]
    ).to(dtype=torch.float64)
    # quantile(0.5) averages the two middle crops of an even count, where Tensor.median takes the lower one.
    noise = per_crop.map(lambda t: torch.quantile(t, 0.5, dim=0))
    low = per_crop.map(lambda t: torch.quantile(t, 0.1, dim=0))
    high = per_crop.map(lambda t: torch.quantile(t, 0.9, dim=0))
    noise_model = network.noise_model
    # What the network does not estimate (the sRGB structure, for the paper's model) stays neutral, without a range.
    ranges = {
        p.name: tuple(zip(low[p.name].tolist(), high[p.name].tolist(), strict=True))
        for p in model_parameters(noise_model, network.config.table_version)
    }
    meta: dict[str, Any] = {
        "source": source,
        "estimator": f"DEN {network.config.variant} width {network.config.width} depth {network.config.depth}",
        "noise_model": noise_model,
        "crops": len(crops),
        "frames": int(reference.shape[0]),
        "aggregate": "median over crops; ranges are the 10th-90th percentiles",
    }
    # A few frames spread over the clip measure the columns and the level: the whole 1080p clip took 1.5 s more.
    measured = spread_frames(reference.shape[0], MEASURED_FRAMES)
    noise = _decide_columns(reference, measured, noise, ranges, meta)
    warnings: list[str] = []
    name = source or "reference"
    uniform = uniform_frames(reference)
    if uniform:
        which = "the reference is" if len(uniform) == reference.shape[0] else f"frames {uniform} are"
        warnings.append(
            f"{name}: {which} uniform (black, saturated or flat: std under {FLAT_STD * 255:.1f} 8-bit level): there "
            "is no noise to measure there, and what the profile holds from them is the network's output on a flat "
            "image, not a measurement"
        )
    cuts = scene_cuts(reference)
    if cuts:
        meta["scene_cuts"] = cuts
        warnings.append(
            f"{name}: scene cut before frame(s) {cuts}: the estimate mixes more than one scene (the refinement reads "
            f"the first {ANALYSIS_FRAMES} frames, the darkening several spread over the clip); give one shot"
        )
    if refines(noise_model, refine) and len(uniform) < reference.shape[0]:
        noise = _refine(reference, noise, ranges, meta, warnings, name)
    level = float(reference.mean())
    if level > BRIGHT_MEAN:
        warnings.append(
            f"{name}: mean level {level:.2f} is bright for a low-light reference; "
            "the estimate may be unreliable (on a clean daylight photo the profile holds what it reads of the "
            "photo's grain, JPEG residue and fine texture as noise, often several 8-bit levels)"
        )
    noise_std = profile_noise_std(noise, reference, measured)
    meta["noise_std_8bit"] = round(noise_std * 255, 3)
    if noise_std < NOISE_FREE_STD:
        warnings.append(
            f"{name}: nearly noise-free; the profile adds noise of std {noise_std * 255:.2f} "
            f"8-bit levels on it (below {NOISE_FREE_STD * 255:.1f})"
        )
    if reference.shape[0] == 1:
        meta["note"] = (
            "single image: temporal banding cannot be told from banding; their split is the network's prior "
            "(what it learned from the training table's ranges), not a measurement"
        )
    darkening = _estimate_darkening(reference, name, ranges, meta, warnings)
    profile = Profile(noise=noise, darkening=darkening, ranges=ranges, meta=meta)
    return Estimate(profile=profile, per_crop=per_crop, warnings=warnings)


FLAT_STD = 0.5 / 255
"""Below this std over all pixels of a frame (half an 8-bit level), a frame is uniform (black, saturated or flat):
it holds no noise to measure."""

SCENE_CUT_CHANGE = 0.08
"""A change of the 16x16-block means between two consecutive frames above this (mean absolute, [0, 1] scale) is
a scene cut: noise, which averages out over 256 pixels, moves the block means by well under 0.01 at the
strongest training level; a camera pan or a light switched on in a dim scene moves them by a few hundredths."""


def refines(noise_model: NoiseModel, refine: bool = True) -> bool:
    """Whether ``estimate`` (asked to ``refine``) refines a network's values of this noise model on the reference:
    the sRGB model's only; the paper model stays the paper's."""
    return refine and noise_model == "srgb"


def uniform_frames(reference: torch.Tensor) -> list[int]:
    """Frames of a reference (T, 3, H, W) whose pixels are all (nearly) the same value.

    Read on every 4th pixel of every 4th row: a frame that varies at all varies there too, and the std of 16
    1080p frames in full took 0.28 s."""
    spread = reference[..., ::4, ::4].flatten(1).std(dim=1)
    return [int(i) for i in torch.nonzero(spread < FLAT_STD).flatten()]


def scene_cuts(reference: torch.Tensor) -> list[int]:
    """Indices t of frames that start a new scene (a cut between frames t - 1 and t)."""
    if reference.shape[0] < 2 or min(reference.shape[-2:]) < 16:
        return []
    blocks = F.avg_pool2d(reference, 16)
    change = (blocks[1:] - blocks[:-1]).abs().mean(dim=(1, 2, 3))
    return [int(i) + 1 for i in torch.nonzero(change > SCENE_CUT_CHANGE).flatten()]


REFINE_MIN_SIDE = 64
"""Smallest side the refinement reads a reference of: below it, its 30 % smoothest pixels split into eight level
bins leave too few pixels per bin for a variance (about 150 at 64 px), and the network's values stay."""


def _refine(
    reference: torch.Tensor,
    noise: NoiseValues,
    ranges: dict[str, tuple[tuple[float, float], ...]],
    meta: dict[str, Any],
    warnings: list[str],
    source: str,
) -> NoiseValues:
    """The network's values refined on the reference, with ``ranges`` carried along (see :func:`moved_ranges`)
    and what the network had said in ``meta["refined"]``."""
    if min(reference.shape[-2:]) < REFINE_MIN_SIDE:
        warnings.append(
            f"{source}: {reference.shape[-1]}x{reference.shape[-2]} is too small to refine the noise on (needs "
            f"{REFINE_MIN_SIDE} px a side); the profile keeps the network's values, which are weaker and greyer "
            "than real noise (docs/refine.md)"
        )
        meta["refined"] = {"method": "not refined: reference too small"}
        return noise
    refined = refine_profile(reference, noise)
    ranges.update(moved_ranges(ranges, noise, refined))
    meta["refined"] = {
        "method": "analysis by synthesis on the reference (docs/refine.md); ranges moved with the values",
        "network_values": {name: [round(float(v), 5) for v in noise[name].tolist()] for name in noise},
    }
    return refined


def moved_ranges(
    ranges: Mapping[str, tuple[tuple[float, float], ...]], before: NoiseValues, after: NoiseValues
) -> dict[str, tuple[tuple[float, float], ...]]:
    """The network's per-crop ranges carried to refined values.

    ``apply`` draws every parameter that has a range within it, so ranges left around the network's values would
    undo the refinement. Levels (parameters with a log floor: positive, spanning decades) move by the ratio of
    the values, every other parameter by their difference, each clipped to its bounds and widened to hold the
    value; compression, which the refinement chooses among a few strengths, keeps no spread. Parameters the
    refinement left unchanged keep their ranges.
    """
    moved: dict[str, tuple[tuple[float, float], ...]] = {}
    for name, intervals in ranges.items():
        if name not in before or name not in after or torch.equal(before[name], after[name]):
            continue
        parameter = noise_parameter(name)
        entries = []
        for (low, high), old, new in zip(intervals, before[name].tolist(), after[name].tolist(), strict=True):
            if name == "compression":
                low = high = new
            elif parameter.log_floor is not None and old > 0.0:
                low, high = low * new / old, high * new / old
            else:
                low, high = low + new - old, high + new - old
            low = min(max(low, parameter.minimum), new)
            high = max(min(high, parameter.maximum), new)
            entries.append((float(low), float(high)))
        moved[name] = tuple(entries)
    return moved


def profile_noise_std(noise: NoiseValues, reference: torch.Tensor, frames: Sequence[int] | None = None) -> float:
    """The std of the noise a profile's values add on a reference (T, C, H, W) (on the given ``frames``, default
    all), before clipping and rounding.

    The variance depends on the reference only through its channel means, which are passed on as a 1 x 1
    frame: the whole reference in float64 would be a copy of 800 MB for 16 frames of 1080p.
    """
    chosen = range(reference.shape[0]) if frames is None else frames
    channel_means = torch.stack([reference[i].mean(dim=(1, 2)) for i in chosen]).mean(0)
    channel_means = channel_means.to(torch.float64).reshape(1, -1, 1, 1)
    batched = noise.map(lambda t: t[None].to(torch.float64))
    return float(mean_noise_variance(batched, channel_means).clamp_min(0).sqrt())


def _decide_columns(
    reference: torch.Tensor,
    frames: list[int],
    noise: NoiseValues,
    ranges: dict[str, tuple[tuple[float, float], ...]],
    meta: dict[str, Any],
) -> NoiseValues:
    """Set the column components absent (neutral, without ranges) when the reference shows no column pattern.

    The network never predicts exactly zero: on a reference without stripes it gives small banding and periodic
    values that draw faint vertical stripes. The presence is measured on the whole reference instead
    (:func:`column_presence`), and what was tested and decided goes into ``meta["columns"]``.
    """
    names = [p.name for c in noise_components() if c.structure == "column" for p in c.parameters]
    presence = column_presence(reference, frames)
    absent = not presence.present
    meta["columns"] = {
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
        meta["columns"]["shared_ratio"] = round(presence.shared_ratio, 3)
    if not absent:
        return noise
    meta["columns"]["set_absent"] = names
    meta["columns"]["network_values"] = {name: [round(float(v), 5) for v in noise[name].tolist()] for name in names}
    for name in names:
        ranges.pop(name, None)
    neutral = {p.name: p.neutral for c in noise_components() if c.structure == "column" for p in c.parameters}
    return noise.replace(**neutral)


DARKENING_FRAMES = 3
"""Frames (evenly spread) on which the darkening and its per-frame range are estimated."""

LOW_DARKENING_CONFIDENCE = 0.1
"""Below this confidence (:attr:`DarkeningEstimate.confidence`) the darkening estimate comes with a warning.

On held-out Kodak images (``scripts/estimate_warnings.py --confidence``) the median tone-curve error is 0.43
below 0.1 (90th percentile 1.12) against 0.21-0.33 above it; at the former 0.2 the warning fired on half of
those images and of the real references while the estimates between 0.1 and 0.2 (error 0.33) were about as
good as those between 0.2 and 0.3 (0.31)."""


SEARCH_BOUNDS = {"alpha": ALPHA_BOUNDS, "gamma": GAMMA_BOUNDS}

PRIOR_DOMINATES = 0.5
"""A darkening parameter whose precision comes more than this share from the prior is reported as the prior's."""

_BOUND_MEANING = {
    ("alpha", "lower"): "darker",
    ("alpha", "upper"): "brighter",
    ("gamma", "lower"): "steeper in the shadows",
    ("gamma", "upper"): "flatter (brighter mid-tones)",
}


def _darkening_origin(name: str, value: float, found: DarkeningEstimate) -> dict[str, Any]:
    """Where an estimated alpha or gamma came from: the reference's tones, the paper's prior, or a bound."""
    share = found.prior_share.get(name)
    if name in found.bounds_hit:
        origin = f"fit, clipped to the {found.bounds_hit[name]} bound of its search range {list(SEARCH_BOUNDS[name])}"
    elif share is not None and share > PRIOR_DOMINATES:
        origin = "mostly prior: the reference's tones leave it undetermined, the paper's range sets it"
    else:
        origin = "fit to the reference's tones"
    return {"value": round(value, 4), "source": origin, "prior_share": None if share is None else round(share, 3)}


def _estimate_darkening(
    reference: torch.Tensor,
    source: str,
    ranges: dict[str, tuple[tuple[float, float], ...]],
    meta: dict[str, Any],
    warnings: list[str],
) -> Darkening | None:
    """The reference's darkening, its per-frame range for a clip, and how it was found (in ``meta``).

    A reference too dark to read gives no darkening (``apply`` then falls back to the paper's ranges) and a
    warning, not an error: the noise estimate is still good.
    """
    # The tone distribution is read on a few frames spread over the clip: more frames of one scene add time,
    # not information (all 16 frames of a 1080p clip took 6 s more).
    frames = reference[spread_frames(reference.shape[0], DARKENING_FRAMES)]
    try:
        # The pooled estimate and each frame's own (for the clip's range) from one pass over the frames.
        found, per_frame_found = estimate_darkening_pooled_and_per_frame(frames, source=source)
    except DarksynthError as error:
        warnings.append(f"{error}; the profile has no darkening, apply will draw it from the paper's ranges")
        meta["darkening"] = {
            "method": "not estimated: too dark or too flat",
            "alpha": {"source": f"prior: apply draws it from the paper's range {list(ALPHA_RANGE)}"},
            "gamma": {"source": f"prior: apply draws it from the paper's range {list(GAMMA_RANGE)}"},
        }
        return None
    # A single image has no frames to spread over: its four regions say how much the estimate depends on content.
    regions = estimate_darkening_spread(reference[:1]) if reference.shape[0] == 1 else []
    meta["darkening"] = {
        "method": "tone quantiles of 4x4 block medians fitted to the clean-image prior (docs/darkening-estimate.md)",
        "quantiles_used": found.quantiles_used,
        "fit_rms": round(found.fit_rms, 4),
        "confidence": round(found.confidence, 3),
        **{name: _darkening_origin(name, float(getattr(found.darkening, name)), found) for name in ("alpha", "gamma")},
        "region_alpha": [round(float(v), 4) for v in np.percentile([e.darkening.alpha for e in regions], [10, 90])]
        if regions
        else None,
        "region_gamma": [round(float(v), 4) for v in np.percentile([e.darkening.gamma for e in regions], [10, 90])]
        if regions
        else None,
    }
    for name, side in found.bounds_hit.items():
        low, high = SEARCH_BOUNDS[name]
        warnings.append(
            f"{source}: the fitted {name} sits on the {side} bound {high if side == 'upper' else low:g} of its "
            f"search range [{low:g}, {high:g}]: the tone curve is {_BOUND_MEANING[name, side]} than the darkening "
            "can express"
        )
    if found.confidence < LOW_DARKENING_CONFIDENCE:
        warnings.append(
            f"{source}: the darkening estimate is uncertain (confidence {found.confidence:.2f} < "
            f"{LOW_DARKENING_CONFIDENCE}: {found.quantiles_used} of {len(PROBABILITIES)} tone quantiles usable, "
            f"fit rms {found.fit_rms:.2f}{', a bound hit' if found.clipped else ''}); on held-out images such "
            "estimates have about twice the tone-curve error"
        )
    if frames.shape[0] > 1:
        per_frame = [estimated.darkening for estimated in per_frame_found if estimated is not None]
        if len(per_frame) > 1:
            for name in ("alpha", "gamma"):
                values = [getattr(d, name) for d in per_frame]
                point = getattr(found.darkening, name)
                low, high = np.percentile(values, [10, 90])
                ranges[name] = ((min(float(low), point), max(float(high), point)),)
            meta["darkening"]["ranges"] = "10th-90th percentile over frames"
    return found.darkening
