"""Whether a reference shows the 8-px block grid of JPEG, on every shared real reference and on the round trip's
kind of image with and without JPEG: the evidence a gate on the camera prior's texture dependence would read.

Makes: docs/spectral-noise.md, "What falls short, and what was tried", the bullet on a JPEG-grid gate for the texture
dependence.

Run from the repo root::

    .venv/bin/python scripts/noise/jpeg_grid_check.py --data ../shared/data

The statistic, per axis: the mean absolute difference of neighbouring pixels (the channels' mean, 8-bit levels,
each difference capped at 6 levels so that edges do not decide it), for each of the 8 phases of the pixel position
modulo 8. A decoded JPEG steps at its blocks' boundaries, one phase in 8; a grid of another period steps at two or
more (a 4-px period at two phases 4 apart). The score is the largest phase's mean over the median of the six phases
that are neither it nor the one 4 away, and the 4-px share the one 4 away over the same median; an axis shows the
JPEG grid when its score is at least 1.3 and its 4-px share rises less than half as far above 1 (a JPEG's blocks
also step a little at their middles; a 4-px period steps as much at both). Printed: per folder, the scores (the smaller
of the two axes), how many images show the grid on both axes; per synthetic kind the same.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import torch

from darksynth.estimation.noise.jpeg_grid import jpeg_grid
from darksynth.estimation.reference import load_reference
from darksynth.evaluation.pairs import list_pair_set
from darksynth.io.discover import IMAGE_SUFFIXES
from darksynth.noise.compression import jpeg_compress


def shows_grid(frame: torch.Tensor) -> tuple[bool, float]:
    """(both axes show the JPEG grid, the smaller axis score), as :func:`darksynth.estimation.noise.jpeg_grid.jpeg_grid`
    reads them."""
    found = jpeg_grid(frame)
    return found.shown, found.score


def _summary(name: str, readings: list[tuple[bool, float]]) -> str:
    scores = sorted(score for _, score in readings)
    shown = sum(grid for grid, _ in readings)
    return (
        f"{name:24s} {len(readings):3d} images  grid on {shown:3d}  score median {statistics.median(scores):.2f} "
        f"range {scores[0]:.2f}-{scores[-1]:.2f}"
    )


def _images(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith("."))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    arguments = parser.parse_args()
    data = arguments.data
    for pair_set in ("sidd", "sidd-phones", "nam-cc15", "nam-cc60", "polyu"):
        pairs = list_pair_set(data / "real-pairs" / pair_set).pairs
        print(_summary(f"pairs/{pair_set}", [shows_grid(load_reference(p.noisy_path)[0]) for p in pairs]), flush=True)
    for folder in ("dicm", "lime", "lol"):
        photos = _images(data / "real-lowlight" / "images" / folder)
        print(_summary(f"photos/{folder}", [shows_grid(load_reference(p)[0]) for p in photos]), flush=True)
    clips = sorted(p for p in (data / "real-lowlight" / "clips").iterdir() if p.is_dir())
    readings = [shows_grid(load_reference(clip, clip=True, max_frames=1)[0]) for clip in clips]
    readings.append(shows_grid(load_reference(data / "real-lowlight" / "videos" / "starlight_submillilux.mov")[0]))
    print(_summary("clips and the video", readings), flush=True)
    generator = torch.Generator().manual_seed(0)
    cleans = [load_reference(p)[0] for p in _images(data / "clean" / "images" / "kodak24")]
    noisy = [(0.25 * clean + 0.012 * torch.randn(clean.shape, generator=generator)).clamp(0, 1) for clean in cleans]
    noisy = [(image * 255.0).round() / 255.0 for image in noisy]
    print(_summary("kodak24 + noise", [shows_grid(image) for image in noisy]))
    for quality in (95, 80, 60):
        compressed = [jpeg_compress(image, quality) for image in noisy]
        print(_summary(f"kodak24 + noise, JPEG {quality}", [shows_grid(image) for image in compressed]), flush=True)


if __name__ == "__main__":
    main()
