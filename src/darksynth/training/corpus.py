"""Clean training material held in memory: still images and clips (frame folders, videos)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.io.discover import classify_input, scan_folder
from darksynth.io.images import Image, read_image
from darksynth.io.video import iter_video_frames

MAX_CLIP_FRAMES = 64
"""Frames kept per clip: training draws short windows, and the corpus stays small in memory."""


@dataclass
class CleanCorpus:
    """Images (H, W, 3) and clips (N, H, W, 3), uint8 RGB, with the files they came from."""

    images: list[np.ndarray] = field(default_factory=list)
    clips: list[np.ndarray] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.images) + len(self.clips)


def _rgb8(image: Image) -> np.ndarray:
    pixels = image.pixels
    if pixels.dtype == np.uint16:
        pixels = (pixels.astype(np.float32) / 257.0 + 0.5).astype(np.uint8)
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return np.ascontiguousarray(pixels)


def _add_video(corpus: CleanCorpus, path: Path) -> None:
    corpus.clips.append(np.stack(list(itertools.islice(iter_video_frames(path), MAX_CLIP_FRAMES))))
    corpus.sources.append(str(path))


def load_corpus(data: Sequence[Path], clip_roots: Sequence[Path] = (), *, minimum_side: int = 64) -> CleanCorpus:
    """Read training material.

    Args:
        data: images, folders of images (recursive) and videos; images count as stills, videos as clips.
        clip_roots: folders whose sub-folders of images are clips (frames in name order) and whose videos
            are clips.
        minimum_side: images or clips smaller than this on either side are left out.

    Raises:
        DarksynthError: a path that does not exist, or no usable material at all.
    """
    corpus = CleanCorpus()
    for root in data:
        kind = classify_input(root)
        if kind == "video":
            _add_video(corpus, root)
            continue
        listing = scan_folder(root) if kind == "folder" else None
        images = [root / p for p in listing.images] if listing else [root]
        for path in images:
            corpus.images.append(_rgb8(read_image(path)))
            corpus.sources.append(str(path))
        for path in listing.videos if listing else []:
            _add_video(corpus, root / path)
    for root in clip_roots:
        listing = scan_folder(root)
        folders: dict[Path, list[Path]] = {}
        for relative in listing.images:
            folders.setdefault(relative.parent, []).append(relative)
        for folder, frames in sorted(folders.items()):
            stack = [_rgb8(read_image(root / f)) for f in sorted(frames)[:MAX_CLIP_FRAMES]]
            if len({s.shape for s in stack}) != 1:
                raise DarksynthError(f"{root / folder}: the frames of a clip must all have one size")
            corpus.clips.append(np.stack(stack))
            corpus.sources.append(str(root / folder))
        for relative in listing.videos:
            _add_video(corpus, root / relative)
    corpus.images = [i for i in corpus.images if min(i.shape[:2]) >= minimum_side]
    corpus.clips = [c for c in corpus.clips if min(c.shape[1:3]) >= minimum_side]
    if not len(corpus):
        raise DarksynthError(f"no training images or clips of at least {minimum_side} pixels were found")
    return corpus


def sample_clean_clips(
    corpus: CleanCorpus,
    batch: int,
    frames: int,
    crop: int,
    *,
    clip_fraction: float = 0.5,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """A batch of clean clips (B, T, 3, crop, crop) in [0, 1].

    Clips come from videos (consecutive frames) with probability ``clip_fraction`` when there are any, else
    from a still image repeated T times (a static scene: its noise still changes every frame). Crops start
    at columns that are multiples of 4 so that the phase of periodic noise relative to the crop is the one
    it has relative to the frame. A random vertical flip adds variety without moving columns.
    """

    def integer(high: int) -> int:
        return int(torch.randint(0, max(high, 1), (), generator=generator))

    out = torch.empty(batch, frames, 3, crop, crop)
    for index in range(batch):
        use_clip = bool(corpus.clips) and (
            not corpus.images or float(torch.rand((), generator=generator)) < clip_fraction
        )
        if use_clip:
            clip = corpus.clips[integer(len(corpus.clips))]
            start = integer(clip.shape[0] - frames + 1)
            window = clip[start : start + frames]
            if window.shape[0] < frames:
                window = np.concatenate([window, window[::-1]] * frames)[:frames]
        else:
            image = corpus.images[integer(len(corpus.images))]
            window = np.broadcast_to(image, (frames, *image.shape))
        height, width = window.shape[1:3]
        top = integer(height - crop + 1)
        left = 4 * integer((width - crop) // 4 + 1)
        patch = torch.from_numpy(np.ascontiguousarray(window[:, top : top + crop, left : left + crop]))
        patch = patch.permute(0, 3, 1, 2).float() / 255.0
        if float(torch.rand((), generator=generator)) < 0.5:
            patch = patch.flip(-2)
        out[index] = patch
    return out
