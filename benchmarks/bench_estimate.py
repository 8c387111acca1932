"""Time and peak memory of estimating a profile from a 16-frame 1080p clip with the shipped DEN.

Run: ``.venv/bin/python benchmarks/bench_estimate.py [--weights W] [--repeats N]``. A synthetic clean 1080p clip
is darkened and made noisy with known parameters, written as an H.264 video, and ``darksynth estimate`` runs
on it in a child process (wall time and peak RSS of that child, from os.wait4). The last line is
``estimate_s=<median> peak_rss_mib=<max> frames=16 size=1920x1080``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import torch

from darksynth.darkening import Darkening
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.video import VideoWriter
from darksynth.noise.values import NoiseValues
from darksynth.synthesize import ClipParameters, ClipSynthesizer
from machine import cpu_summary

HEIGHT, WIDTH, FRAMES = 1080, 1920, 16


def make_reference(path: Path) -> None:
    rng = np.random.default_rng(0)
    ramp = np.linspace(0, 255, WIDTH, dtype=np.float32)[None, :, None]
    parameters = ClipParameters(
        noise=NoiseValues.from_values(
            {
                "shot": 0.08,
                "read": 0.02,
                "quantization": 0.005,
                "banding": 0.01,
                "temporal_banding": 0.01,
                "periodic": 0.005,
            }
        ),
        darkening=Darkening(alpha=0.2, gamma=0.6),
    )
    synthesizer = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(0))
    # H.264 (the writer's default), as phone videos arrive; its decoding is part of the timing.
    with VideoWriter(path, width=WIDTH, height=HEIGHT, fps=Fraction(30)) as writer:
        for _ in range(FRAMES):
            clean = np.clip(ramp + rng.normal(0, 30, (HEIGHT, 1, 3)), 0, 255).astype(np.uint8)
            clean = np.ascontiguousarray(np.broadcast_to(clean, (HEIGHT, WIDTH, 3)))
            frame = synthesizer(hwc_to_chw(clean))
            writer.write(np.ascontiguousarray(frame.permute(1, 2, 0).numpy()))


def run_once(reference: Path, weights: Path | None, extra: list[str]) -> tuple[float, float]:
    command = [sys.executable, "-m", "darksynth", "estimate", str(reference), *extra]
    if weights is not None:
        command += ["--weights", str(weights)]
    started = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    # wait4 gives this child's own peak resident size (ru_maxrss, KiB on Linux).
    _, status, usage = os.wait4(child.pid, 0)
    elapsed = time.perf_counter() - started
    if status != 0:
        raise SystemExit(f"estimate failed: {child.stderr.read().decode() if child.stderr else status}")
    return elapsed, usage.ru_maxrss / 1024


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--weights", type=Path, default=None)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-refine", action="store_true", help="time the network alone, without the refinement")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        reference = Path(folder) / "reference.mp4"
        make_reference(reference)
        extra = ["--no-refine"] if args.no_refine else []
        runs = [run_once(reference, args.weights, extra) for _ in range(args.repeats)]
    times = [t for t, _ in runs]
    peak = max(m for _, m in runs)
    print(f"runs (s, MiB): {[(round(t, 2), round(m)) for t, m in runs]}; includes process start and imports")
    print(f"estimate_s={statistics.median(times):.2f} peak_rss_mib={peak:.0f} frames={FRAMES} size={WIDTH}x{HEIGHT}")


if __name__ == "__main__":
    main()
