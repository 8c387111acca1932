"""Reference -> crops or clips -> DEN -> robust aggregate -> noise profile.

The estimate of every crop is a full v; the profile holds their median (robust to crops where content,
clipping or a light source misleads the network) and, as ``ranges``, the 10th to 90th percentile across crops,
so that ``apply`` can reproduce the spread the reference shows. The darkening (alpha, gamma) is read from the
reference's tone distribution (:mod:`darksynth.darkening_estimate`); for a clip, its ``ranges`` are the 10th
to 90th percentile of the per-frame estimates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from darksynth.darkening import Darkening
from darksynth.darkening_estimate import estimate_darkening, estimate_darkening_spread
from darksynth.errors import DarksynthError
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.discover import classify_input, scan_folder
from darksynth.io.images import read_image
from darksynth.io.video import iter_video_frames
from darksynth.models.den import DEN
from darksynth.noise.components import model_parameters
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile

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


def estimate_file(path: Path, network: DEN, options: EstimateOptions) -> Estimate:
    """Read a reference file or frame folder and estimate its profile (the ``estimate`` job)."""
    frames = load_reference(path, clip=options.clip, max_frames=options.max_frames)
    return estimate(frames, network, source=str(path), batch=options.batch, device=options.device)


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
) -> Estimate:
    """Estimate a noise profile from reference frames (T, 3, H, W) in [0, 1]."""
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
    warnings = []
    level = float(reference.mean())
    if level > BRIGHT_MEAN:
        warnings.append(
            f"{source or 'reference'}: mean level {level:.2f} is bright for a low-light reference; "
            "the estimate may be unreliable"
        )
    if noise.scalar("shot") < 0.005 and noise.scalar("read") < 0.003:
        warnings.append(f"{source or 'reference'}: nearly noise-free; the profile will add almost no noise")
    meta: dict[str, Any] = {
        "source": source,
        "estimator": f"DEN {network.config.variant} width {network.config.width} depth {network.config.depth}",
        "noise_model": noise_model,
        "crops": len(crops),
        "frames": int(reference.shape[0]),
        "aggregate": "median over crops; ranges are the 10th-90th percentiles",
    }
    if reference.shape[0] == 1:
        meta["note"] = "single image: temporal banding cannot be told from banding and is a prior, not a measurement"
    darkening = _estimate_darkening(reference, source or "reference", ranges, meta, warnings)
    profile = Profile(noise=noise, darkening=darkening, ranges=ranges, meta=meta)
    return Estimate(profile=profile, per_crop=per_crop, warnings=warnings)


DARKENING_FRAMES = 3
"""Frames (evenly spread) on which the darkening and its per-frame range are estimated."""

LOW_DARKENING_CONFIDENCE = 0.2
"""Below this confidence (:attr:`DarkeningEstimate.confidence`) the darkening estimate comes with a warning."""


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
    frames = reference[np.unique(np.linspace(0, reference.shape[0] - 1, DARKENING_FRAMES).round().astype(int))]
    try:
        found = estimate_darkening(frames, source=source)
    except DarksynthError as error:
        warnings.append(f"{error}; the profile has no darkening, apply will draw it from the paper's ranges")
        meta["darkening"] = "not estimated: too dark or too flat"
        return None
    # A single image has no frames to spread over: its four regions say how much the estimate depends on content.
    regions = estimate_darkening_spread(reference[:1]) if reference.shape[0] == 1 else []
    meta["darkening"] = {
        "method": "tone quantiles of 4x4 block medians fitted to the clean-image prior (docs/darkening-estimate.md)",
        "quantiles_used": found.quantiles_used,
        "fit_rms": round(found.fit_rms, 4),
        "confidence": round(found.confidence, 3),
        "region_alpha": [round(float(v), 4) for v in np.percentile([e.darkening.alpha for e in regions], [10, 90])]
        if regions
        else None,
        "region_gamma": [round(float(v), 4) for v in np.percentile([e.darkening.gamma for e in regions], [10, 90])]
        if regions
        else None,
    }
    if found.confidence < LOW_DARKENING_CONFIDENCE:
        warnings.append(
            f"{source}: the darkening estimate is uncertain (confidence {found.confidence:.2f}): the scene's tones "
            "are far from an average natural image's"
        )
    if frames.shape[0] > 1:
        per_frame = []
        for frame in frames:
            try:
                per_frame.append(estimate_darkening(frame, source=source).darkening)
            except DarksynthError:
                continue
        if len(per_frame) > 1:
            for name in ("alpha", "gamma"):
                values = [getattr(d, name) for d in per_frame]
                point = getattr(found.darkening, name)
                low, high = np.percentile(values, [10, 90])
                ranges[name] = ((min(float(low), point), max(float(high), point)),)
            meta["darkening"]["ranges"] = "10th-90th percentile over frames"
    return found.darkening
