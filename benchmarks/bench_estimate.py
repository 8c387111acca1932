"""Time and peak memory of estimating a profile from a 16-frame 1080p clip with the shipped DEN.

Run: ``.venv/bin/python benchmarks/bench_estimate.py [--weights W] [--repeats N] [--photo [--data D]]
[--reference FILE] [--camera-prior]``. A synthetic clean 1080p clip is darkened and made noisy with known
parameters, written as an H.264 video, and ``darksynth estimate`` runs on it in a child process (wall time and peak
RSS of that child, from os.wait4); ``--reference`` times a file made before (the same one for two commits compared);
``--camera-prior`` times the estimate with the camera prior (its cost: the two runs' ratio). The last line is
``estimate_s=<median> cpu_s=<median> peak_rss_mib=<max> frames=16 size=1920x1080`` (cpu_s: the child's user and
system time, which waiting for a busy machine's processors does not inflate).

``--photo``: one 12 MP photo instead (4000x3000 PNG): a shared Kodak image (kodim01) upscaled, darkened and made
noisy the same way, a real scene's texture over the whole frame.
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

import cv2
import numpy as np
import torch

from darksynth.io.arrays import hwc_to_chw
from darksynth.io.video import VideoWriter
from darksynth.light.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer
from machine import cpu_summary

HEIGHT, WIDTH, FRAMES = 1080, 1920, 16
PHOTO_HEIGHT, PHOTO_WIDTH = 3000, 4000
PHOTO_SOURCE = "clean/images/kodak24/kodim01.png"


def _synthesizer() -> ClipSynthesizer:
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
    return ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(0))


def make_reference(path: Path) -> None:
    rng = np.random.default_rng(0)
    ramp = np.linspace(0, 255, WIDTH, dtype=np.float32)[None, :, None]
    synthesizer = _synthesizer()
    # H.264 (the writer's default), as phone videos arrive; its decoding is part of the timing.
    with VideoWriter(path, width=WIDTH, height=HEIGHT, fps=Fraction(30)) as writer:
        for _ in range(FRAMES):
            clean = np.clip(ramp + rng.normal(0, 30, (HEIGHT, 1, 3)), 0, 255).astype(np.uint8)
            clean = np.ascontiguousarray(np.broadcast_to(clean, (HEIGHT, WIDTH, 3)))
            frame = synthesizer(hwc_to_chw(clean))
            writer.write(np.ascontiguousarray(frame.permute(1, 2, 0).numpy()))


def make_photo(path: Path, data: Path) -> None:
    source = cv2.imread(str(data / PHOTO_SOURCE), cv2.IMREAD_COLOR_RGB)
    clean = cv2.resize(source, (PHOTO_WIDTH, PHOTO_HEIGHT), interpolation=cv2.INTER_CUBIC)
    photo = _synthesizer()(hwc_to_chw(clean))
    cv2.imwrite(str(path), cv2.cvtColor(np.ascontiguousarray(photo.permute(1, 2, 0).numpy()), cv2.COLOR_RGB2BGR))


def run_once(reference: Path, weights: Path | None, extra: list[str]) -> tuple[float, float, float]:
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
    # The child's processor time beside its wall time: on a shared machine the wall time includes waiting.
    return elapsed, usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--weights", type=Path, default=None)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--photo", action="store_true", help="one 12 MP photo (PNG) instead of the 1080p clip")
    parser.add_argument("--reference", type=Path, default=None, help="time this file instead of making one")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    parser.add_argument("--no-refine", action="store_true", help="time the network alone (no spectrum)")
    parser.add_argument("--camera-prior", action="store_true", help="take the texture dependence from the camera prior")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.reference is not None:
            reference = args.reference
        elif args.photo:
            reference = Path(folder) / "photo12mp.png"
            make_photo(reference, args.data)
        else:
            reference = Path(folder) / "reference.mp4"
            make_reference(reference)
        extra = (["--no-refine"] if args.no_refine else []) + (["--camera-prior"] if args.camera_prior else [])
        runs = [run_once(reference, args.weights, extra) for _ in range(args.repeats)]
    times = [t for t, _, _ in runs]
    peak = max(m for _, m, _ in runs)
    print(
        f"runs (wall s, MiB, cpu s): {[(round(t, 2), round(m), round(c, 2)) for t, m, c in runs]}; includes process "
        f"start and imports; load average before {os.getloadavg()[0]:.1f}"
    )
    cpu = statistics.median(c for _, _, c in runs)
    shape = f"frames=1 size={PHOTO_WIDTH}x{PHOTO_HEIGHT}" if args.photo else f"frames={FRAMES} size={WIDTH}x{HEIGHT}"
    if args.reference is not None:
        shape = f"reference={args.reference.name}"
    print(f"estimate_s={statistics.median(times):.2f} cpu_s={cpu:.2f} peak_rss_mib={peak:.0f} {shape}")


if __name__ == "__main__":
    main()
