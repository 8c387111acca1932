"""Randomized round trip of the shutter estimate on real textures: dark, noisy, moving, with a known exposure fraction.

Makes: docs/motion-blur.md, "The shutter harness" (the table of median error, share off by more than 0.5 without
fallback and fallback rate per part, and the counts of fallbacks by reason). tests/estimation/test_motion.py loads
this file and runs 12 of its develop cases (seeds 200-211) and two JPEG cases against the same bars.

Run from the repo root::

    OMP_NUM_THREADS=1 PYTHONPATH=src .venv/bin/python scripts/light/shutter_harness.py --part develop --cases 160
    OMP_NUM_THREADS=1 PYTHONPATH=src .venv/bin/python scripts/light/shutter_harness.py --part check --cases 160

Options: ``[--part develop|check] [--cases 160] [--first 0] [--data ../shared/data] [--out FILE.json]``.

Each case (its own seed, fixed: ``develop`` draws seeds 0.., ``check`` seeds 100000..) takes a crop of a shared
clean image as the scene and moves it: a translation of 2-20 px/frame in any direction, and in a quarter of the
cases a slow rotation (up to 0.6 degrees/frame) and zoom (up to 1 %/frame) about the centre on top. Each of 5 frames
(192x256) is the mean, in linear light, of copies of the scene along its path over a window of ``s`` frame
intervals centred on the frame (copies at most 0.5 px apart), ``s`` uniform in [0, 1]. The frames are toned dark
(``a + b x^g`` on sRGB values, g in [1, 2.4], black offset a up to half the mean, mean level 0.02-0.35) and noised:
std 0.5-15 8-bit levels (log-uniform), white, half the cases with a shot part (variance proportional to the level),
a quarter with a share (up to a half) of the noise power fixed from frame to frame (what temporal noise reduction
or a codec leaves); 8-bit levels; half the cases JPEG (quality 60-95) per frame.

The parts: ``develop`` takes its textures from kodak24 and cbsd68 (the estimate's confidence was developed on
these); ``check`` from mcmaster and the clean halves of every shared real-pair set (sidd, nam-cc15, polyu,
nam-cc60), kept for checking only.

Prints one row per case (true s, read s, confidence, whether it fell back to the prior, speed, mean level, noise
std, JPEG, the notes), then the distribution: the median |error| over the cases that read, the share of cases off
by more than 0.5 without falling back (the bar: 0), the fallback rate, and the share off by more than 0.5 before
the fallback (what a reading without the confidence would have given).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np
import torch

from darksynth.estimation.light.motion import estimate_motion

PARTS = {
    "develop": ("clean/images/kodak24", "clean/images/cbsd68"),
    "check": (
        "clean/images/mcmaster",
        "real-pairs/sidd/clean",
        "real-pairs/nam-cc15/clean",
        "real-pairs/polyu/clean",
        "real-pairs/nam-cc60/clean",
    ),
}
"""Where each part's textures come from (under the shared data folder)."""

FIRST_SEED = {"develop": 0, "check": 100000}
"""Each part's first case seed: the two never share a drawn case."""

FRAMES = 5
"""Frames a case: four pairs, as few as a short reference clip gives."""

HEIGHT, WIDTH = 192, 256
"""Frame size: about 12 blocks of 64 px a pair, fewer once the motion carries blocks out of the frame."""

OFF_BY = 0.5
"""An error larger than this without a fallback is a wrong reading given with confidence (the issue's bar)."""


@dataclass(frozen=True)
class Case:
    """One drawn case: the texture, its motion, its shutter and its darkness and noise."""

    seed: int
    texture: str
    top: int
    left: int
    velocity: tuple[float, float]
    rotation: float
    zoom: float
    exposure: float
    black: float
    mean_level: float
    gamma: float
    noise_std: float
    shot_share: float
    persistent_share: float
    jpeg: int


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def textures(data: Path, part: str) -> list[Path]:
    return [
        p for folder in PARTS[part] for p in sorted((data / folder).glob("*")) if p.suffix.lower() in (".png", ".jpg")
    ]


def draw_case(seed: int, data: Path, paths: list[Path], sizes: dict[Path, tuple[int, int]]) -> Case:
    rng = np.random.default_rng(seed)
    path = paths[int(rng.integers(len(paths)))]
    height, width = sizes[path]
    speed, angle = rng.uniform(2.0, 20.0), rng.uniform(0.0, 2 * math.pi)
    velocity = (speed * math.sin(angle), speed * math.cos(angle))
    turning = rng.random() < 0.25
    rotation = float(rng.uniform(-0.6, 0.6)) if turning else 0.0
    zoom = float(rng.uniform(-0.01, 0.01)) if turning else 0.0
    # The crop leaves room for the path over the frames (the scene moves by +velocity in the frame, so the window
    # onto the source moves by -velocity).
    travel_y, travel_x = abs(velocity[0]) * FRAMES + 24, abs(velocity[1]) * FRAMES + 24
    top = int(rng.integers(0, max(1, int(height - HEIGHT - travel_y)))) + int(travel_y * (velocity[0] > 0))
    left = int(rng.integers(0, max(1, int(width - WIDTH - travel_x)))) + int(travel_x * (velocity[1] > 0))
    mean_level = float(rng.uniform(0.02, 0.35))
    return Case(
        seed=seed,
        texture=str(path.relative_to(data)),
        top=top,
        left=left,
        velocity=(float(velocity[0]), float(velocity[1])),
        rotation=rotation,
        zoom=zoom,
        exposure=float(rng.uniform(0.0, 1.0)),
        black=float(rng.uniform(0.0, 0.5)) * mean_level,
        mean_level=mean_level,
        gamma=float(rng.uniform(1.0, 2.4)),
        noise_std=float(math.exp(rng.uniform(math.log(0.5), math.log(15.0)))),
        shot_share=float(rng.uniform(0.3, 0.9)) if rng.random() < 0.5 else 0.0,
        persistent_share=float(rng.uniform(0.1, 0.5)) if rng.random() < 0.25 else 0.0,
        jpeg=int(rng.integers(60, 96)) if rng.random() < 0.5 else 0,
    )


def frame_at(source: np.ndarray, case: Case, time_: float) -> np.ndarray:
    """The scene (linear light, H, W, 3) as the frame sees it at ``time_`` (frames): source pixel for each frame
    pixel, a rotation and zoom about the frame's centre, then the crop moving against the scene's motion."""
    theta = math.radians(case.rotation * time_)
    scale = (1.0 + case.zoom) ** time_
    cos, sin = math.cos(theta) / scale, math.sin(theta) / scale
    centre_x, centre_y = (WIDTH - 1) / 2, (HEIGHT - 1) / 2
    # Frame pixel p -> source q = c + R (p - c) / scale - velocity * t + crop corner.
    shift_x = case.left + centre_x - cos * centre_x + sin * centre_y - case.velocity[1] * time_
    shift_y = case.top + centre_y - sin * centre_x - cos * centre_y - case.velocity[0] * time_
    matrix = np.array([[cos, -sin, shift_x], [sin, cos, shift_y]], np.float32)
    flags = cv2.INTER_LANCZOS4 | cv2.WARP_INVERSE_MAP
    return cv2.warpAffine(source, matrix, (WIDTH, HEIGHT), flags=flags, borderMode=cv2.BORDER_REFLECT)


def clean_frames(source: np.ndarray, case: Case) -> np.ndarray:
    """(T, H, W, 3) sRGB values in [0, 1]: each frame the linear-light mean over its exposure window."""
    speed = math.hypot(*case.velocity)
    copies = max(1, math.ceil(2 * case.exposure * speed) + 1)
    offsets = case.exposure * ((np.arange(copies) + 0.5) / copies - 0.5) if copies > 1 else np.zeros(1)
    out = [np.mean([frame_at(source, case, t + u) for u in offsets], axis=0) for t in range(FRAMES)]
    return np.stack([linear_to_srgb(frame) for frame in out])


def dark_noisy(frames: np.ndarray, case: Case) -> np.ndarray:
    """Toned to the case's darkness, noised, 8-bit, JPEG if drawn: (T, H, W, 3) uint8."""
    rng = np.random.default_rng(case.seed + 7919)
    toned = frames**case.gamma
    gain = (case.mean_level - case.black) / max(float(toned.mean()), 1e-6)
    signal = np.clip(case.black + gain * toned, 0.0, 1.0)
    variance = (case.noise_std / 255.0) ** 2
    shot = case.shot_share * variance * signal / max(float(signal.mean()), 1e-6)
    total = np.sqrt((1.0 - case.shot_share) * variance + shot)
    fresh = rng.standard_normal(signal.shape)
    fixed = rng.standard_normal(signal.shape[1:])[None]
    noise = math.sqrt(1.0 - case.persistent_share) * fresh + math.sqrt(case.persistent_share) * fixed
    levels = np.clip(np.round((signal + total * noise) * 255.0), 0, 255).astype(np.uint8)
    if case.jpeg:
        quality = [cv2.IMWRITE_JPEG_QUALITY, case.jpeg]
        levels = np.stack(
            [cv2.imdecode(cv2.imencode(".jpg", frame, quality)[1], cv2.IMREAD_UNCHANGED) for frame in levels]
        )
    return levels


def run_case(case: Case, data: Path) -> dict[str, object]:
    source = cv2.imread(str(data / case.texture), cv2.IMREAD_COLOR)
    linear = srgb_to_linear(source[..., ::-1].astype(np.float32) / 255.0).astype(np.float32)
    frames = dark_noisy(clean_frames(linear, case), case)
    reference = torch.from_numpy(frames).permute(0, 3, 1, 2).float() / 255.0
    start = time.perf_counter()
    found = estimate_motion(reference)
    meta = found.to_meta()
    return asdict(case) | {
        "read": found.exposure_fraction,
        "measured": found.exposure_measured,
        "confidence": meta.get("exposure_confidence"),
        "raw": (meta.get("exposure_checks") or {}).get(
            "reading", found.exposure_fraction if found.exposure_measured else None
        ),
        "checks": meta.get("exposure_checks"),
        "displacement": found.displacement,
        "blocks": found.blocks,
        "notes": [n for n in found.notes if "flicker" not in n],
        "seconds": round(time.perf_counter() - start, 2),
    }


def summary(rows: list[dict[str, object]]) -> dict[str, float]:
    """The distribution: median |error| over the readings, wrong readings kept, fallback rate."""
    read = [r for r in rows if r["measured"]]
    errors = [abs(min(float(r["read"]), 1.0) - float(r["exposure"])) for r in read]  # type: ignore[arg-type]
    raw = [r for r in rows if r["raw"] is not None]
    raw_errors = [abs(min(float(r["raw"]), 1.0) - float(r["exposure"])) for r in raw]  # type: ignore[arg-type]
    return {
        "cases": len(rows),
        "read": len(read),
        "median_error": float(np.median(errors)) if errors else math.nan,
        "p90_error": float(np.percentile(errors, 90)) if errors else math.nan,
        "off_without_fallback": sum(e > OFF_BY for e in errors) / max(len(rows), 1),
        "fallback_rate": 1.0 - len(read) / max(len(rows), 1),
        "raw_median_error": float(np.median(raw_errors)) if raw_errors else math.nan,
        "raw_off": sum(e > OFF_BY for e in raw_errors) / max(len(rows), 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--part", choices=sorted(PARTS), default="develop")
    parser.add_argument("--cases", type=int, default=160)
    parser.add_argument("--first", type=int, default=0, help="skip this many of the part's cases")
    parser.add_argument("--out", type=Path, help="write the rows and the summary as JSON here")
    args = parser.parse_args()
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    paths = textures(args.data, args.part)
    sizes = {p: cv2.imread(str(p), cv2.IMREAD_UNCHANGED).shape[:2] for p in paths}
    rows = []
    for index in range(args.first, args.first + args.cases):
        case = draw_case(FIRST_SEED[args.part] + index, args.data, paths, sizes)
        row = run_case(case, args.data)
        rows.append(row)
        speed = math.hypot(*case.velocity)
        confidence = "   - " if row["confidence"] is None else f"{row['confidence']:5.2f}"
        print(
            f"{case.seed:>6} {case.texture[-34:]:<34} s {case.exposure:4.2f} read {row['read']:4.2f} "
            f"{'   ' if row['measured'] else 'FB '}conf {confidence} v {speed:4.1f} turn {case.rotation:+.2f} "
            f"lvl {case.mean_level:.3f} std {case.noise_std:4.1f} jpeg {case.jpeg:>2} {'; '.join(row['notes'])}",  # type: ignore[arg-type]
            flush=True,
        )
    totals = summary(rows)
    print(" ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in totals.items()))
    if args.out is not None:
        args.out.write_text(json.dumps({"summary": totals, "rows": rows}, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
