"""How the writer's pixel format changes the synthetic noise a video keeps: 4:2:0 (the default) against 4:4:4.

Makes: docs/video-output.md, "What 4:2:0 does to the noise" (the table of noise std per RGB channel, Y, Cb, Cr, the
lag-1 of Cb and Cr and the file size, unencoded, yuv420p and yuv444p).

Run from the repo root::

    .venv/bin/python scripts/video/video_chroma_noise.py --frames 60 --scale 2

Options: ``[--video CLEAN] [--frames 60] [--scale 1] [--seed 0]``.

A clean clip is darkened and given noise with the shipped default profile, as ``apply`` does; the noisy frames are
encoded with the default codec and CRF in yuv420p and in yuv444p and decoded again. Against the darkened clean
frames (float, before noise and rounding), it prints for the unencoded synthetic noise and for each encoding: the
noise std per RGB channel, of BT.709 luma (Y) and chroma (Cb, Cr), and the lag-1 autocorrelation of Cb and Cr
(mean of the horizontal and vertical neighbour), all in 8-bit units, and the size of each file. The default clip is
the BSD-3 ``bikes.mp4`` of the shared data (640x272, 250 frames); ``--scale 2`` enlarges its frames bicubically.
"""

from __future__ import annotations

import argparse
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from darksynth.io.arrays import chw_to_hwc, hwc_to_chw
from darksynth.io.video import DEFAULT_CODEC, DEFAULT_CRF, VideoEncoding, VideoWriter, iter_video_frames, probe_video
from darksynth.light.darkening import darken
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import draw_clip_parameters
from darksynth.synthesize import ClipSynthesizer

DEFAULT_VIDEO = Path(__file__).resolve().parents[3] / "shared" / "data" / "clean" / "videos" / "bikes.mp4"

# BT.709, the matrix the writer tags H.264 with: RGB differences -> Y, Cb, Cr in the same units.
_TO_YCBCR = np.array(
    [
        [0.2126, 0.7152, 0.0722],
        [-0.2126 / 1.8556, -0.7152 / 1.8556, 0.9278 / 1.8556],
        [0.7874 / 1.5748, -0.7152 / 1.5748, -0.0722 / 1.5748],
    ]
)


class NoiseStats:
    """Running sums over frames of (H, W, 3) noise maps: channel and YCbCr std, chroma lag-1 autocorrelation."""

    def __init__(self) -> None:
        self.count = 0
        self.sums = np.zeros(6)
        self.squares = np.zeros(6)
        self.lag_products = np.zeros(2)
        self.lag_squares = np.zeros(2)

    def add(self, noise: np.ndarray) -> None:
        ycbcr = noise @ _TO_YCBCR.T
        planes = np.concatenate([noise, ycbcr], axis=2).reshape(-1, 6)
        self.count += planes.shape[0]
        self.sums += planes.sum(0)
        self.squares += (planes**2).sum(0)
        for index, plane in enumerate((ycbcr[..., 1], ycbcr[..., 2])):
            centred = plane - plane.mean()
            # Mean of the horizontal and vertical lag-1 products, over the frame's own variance.
            products = (centred[:, 1:] * centred[:, :-1]).mean() + (centred[1:] * centred[:-1]).mean()
            self.lag_products[index] += products / 2
            self.lag_squares[index] += (centred**2).mean()

    def row(self) -> list[float]:
        mean = self.sums / self.count
        std = np.sqrt(self.squares / self.count - mean**2)
        return [*std, *(self.lag_products / self.lag_squares)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--video", type=Path, default=DEFAULT_VIDEO)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--scale", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(2)

    info = probe_video(args.video)
    width, height = round(info.width * args.scale) // 2 * 2, round(info.height * args.scale) // 2 * 2
    profile = load_profile(default_profile_path())
    generator = torch.Generator().manual_seed(args.seed)
    parameters = draw_clip_parameters(profile, generator=generator)
    if parameters.darkening is None:
        raise SystemExit("the default profile has no darkening")
    synthesizer = ClipSynthesizer(parameters, generator=generator)
    alpha, gamma = parameters.darkening.alpha, parameters.darkening.gamma

    dark_frames: list[np.ndarray] = []
    noisy_frames: list[np.ndarray] = []
    for index, frame in enumerate(iter_video_frames(args.video)):
        if index == args.frames:
            break
        if (width, height) != (info.width, info.height):
            frame = np.asarray(Image.fromarray(frame).resize((width, height), Image.Resampling.BICUBIC))
        clean = hwc_to_chw(frame)
        dark = darken(clean.to(torch.float64)[None] / 255, alpha, gamma)[0] * 255
        dark_frames.append(chw_to_hwc(dark))
        noisy_frames.append(chw_to_hwc(synthesizer(clean)))

    results: dict[str, tuple[list[float], int]] = {}
    synthetic = NoiseStats()
    for noisy, dark in zip(noisy_frames, dark_frames, strict=True):
        synthetic.add(noisy.astype(np.float64) - dark)
    results["synthetic, not encoded"] = (synthetic.row(), 0)
    with tempfile.TemporaryDirectory() as folder:
        for pix_fmt in ("yuv420p", "yuv444p"):
            path = Path(folder) / f"{pix_fmt}.mp4"
            with VideoWriter(
                path, width=width, height=height, fps=Fraction(info.fps), encoding=VideoEncoding(pix_fmt=pix_fmt)
            ) as writer:
                for noisy in noisy_frames:
                    writer.write(noisy)
            stats = NoiseStats()
            for decoded, dark in zip(iter_video_frames(path), dark_frames, strict=True):
                stats.add(decoded.astype(np.float64) - dark)
            results[f"{DEFAULT_CODEC} CRF {DEFAULT_CRF} {pix_fmt}"] = (stats.row(), path.stat().st_size)

    print(
        f"{args.video.name}: {len(noisy_frames)} frames {width}x{height}, seed {args.seed}, alpha {alpha} gamma {gamma}"
    )
    header = "| noise (8-bit units) | R std | G std | B std | Y std | Cb std | Cr std | Cb lag-1 | Cr lag-1 | file |"
    print(header)
    print("|---" * (header.count("|") - 1) + "|")
    for name, (row, size) in results.items():
        cells = [f"{v:.2f}" for v in row[:6]] + [f"{v:.3f}" for v in row[6:]]
        file = f"{size / 2**20:.1f} MiB" if size else "-"
        print(f"| {name} | {' | '.join(cells)} | {file} |")


if __name__ == "__main__":
    main()
