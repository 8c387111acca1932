"""How long is the blur that ``apply`` draws on a real clean video, against the motion it follows?

Makes: docs/motion-blur.md, "The blur drawn on a real clean video" (the median blur length over s times the
displacement, its quartiles and block count, and the mean change of still pixels).

Run from the repo root::

    PYTHONPATH=src .venv/bin/python scripts/light/motion_blur_check.py

Options: ``[--video ../shared/data/clean/videos/bikes.mp4] [--frames 40] [--s 1.0]``.

On bikes.mp4 (../shared/data/clean/videos), every frame is blurred with exposure fraction ``s`` (default 1, a
360-degree shutter) by :class:`darksynth.light.motion_blur.MotionBlurStream`. The blur length is then measured on
the result, independently of the flow the blur used: in each 32x32 block that moves (|d| >= 2 px per frame by a
finer flow, OpenCV Farneback at full resolution, consistent over the block) and has edges across its motion,
the unblurred frame is blurred by a straight path of length L along the block's motion (in linear light) for L on
a grid, and the L that best matches the blurred frame is the block's blur length. The figure is the median over
blocks of L / (s * |d|), wanted within 0.8-1.2; still parts (s * |d| < 0.5 px) must stay within 0.5 of a level.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import cv2
import numpy as np

from darksynth.io.video import iter_video_frames
from darksynth.light.linear_light import decode
from darksynth.light.motion_blur import MotionBlurStream, line_kernel

VIDEO = Path(__file__).resolve().parents[3] / "shared" / "data" / "clean" / "videos" / "bikes.mp4"
BLOCK = 32


def fine_flow(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    grey = [cv2.cvtColor(f, cv2.COLOR_RGB2GRAY) for f in (a, b)]
    return cv2.calcOpticalFlowFarneback(grey[0], grey[1], None, 0.5, 4, 21, 5, 7, 1.5, 0)  # type: ignore[call-overload,no-any-return]


def block_length(sharp: np.ndarray, blurred: np.ndarray, velocity: np.ndarray, top: int, left: int) -> float | None:
    """The blur length that best turns the sharp block into the blurred one, or None for a block without edges
    across its motion or with mixed motion."""
    flow = velocity[top : top + BLOCK, left : left + BLOCK]
    mean = flow.reshape(-1, 2).mean(axis=0)
    speed = float(np.hypot(*mean))
    if speed < 2.0 or float(np.abs(flow - mean).mean()) > 0.15 * speed:
        return None
    angle = math.degrees(math.atan2(-mean[1], mean[0]))
    pad = math.ceil(speed * 1.5) + 4
    y0, y1 = max(0, top - pad), min(sharp.shape[0], top + BLOCK + pad)
    x0, x1 = max(0, left - pad), min(sharp.shape[1], left + BLOCK + pad)
    if y0 != top - pad or x0 != left - pad or y1 != top + BLOCK + pad or x1 != left + BLOCK + pad:
        return None
    linear = decode(sharp[y0:y1, x0:x1])
    target = decode(blurred[y0:y1, x0:x1])[pad:-pad, pad:-pad]
    # Edges across the motion: the directional derivative along it must carry signal.
    along = np.array([math.cos(math.radians(angle)), -math.sin(math.radians(angle))], np.float32)
    gx = cv2.Sobel(linear, cv2.CV_32F, 1, 0)[pad:-pad, pad:-pad]
    gy = cv2.Sobel(linear, cv2.CV_32F, 0, 1)[pad:-pad, pad:-pad]
    if float(np.abs(gx * along[0] + gy * along[1]).mean()) < 0.02:
        return None
    lengths = np.arange(0.0, 2.0 * speed + 0.01, 0.25)
    errors = []
    for length in lengths:
        candidate = linear if length < 0.5 else cv2.filter2D(linear, -1, line_kernel(float(length), angle))
        errors.append(float(np.abs(candidate[pad:-pad, pad:-pad] - target).mean()))
    best = int(np.argmin(errors))
    if best == len(lengths) - 1:
        return None
    return float(lengths[best])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--video", type=Path, default=VIDEO)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--s", type=float, default=1.0)
    args = parser.parse_args()
    frames = [f for _, f in zip(range(args.frames), iter_video_frames(args.video), strict=False)]
    blurred = list(MotionBlurStream(args.s).run(iter(frames)))
    ratios: list[float] = []
    still_max, still_sum, still_count = 0.0, 0.0, 0
    for t in range(1, len(frames) - 1):
        velocity = (fine_flow(frames[t], frames[t + 1]) - fine_flow(frames[t], frames[t - 1])) / 2
        speed = np.hypot(velocity[..., 0], velocity[..., 1]) * args.s
        difference = np.abs(blurred[t].astype(np.float64) - frames[t].astype(np.float64))
        # Still by the fine flow, away from moving pixels (the blur of a neighbour reaches a few pixels over).
        moving = cv2.dilate((speed >= 0.5).astype(np.uint8), np.ones((15, 15), np.uint8)) > 0
        still = ~moving
        still_count += int(still.sum())
        still_sum += float(difference[still].sum() / difference.shape[-1])
        still_max = max(still_max, float(difference[still].max()) if still.any() else 0.0)
        for top in range(0, frames[t].shape[0] - BLOCK + 1, BLOCK):
            for left in range(0, frames[t].shape[1] - BLOCK + 1, BLOCK):
                length = block_length(frames[t], blurred[t], velocity, top, left)
                if length is not None:
                    block = velocity[top : top + BLOCK, left : left + BLOCK].reshape(-1, 2).mean(axis=0)
                    ratios.append(length / (args.s * float(np.hypot(*block))))
    print(f"video {args.video.name}: {len(frames)} frames {frames[0].shape[1]}x{frames[0].shape[0]}, s = {args.s}")
    if ratios:
        q = np.percentile(ratios, [25, 50, 75])
        print(f"moving blocks measured: {len(ratios)}; blur length / (s * flow displacement): median {q[1]:.3f} "
              f"(quartiles {q[0]:.3f}-{q[2]:.3f}); wanted 0.8-1.2")  # fmt: skip
    else:
        print("no moving block with edges across its motion was found")
    print(f"still pixels: {still_count}; mean change {still_sum / max(1, still_count):.4f} levels, "
          f"largest {still_max:.0f}; wanted within 0.5 level")  # fmt: skip


if __name__ == "__main__":
    main()
