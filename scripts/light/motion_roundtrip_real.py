"""The shutter estimate on real scenes: real motion and texture, blurred with a known exposure fraction by `apply`.

Makes: docs/motion-blur.md, "Real scenes with a known blur" (the table of the exposure fraction read per video,
clean and for s = 0, 0.25, 0.5, 1).

Run from the repo root::

    PYTHONPATH=src .venv/bin/python scripts/light/motion_roundtrip_real.py

Options: ``[--data ../shared/data] [--profile P] [--only NAME ...] [--out FILE.json]``.

No real low-light clip comes with its shutter, so the estimator (``estimation.light.motion``) is checked here on the
shared clean videos, which are real footage: their motion is a real camera's and real objects' (parallax, several
movers, occlusions), their texture is real, and they come with a short shutter of their own (daylight: a GoPro or a
camcorder in sun exposes for a small share of the frame interval). For each video:

- ``clean``: the estimate on the clean video as it is (bright, the camera's own shutter: near 0 expected);
- ``s = 0``: ``darksynth apply --no-blur`` with a real reference's profile (darkened, noised, encoded with
  libx264), then the estimate on that output: what darkening, noise and compression alone read as;
- ``s = 0.25, 0.5, 1.0``: the same with the profile's ``light`` section set to that exposure fraction (no flicker),
  so ``apply`` blurs along the clean video's own optical flow before darkening and noise.

The profile is estimated once from a real low-light clip (clip1021; ``--profile`` to give one). What it shows:
whether the estimator finds a known blur through a real scene's motion and a real camera's noise and compression
(the synthetic round trip of tests/estimation/test_motion.py uses a translated pattern). What it cannot show: the
exposure fraction of a real night clip, which stays unvalidated (docs/motion-blur.md). Prints one row a video and
``s``; ``--out`` writes them as JSON.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from darksynth.estimation.light.motion import estimate_motion
from darksynth.estimation.reference import load_reference

FRACTIONS = (0.25, 0.5, 1.0)
REFERENCE_CLIP = "real-lowlight/clips/clip1021"
"""The reference whose noise and darkness the outputs take: a handheld phone clip at night (its own exposure
fraction reads 0.49)."""


def _darksynth(*arguments: str) -> None:
    command = [str(Path(sys.executable).with_name("darksynth")), *arguments]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"darksynth {' '.join(arguments)} failed: {done.stderr.strip().splitlines()[-1:]}")


def videos(data: Path) -> list[tuple[Path, bool]]:
    """The clean videos (files) and frame folders (clips) under ``clean/videos``."""
    root = data / "clean" / "videos"
    return [(path, path.is_dir()) for path in sorted(root.iterdir()) if path.is_dir() or path.suffix == ".mp4"]


def estimate(path: Path, clip: bool) -> dict[str, Any]:
    found = estimate_motion(load_reference(path, clip=clip))
    return {
        "s": round(found.exposure_fraction, 3),
        "measured": found.exposure_measured,
        "displacement": round(found.displacement, 2),
        "blocks": found.blocks,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--profile", type=Path, help="the profile to apply (default: estimated from clip1021)")
    parser.add_argument("--only", nargs="*", help="only these videos (names under clean/videos)")
    parser.add_argument("--out", type=Path, help="write the rows as JSON here")
    args = parser.parse_args()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="darksynth-motion-real-") as scratch:
        work = Path(scratch)
        profile_path = args.profile
        if profile_path is None:
            profile_path = work / "reference.json"
            _darksynth("estimate", str(args.data / REFERENCE_CLIP), "--clip", "--out", str(profile_path), "--quiet")
        document = json.loads(profile_path.read_text())
        for source, clip in videos(args.data):
            if args.only and source.name not in args.only:
                continue
            row: dict[str, Any] = {"video": source.name, "clean": estimate(source, clip)}
            for fraction in (0.0, *FRACTIONS):
                document["version"] = max(5, int(document.get("version", 1)))
                document["light"] = {"exposure_fraction": fraction, "flicker": 0.0, "flicker_correlation": 0.0}
                profile = work / f"s{fraction}.json"
                profile.write_text(json.dumps(document))
                # A clip (frame folder) comes out as a frame folder (PNG, no codec); a video as an mp4 (libx264).
                output = work / (f"{source.stem}_s{fraction}" + ("" if clip else ".mp4"))
                options = ["--no-flicker", "--seed", "0", "--quiet"] + (["--no-blur"] if fraction == 0 else [])
                _darksynth("apply", str(source), str(output), "--profile", str(profile), *options, *(["--clip"] * clip))
                row[f"s={fraction}"] = estimate(output, clip)
            rows.append(row)
            cells = "  ".join(
                f"{key} {value['s']:.2f}{'' if value['measured'] else '*'} ({value['displacement']:.1f} px)"
                for key, value in row.items()
                if key != "video"
            )
            print(f"{row['video']:<22} {cells}", flush=True)
    print("* the prior: not measured (too little motion or too few moving textured blocks)")
    if args.out is not None:
        args.out.write_text(json.dumps(rows, indent=2) + "\n", encoding="utf-8")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
