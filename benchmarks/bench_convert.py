"""Throughput and peak memory of ``darksynth convert`` on a folder dataset, with 1 and with 2 workers.

Run: ``.venv/bin/python benchmarks/bench_convert.py [--images 2000] [--width 640 --height 480]
[--workers 1,2] [--repeats 1] [--workdir DIR]``.

A class-per-folder dataset of ``--images`` JPEG images (smooth colour fields with a moving pattern, 10 classes)
is generated in this process, then ``darksynth convert DATASET OUT --format folder --profile default_profile.json``
runs as a child process (``sys.executable -m darksynth``) once per worker count and repeat, each into a fresh
output folder. Wall time is measured around the child; peak memory is the largest sum of the resident memory
of the child and all its descendants (the worker processes), sampled every 0.2 s from /proc — what a job
scheduler would count against the run.

The last line is ``images=<n> size=<w>x<h> throughput_1=<img/s> throughput_2=<img/s> ratio=<r>
peak_rss_1_mib=<m> peak_rss_2_mib=<m>`` (medians over repeats; ratio = throughput_2 / throughput_1).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from PIL import Image

from machine import cpu_summary

REPO = Path(__file__).resolve().parents[1]
PROFILE = REPO / "src" / "darksynth" / "data" / "default_profile.json"
CLASSES = 10
POLL_S = 0.2
MIB = 1024.0


def make_dataset(root: Path, images: int, width: int, height: int) -> None:
    """``images`` JPEG files in ``CLASSES`` class folders; every image differs (phase and colour)."""
    y = np.arange(height, dtype=np.float32)[:, None]
    x = np.arange(width, dtype=np.float32)[None, :]
    rng = np.random.default_rng(0)
    for index in range(images):
        phase = rng.uniform(0, 2 * np.pi)
        colour = rng.uniform(0.2, 1.0, 3)
        pattern = 0.5 + 0.4 * np.sin(x / 37 + phase) * np.cos(y / 23 - phase)
        rgb = np.stack([pattern * c + 0.05 * (x / width) for c in colour], axis=-1)
        folder = root / f"class_{index % CLASSES:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8)).save(folder / f"{index:06d}.jpg", quality=90)


def _rss_kib(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        pass
    return 0


def _tree(pid: int) -> list[int]:
    """The process and all its descendants, from /proc's children lists."""
    found, stack = [], [pid]
    while stack:
        current = stack.pop()
        found.append(current)
        for task in Path(f"/proc/{current}/task").glob("*"):
            try:
                stack.extend(int(child) for child in (task / "children").read_text().split())
            except (FileNotFoundError, ProcessLookupError):
                continue
    return found


def run_convert(dataset: Path, output: Path, workers: int) -> tuple[float, float]:
    """Seconds and peak summed RSS (MiB) of one conversion in a child process."""
    command = [
        sys.executable, "-m", "darksynth", "convert", str(dataset), str(output),
        "--format", "folder", "--profile", str(PROFILE), "--seed", "0", "--workers", str(workers),
    ]  # fmt: skip
    peak = 0
    started = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    done = threading.Event()

    def poll() -> None:
        nonlocal peak
        while not done.is_set():
            peak = max(peak, sum(_rss_kib(pid) for pid in _tree(child.pid)))
            done.wait(POLL_S)

    sampler = threading.Thread(target=poll, daemon=True)
    sampler.start()
    _, stderr = child.communicate()
    seconds = time.perf_counter() - started
    done.set()
    sampler.join()
    if child.returncode != 0:
        raise SystemExit(f"convert failed ({child.returncode}): {stderr.strip()[-2000:]}")
    return seconds, peak / MIB


def main() -> int:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--images", type=int, default=2000)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--workdir", type=Path, help="where to generate (default: a temporary folder)")
    args = parser.parse_args()
    counts = [int(w) for w in args.workers.split(",")]
    workdir = Path(tempfile.mkdtemp(prefix="bench_convert_", dir=args.workdir))
    try:
        dataset = workdir / "dataset"
        started = time.perf_counter()
        make_dataset(dataset, args.images, args.width, args.height)
        print(f"generated {args.images} images of {args.width}x{args.height} in {time.perf_counter() - started:.1f} s")
        throughput: dict[int, list[float]] = {w: [] for w in counts}
        memory: dict[int, list[float]] = {w: [] for w in counts}
        for repeat in range(args.repeats):
            for workers in counts:  # interleaved, so a slow phase of the machine hits every count alike
                output = workdir / f"out_{workers}_{repeat}"
                seconds, peak = run_convert(dataset, output, workers)
                throughput[workers].append(args.images / seconds)
                memory[workers].append(peak)
                print(
                    f"workers={workers} repeat={repeat}: {seconds:.1f} s, {args.images / seconds:.1f} images/s, "
                    f"peak RSS {peak:.0f} MiB"
                )
                shutil.rmtree(output)
        medians = {w: statistics.median(v) for w, v in throughput.items()}
        fields = [f"images={args.images}", f"size={args.width}x{args.height}"]
        fields += [f"throughput_{w}={medians[w]:.2f}" for w in counts]
        if len(counts) >= 2:
            fields.append(f"ratio={medians[counts[-1]] / medians[counts[0]]:.2f}")
        fields += [f"peak_rss_{w}_mib={statistics.median(memory[w]):.0f}" for w in counts]
        print(" ".join(fields))
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
