"""The shutter and flicker estimate on the shared real low-light videos and clips.

Makes: docs/motion-blur.md, "The shared real clips and video" (the table of s, measured, displacement, moving
share, flicker and correlation per reference) and "The shared real clips, before and after"; docs/performance.md
("`estimate` of 16 frames of 1080p") quotes its timings.

Run from the repo root::

    PYTHONPATH=src .venv/bin/python scripts/light/motion_reference_check.py

Options: ``[--data ../shared/data] [--out FILE.json]``.

For every video under ``real-lowlight/videos`` (its first 16 frames) and every frame folder under
``real-lowlight/clips`` (read as a clip): :func:`darksynth.estimation.light.motion.estimate_motion`, printed as one row
each (exposure fraction and whether it was measured, the median speed of the blocks used in px/frame, the moving
share of the frame, the flicker and its lag-1 correlation, the notes, and the seconds the estimate took, reading
excluded); ``--out`` writes the same rows as JSON.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from darksynth.estimation.light.motion import estimate_motion
from darksynth.estimation.reference import load_reference


def references(data: Path) -> list[tuple[Path, bool]]:
    low = data / "real-lowlight"
    videos = [(p, False) for p in sorted((low / "videos").glob("*")) if p.is_file()]
    clips = [(p, True) for p in sorted((low / "clips").glob("*")) if p.is_dir()]
    return videos + clips


def check(path: Path, clip: bool) -> dict[str, Any]:
    reference = load_reference(path, clip=clip)
    start = time.perf_counter()
    found = estimate_motion(reference)
    seconds = time.perf_counter() - start
    frames, _, height, width = reference.shape
    return {"name": path.name, "frames": frames, "size": f"{width}x{height}", "seconds": round(seconds, 3)} | (
        found.to_meta()
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--out", type=Path, help="write the rows as JSON here")
    args = parser.parse_args()
    rows = [check(path, clip) for path, clip in references(args.data)]
    header = (
        f"{'name':<28} {'frames':>6} {'size':>9} {'s':>5} {'meas':>5} {'disp':>6} {'moving':>6} {'flicker':>7} "
        f"{'rho':>5} {'sec':>5}  notes"
    )
    print(header)
    for row in rows:
        print(
            f"{row['name']:<28} {row['frames']:>6} {row['size']:>9} {row['exposure_fraction']:>5.2f} "
            f"{'yes' if row['exposure_measured'] else 'no':>5} {row['displacement']:>6.2f} {row['moving_share']:>6.2f} "
            f"{row['flicker']:>7.4f} {row['flicker_correlation']:>5.2f} {row['seconds']:>5.2f}  "
            f"{'; '.join(row['notes'])}"
        )
    if args.out is not None:
        args.out.write_text(json.dumps(rows, indent=2) + "\n", encoding="utf-8")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
