"""Development harness for the frame-to-frame correlation of the noise: drawn clips with known AR(1) coefficients.

Makes: docs/spectral-noise.md, "Measured" (the bullet "Frame to frame, drawn clips": the table of |AR error| and
check gap per version of the code, where the persistence fit was developed); src/darksynth/estimation/
persistence_fit.py quotes it. A development harness: kept to check any change to the persistence fit.

Run from the repo root::

    .venv/bin/python scripts/noise/temporal_harness.py --cases 20 --first-seed 0

Options: ``[--data ../shared/data] [--cases 24] [--first-seed 0] [--out cases.jsonl]``. It imports the camera-like
spectrum and the darkening draw of ``benchmarks/estimate_roundtrip.py`` (it puts ``benchmarks/`` on the path).

Each case (its own seed): a clean crop of a shared image (kodak24, cbsd68, mcmaster; 384 px a side), darkened as
the round trip darkens, made into a 4-frame clip of a still scene; in half the cases a rectangle of it (a third of
the width) moves by 2-6 px per frame (a moving part the estimate must leave out). Noise of the spectral model: a
camera-like spectrum (``benchmarks/estimate_roundtrip.py``), a level of 1-12 8-bit levels, per octave an AR(1)
coefficient in [0, 0.9] (a straight line in the octave from a drawn fine to a drawn coarse value), JPEG quality 80
or 60 in a third of the cases. The clip is estimated (``estimation.noise.spectrum.estimate_spectrum``, what ``estimate``
runs for the spectrum) and compared:

* the estimated coefficient per octave against the truth (the three finest octaves, 2-16 px, carry most of what a
  viewer and ``evaluation.structure.temporal_lag_correlation`` see);
* the check's figure on the clip's own scene: ``temporal_lag_correlation`` of the noisy clip, and of the same dark
  clip made noisy with the estimated values (another seed), a fair version of
  ``scripts/noise/spectral_temporal_check.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.noise.spectrum import estimate_spectrum
from darksynth.evaluation.measures.structure import temporal_lag_correlation
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import read_image
from darksynth.light.darkening import darken
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES
from darksynth.noise.values import NoiseValues
from estimate_roundtrip import _camera_spectrum, _log_uniform, _uniform, draw_darkening, run_cases

IMAGE_SETS = ("clean/images/kodak24", "clean/images/cbsd68", "clean/images/mcmaster")
SIDE = 384
FRAMES = 4
FINE_OCTAVES = 3


def draw_crop(data: Path, generator: np.random.Generator) -> tuple[str, torch.Tensor]:
    """A random crop (3, SIDE, SIDE) or smaller in [0, 1] of a random image of a random set."""
    folder = data / IMAGE_SETS[int(generator.integers(len(IMAGE_SETS)))]
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in {".png", ".jpg", ".jpeg", ".bmp", ".tif"})
    path = paths[int(generator.integers(len(paths)))]
    image = hwc_to_chw(read_image(path).pixels).to(torch.float32) / 255.0
    height, width = image.shape[-2:]
    top = int(generator.integers(max(height - SIDE, 0) + 1))
    left = int(generator.integers(max(width - SIDE, 0) + 1))
    return f"{folder.name}/{path.name}", image[:, top : top + SIDE, left : left + SIDE]


def still_clip_with_moving_part(clean: torch.Tensor, step: int) -> torch.Tensor:
    """(FRAMES, 3, H, W): the image in every frame, its right third rolled by ``step`` px more each frame (0: still)."""
    frames = clean[None].repeat(FRAMES, 1, 1, 1)
    if step:
        third = clean.shape[-1] // 3
        for t in range(1, FRAMES):
            frames[t, :, :, -third:] = torch.roll(clean[:, :, -third:], shifts=(t * step, t * step), dims=(1, 2))
    return frames


def draw_noise(generator: np.random.Generator) -> tuple[dict[str, Any], list[float]]:
    """Spectral noise values (level 1-12 8-bit levels, camera-like spectrum, AR(1) per octave, JPEG a third of the
    time) and the coefficients drawn."""
    level = _log_uniform(generator, 1.0, 12.0) / 255.0
    shot_share = _uniform(generator, 0.0, 0.8)
    gains = (_uniform(generator, 0.8, 1.5), 1.0, _uniform(generator, 0.8, 1.5))
    curve = [g * level * np.sqrt((1 - shot_share) + shot_share * 4 * x) for g in gains for x in LEVEL_KNOTS]
    power, correlation = _camera_spectrum(generator)
    fine, coarse = _uniform(generator, 0.0, 0.9), _uniform(generator, 0.0, 0.9)
    temporal = [float(fine + (coarse - fine) * k / (OCTAVES - 1)) for k in range(OCTAVES)]
    values: dict[str, Any] = {
        "level_curve": [float(c) for c in curve],
        "octave_power": power,
        "octave_correlation": correlation,
        "temporal_correlation": temporal,
    }
    if generator.uniform() < 1 / 3:
        values["compression"] = (0.2, 0.4)[int(generator.integers(2))]
    return values, temporal


def noisy_clip(dark: torch.Tensor, values: NoiseValues, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    return quantised(add_noise(dark[None], values, generator=generator)[0])


def check_figure(clip: torch.Tensor) -> float:
    return temporal_lag_correlation(clip.permute(0, 2, 3, 1).double().numpy())


def run_case(data: Path, seed: int) -> dict[str, Any]:
    generator = np.random.default_rng(seed)
    name, clean = draw_crop(data, generator)
    step = int(generator.integers(2, 7)) if generator.uniform() < 0.5 else 0
    alpha, gamma = draw_darkening(clean, generator)
    drawn, truth = draw_noise(generator)
    dark = quantised(darken(still_clip_with_moving_part(clean, step), alpha, gamma))
    noisy = noisy_clip(dark, NoiseValues.from_values(drawn, dtype=torch.float32), seed * 7 + 1)
    started = time.perf_counter()
    found = estimate_spectrum(noisy, seed=seed, name=f"case {seed}")
    seconds = time.perf_counter() - started
    estimated = [float(v) for v in found.values["temporal_correlation"]]
    synthetic = noisy_clip(dark, NoiseValues.from_values(found.values, dtype=torch.float32), seed * 7 + 2)
    return {
        "seed": seed,
        "image": name,
        "moving_step": step,
        "jpeg": float(drawn.get("compression", 0.0)),
        "level_8bit": round(float(drawn["level_curve"][3]) * 255, 2),
        "truth": [round(v, 3) for v in truth],
        "estimated": [round(v, 3) for v in estimated],
        "fine_error": float(np.mean(np.abs(np.subtract(estimated, truth)[:FINE_OCTAVES]))),
        "check_real": check_figure(noisy),
        "check_synthetic": check_figure(synthetic),
        "still_blocks": found.meta.get("still_flat_blocks"),
        "warnings": [w for w in found.warnings if "frame" in w],
        "seconds": round(seconds, 1),
    }


def summarise(cases: list[dict[str, Any]]) -> None:
    errors = np.asarray([c["fine_error"] for c in cases])
    gaps = np.asarray([c["check_synthetic"] - c["check_real"] for c in cases])
    signed = np.asarray([np.mean(np.subtract(c["estimated"], c["truth"])[:FINE_OCTAVES]) for c in cases])
    print(
        f"\n{len(cases)} cases: |AR error| (octaves 1-{FINE_OCTAVES}) median {np.median(errors):.3f}, 90th pct "
        f"{np.percentile(errors, 90):.3f}, mean signed {signed.mean():+.3f}; check gap (synthetic - real) median "
        f"|gap| {np.nanmedian(np.abs(gaps)):.3f}, mean {np.nanmean(gaps):+.3f}, within 0.15: "
        f"{int((np.abs(gaps) <= 0.15).sum())} of {len(cases)}"
    )
    for key in ("jpeg", "moving_step"):
        groups: dict[Any, list[float]] = {}
        for c in cases:
            groups.setdefault(c[key] if key == "jpeg" else bool(c[key]), []).append(c["fine_error"])
        print(f"|AR error| by {key}:", {k: f"{np.median(v):.3f} (n={len(v)})" for k, v in sorted(groups.items())})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--cases", type=int, default=24)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="write each case as a JSON line")
    arguments = parser.parse_args()
    torch.set_num_threads(1)

    def line(seed: int, case: dict[str, Any]) -> str:
        return (
            f"{seed:3d} level {case['level_8bit']:5.2f} jpeg {case['jpeg']:.1f} move {case['moving_step']} "
            f"truth {case['truth'][:FINE_OCTAVES]} est {case['estimated'][:FINE_OCTAVES]} "
            f"check real {case['check_real']:.3f} synth {case['check_synthetic']:.3f} "
            f"still {case['still_blocks']} {case['seconds']}s {case['warnings']}"
        )

    seeds = range(arguments.first_seed, arguments.first_seed + arguments.cases)
    summarise(run_cases(seeds, lambda seed: run_case(arguments.data, seed), line, arguments.out))


if __name__ == "__main__":
    main()
