"""Wall time of the command line as a user meets it: start-up, and one 1080p image through ``apply``.

Run: ``.venv/bin/python benchmarks/bench_startup.py [--repeats N]``. Each command runs N times in a child
process (interpreter start, imports and the work itself, as from a shell); medians are printed. ``apply`` makes
a 1920x1080 PNG low-light with the profile ``estimate`` writes for the shipped demo reference (written once, not
timed). The last line is ``version_s=<a> help_s=<b> apply_png_s=<c>`` (issue targets: a, b < 0.5; c < 1.5).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from machine import cpu_summary

DARKSYNTH = [sys.executable, "-m", "darksynth"]
DEMO_REFERENCE = Path(__file__).resolve().parents[1] / "src" / "darksynth" / "data" / "sample" / "reference.png"


def wall(command: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        rng = np.random.default_rng(0)
        ramp = np.linspace(0, 255, 1920, dtype=np.float32)[None, :, None]
        frame = np.clip(ramp + rng.normal(0, 20, (1080, 1920, 3)), 0, 255).astype(np.uint8)
        Image.fromarray(frame).save(root / "frame.png")
        profile = root / "profile.json"
        subprocess.run([*DARKSYNTH, "estimate", str(DEMO_REFERENCE), "--out", str(profile)], check=True)
        commands = {
            "version": [*DARKSYNTH, "--version"],
            "help": [*DARKSYNTH, "--help"],
            "apply_png": [
                *DARKSYNTH,
                "apply",
                str(root / "frame.png"),
                str(root / "out.png"),
                "-p",
                str(profile),
                "--overwrite",
            ],
        }
        times: dict[str, list[float]] = {name: [] for name in commands}
        for _ in range(args.repeats):
            for name, command in commands.items():
                (root / "out.png").unlink(missing_ok=True)
                times[name].append(wall(command))
    median = {name: statistics.median(values) for name, values in times.items()}
    for name, values in times.items():
        print(f"{name}: runs {[round(v, 2) for v in values]} s")
    print(f"version_s={median['version']:.2f} help_s={median['help']:.2f} apply_png_s={median['apply_png']:.2f}")


if __name__ == "__main__":
    main()
