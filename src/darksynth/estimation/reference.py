"""Reading a reference, once, into the record every measurement reads.

A reference is an image, a video (its first frames) or, with ``clip``, a folder of frames, read as frames
(T, 3, H, W) in [0, 1] (:func:`load_reference`). :func:`describe_reference` adds what is known of them before any
measurement and what every stage needs alike (a :class:`Reference`): the frames to measure
(:func:`spread_frames`), the frames without noise to measure (:func:`uniform_frames`), the scene cuts
(:func:`scene_cuts`); :func:`reference_warnings` says what those mean for the estimate. Here too: the grid of
crops the network reads (:func:`crop_grid`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from darksynth.errors import DarksynthError
from darksynth.io.arrays import rgb_chw, unit_float_frames
from darksynth.io.discover import classify_input, scan_folder
from darksynth.io.images import read_image
from darksynth.io.video import iter_video_frames
from darksynth.light.motion_blur import SCENE_CUT_CHANGE

CROP = 128
"""Side of the square crops; the network was trained on crops of this size."""

MIN_SIDE = 32
"""References smaller than this on either side are refused: the column statistics need some extent."""

MAX_FRAMES = 16
"""Frames read from a video or frame folder: enough for temporal statistics, bounded in memory and time."""

CLIP_FRAMES = 4
"""Frames per clip given to the network (it was trained on clips of 4 and single frames)."""

FLAT_STD = 0.5 / 255
"""Below this std over all pixels of a frame (half an 8-bit level), a frame is uniform (black, saturated or flat):
it holds no noise to measure."""

MEASURED_FRAMES = 4
"""Frames (evenly spread) on which the column presence and the profile's noise level are measured: the whole
1080p clip took 1.5 s more."""

BRIGHT_MEAN = 0.35
"""A reference whose mean level is above this is not low-light; its estimate is less reliable."""


def spread_frames(total: int, count: int) -> list[int]:
    """Indices of up to ``count`` frames evenly spread over ``total`` (first and last included)."""
    return np.unique(np.linspace(0, total - 1, count).round().astype(int)).tolist()  # type: ignore[no-any-return]


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
        frames = [rgb_chw(read_image(path).pixels)]
    elif kind == "video":
        for frame in iter_video_frames(path):
            frames.append(rgb_chw(frame))
            if len(frames) == max_frames:
                break
        if not frames:
            raise DarksynthError(f"{path}: the video has no decodable frames")
    else:
        if not clip:
            raise DarksynthError(f"{path}: a folder is a reference only as a clip of frames; add --clip")
        for name in scan_folder(path).images[:max_frames]:
            image = rgb_chw(read_image(path / name).pixels)
            if frames and image.shape != frames[0].shape:
                raise DarksynthError(
                    f"{path / name}: frame size {tuple(image.shape[1:])} differs from {tuple(frames[0].shape[1:])}"
                )
            frames.append(image)
    reference = unit_float_frames(frames)
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


@dataclass(frozen=True)
class Reference:
    """A reference's frames as every measurement reads them, with what is known of them before any measurement.

    Attributes:
        frames: (T, 3, H, W) in [0, 1].
        name: how warnings name it (its path, or ``"reference"``).
        measured: up to :data:`MEASURED_FRAMES` frames spread over the clip, where the column presence and the
            profile's noise level are measured.
        uniform: frames without noise to measure (:func:`uniform_frames`).
        cuts: frames that start a new scene (:func:`scene_cuts`).
    """

    frames: torch.Tensor
    name: str
    measured: list[int]
    uniform: list[int]
    cuts: list[int]

    @property
    def all_uniform(self) -> bool:
        return len(self.uniform) == self.frames.shape[0]


def describe_reference(frames: torch.Tensor, source: str = "") -> Reference:
    """The record of reference frames (T, 3, H, W) in [0, 1] that the measurements share."""
    return Reference(
        frames=frames,
        name=source or "reference",
        measured=spread_frames(frames.shape[0], MEASURED_FRAMES),
        uniform=uniform_frames(frames),
        cuts=scene_cuts(frames),
    )


def reference_warnings(reference: Reference, *, spectrum_frames: int) -> list[str]:
    """What the reference itself makes doubtful before any measurement: uniform frames, scene cuts (the spectrum
    reads the first ``spectrum_frames`` frames), a mean level too bright for a low-light reference."""
    warnings = []
    name, frames = reference.name, reference.frames
    if reference.uniform:
        which = "the reference is" if reference.all_uniform else f"frames {reference.uniform} are"
        warnings.append(
            f"{name}: {which} uniform (black, saturated or flat: std under {FLAT_STD * 255:.1f} 8-bit level): there "
            "is no noise to measure there, and what the profile holds from them is the network's output on a flat "
            "image, not a measurement"
        )
    if reference.cuts:
        warnings.append(
            f"{name}: scene cut before frame(s) {reference.cuts}: the estimate mixes more than one scene (the "
            f"spectrum reads the first {spectrum_frames} frames, the darkening several spread over the clip); give "
            "one shot"
        )
    level = float(frames.mean())
    if level > BRIGHT_MEAN:
        warnings.append(
            f"{name}: mean level {level:.2f} is bright for a low-light reference; "
            "the estimate may be unreliable (on a clean daylight photo the profile holds what it reads of the "
            "photo's grain, JPEG residue and fine texture as noise, often several 8-bit levels)"
        )
    return warnings
