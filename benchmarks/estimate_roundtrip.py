"""Randomized round trip of ``estimate``: known noise on darkened clean images, estimated blind, applied again.

Run: ``.venv/bin/python benchmarks/estimate_roundtrip.py [--data ../shared/data] [--cases 200] [--first-seed 1000]
[--out cases.jsonl] [--threads 2]``.

Each case (its own seed; the same seed gives the same case on any machine):

* a clean image drawn from every shared kind: kodak24, cbsd68, mcmaster and the clean halves of every real-pair set
  (sidd, nam-cc15, polyu, nam-cc60), cut to at most 512 px a side at a random place;
* darkened as ``apply`` darkens, ``alpha * x ** (1 / gamma)``: gamma ~ U(0.4, 1), alpha set so that the mean level
  is log-uniform over [0.02, 0.35] (very dark to mid-grey; the darkest cases clip much of their noise at 0);
* noise of one of three kinds: ``white`` (Poisson-Gaussian, shot log-uniform over [0.01, 0.16], read over [0.003,
  0.04]), ``structured`` (the same levels with the sRGB vocabulary's channel gains, spatial and channel
  correlation drawn from its training ranges, drawn as a version-3 profile is: translated into the spectral
  model), ``spectral`` (the level curve of such a shot and read with channel gains, and a
  spectrum like a camera's: brightness rising toward coarse scales by up to 4x, colour mottle peaking at 16-64 px at
  up to 60x white noise); a third of the cases JPEG-compressed (quality 80 or 60); one case in eight a 4-frame
  clip of a still scene whose noise persists from frame to frame (AR(1) per octave up to 0.8);
* ``estimate`` (the shipped network and the spectral measurement) reads the profile from the noisy reference;
* the same darkened image made noisy again with the estimated profile (another seed).

Compared on the two noise maps (noisy - darkened clean, 8-bit, clipping included as a camera clips): the std ratio
(estimated over true) overall, per channel and per quartile of the darkened clean intensity; the band power ratios
(brightness and colour, five bands fine to coarse, ``evaluation.structure``); for clips the lag-1 correlation of
the noise; and the estimate's warnings. Printed: one line per case, then the distribution: median and 90th
percentile of |std ratio - 1|, cases off by more than 2x and whether they warned, the median band ratios.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.evaluation.measures.structure import band_powers, band_ratios
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import read_image
from darksynth.light.darkening import darken
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVE_FREQUENCIES, OCTAVES
from darksynth.noise.values import NoiseValues
from darksynth.training.weights import default_weights_path, load_weights
from machine import cpu_summary

IMAGE_SETS = (
    "clean/images/kodak24",
    "clean/images/cbsd68",
    "clean/images/mcmaster",
    "real-pairs/sidd/clean",
    "real-pairs/nam-cc15/clean",
    "real-pairs/polyu/clean",
    "real-pairs/nam-cc60/clean",
)
SIDE = 512
CLIP_FRAMES = 4


MEASUREMENT_KEYS = (
    "denoiser_strength_8bit",
    "flat_block_gradient_8bit",
    "strength_over_fitted_noise",
    "knot_response",
    "compression_chosen",
    "compression_scores",
    "read_octaves",
    "coarse_anchor",
    "level_by_compression_8bit",
    "jpeg_lattice",
)
"""What each case keeps of the estimate's record of its measurement (``meta.spectrum``), to tell why it missed."""


def _uniform(generator: np.random.Generator, low: float, high: float) -> float:
    return float(generator.uniform(low, high))


def _log_uniform(generator: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(generator.uniform(math.log(low), math.log(high))))


def draw_image(data: Path, generator: np.random.Generator) -> tuple[str, torch.Tensor]:
    """A random crop (3, H, W) in [0, 1] of a random image of a random set."""
    folder = data / IMAGE_SETS[int(generator.integers(len(IMAGE_SETS)))]
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in {".png", ".jpg", ".jpeg", ".bmp", ".tif"})
    path = paths[int(generator.integers(len(paths)))]
    image = hwc_to_chw(read_image(path).pixels).to(torch.float32) / 255.0
    height, width = image.shape[-2:]
    top = int(generator.integers(max(height - SIDE, 0) + 1))
    left = int(generator.integers(max(width - SIDE, 0) + 1))
    return f"{folder.parent.name}/{folder.name}/{path.name}", image[:, top : top + SIDE, left : left + SIDE]


def draw_darkening(clean: torch.Tensor, generator: np.random.Generator) -> tuple[float, float]:
    """(alpha, gamma): gamma ~ U(0.4, 1), alpha giving a mean level log-uniform over [0.02, 0.35]."""
    gamma = _uniform(generator, 0.4, 1.0)
    level = _log_uniform(generator, 0.02, 0.35)
    base = float(clean.clamp_min(0.0).pow(1.0 / gamma).mean())
    return min(level / max(base, 1e-6), 1.0), gamma


def _level_curve(shot: float, read: float, gains: tuple[float, float, float]) -> list[float]:
    knots = np.asarray(LEVEL_KNOTS)
    return [float(g * math.sqrt(shot**2 * x + read**2)) for g in gains for x in knots]


def _camera_spectrum(generator: np.random.Generator) -> tuple[list[float], list[float]]:
    """``octave_power`` and ``octave_correlation`` of a camera-like spectrum: brightness rising toward coarse
    scales, colour mottle peaking at a random coarse octave, mild correlations."""
    frequency = np.asarray(OCTAVE_FREQUENCIES)
    rise = _uniform(generator, 0.0, 1.0)
    peak, width = _log_uniform(generator, 1 / 64, 1 / 12), _uniform(generator, 0.6, 1.5)
    mottle = _log_uniform(generator, 1.0, 60.0)
    power, correlation = [], []
    for octave in range(OCTAVES):
        brightness = (frequency[0] / frequency[octave]) ** (rise * 0.5)
        colour = 1.0 + mottle * math.exp(-((math.log2(frequency[octave] / peak) / width) ** 2))
        power += [brightness, colour, colour * _uniform(generator, 0.5, 1.5)]
        correlation += [_uniform(generator, -0.2, 0.2), _uniform(generator, -0.2, 0.2), _uniform(generator, -0.3, 0.3)]
    return power, correlation


def draw_noise(generator: np.random.Generator, clip: bool) -> tuple[str, dict[str, Any]]:
    """A kind and the noise values by name (column components off: their presence is judged separately)."""
    kind = ("white", "structured", "spectral")[int(generator.integers(3))]
    shot, read = _log_uniform(generator, 0.01, 0.16), _log_uniform(generator, 0.003, 0.04)
    values: dict[str, Any] = {}
    if kind == "white":
        values = {"shot": shot, "read": read}
    elif kind == "structured":
        values = {
            "shot": shot,
            "read": read,
            "channel_gain": [_uniform(generator, 0.8, 1.5), _uniform(generator, 0.8, 1.5)],
            "correlation_length": _uniform(generator, 0.0, 1.5),
            "channel_correlation": [_uniform(generator, 0.0, 0.6) for _ in range(3)],
            "chroma_length": _uniform(generator, 0.0, 3.0),
        }
    else:
        gains = (_uniform(generator, 0.8, 1.5), 1.0, _uniform(generator, 0.8, 1.5))
        power, correlation = _camera_spectrum(generator)
        values = {
            "level_curve": _level_curve(shot, read, gains),
            "octave_power": power,
            "octave_correlation": correlation,
        }
        if clip:
            values["temporal_correlation"] = [_uniform(generator, 0.0, 0.8)] * OCTAVES
    if generator.uniform() < 1 / 3:
        values["compression"] = (0.2, 0.4)[int(generator.integers(2))]
    return kind, values


def _noise_map(dark: torch.Tensor, values: NoiseValues, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    return quantised(add_noise(dark[None], values, generator=generator)[0]) - dark


def compare(real: torch.Tensor, synthetic: torch.Tensor, dark: torch.Tensor) -> dict[str, Any]:
    """Std ratios (overall, per channel, per intensity quartile), band ratios and lag-1 correlations."""
    ratio = float(synthetic.std() / real.std().clamp_min(1e-9))
    channels = [float(synthetic[:, c].std() / real[:, c].std().clamp_min(1e-9)) for c in range(3)]
    grey = dark.mean(dim=1, keepdim=True).expand_as(dark)
    edges = torch.quantile(grey.flatten()[:: max(1, grey.numel() // 100000)], torch.tensor([0.25, 0.5, 0.75]))
    quartiles = []
    for low, high in zip([-1.0, *edges.tolist()], [*edges.tolist(), 2.0], strict=True):
        inside = (grey > low) & (grey <= high)
        quartiles.append(float(synthetic[inside].std() / real[inside].std().clamp_min(1e-9)) if inside.any() else None)
    bands = band_ratios(
        band_powers(synthetic[0].permute(1, 2, 0).double().numpy()),
        band_powers(real[0].permute(1, 2, 0).double().numpy()),
    )
    result = {
        "std_ratio": ratio,
        "channel_ratio": channels,
        "quartile_ratio": quartiles,
        "brightness_bands": [float(v) for v in bands["brightness"]],
        "colour_bands": [float(v) for v in bands["colour"]],
    }
    if real.shape[0] > 1:
        result["lag1"] = [_lag1(real), _lag1(synthetic)]
    return result


def _lag1(noise: torch.Tensor) -> float:
    centred = noise - noise.mean(dim=(2, 3), keepdim=True)
    return float((centred[1:] * centred[:-1]).mean() / centred.square().mean().clamp_min(1e-12))


def run_case(data: Path, network: Any, seed: int) -> dict[str, Any]:
    generator = np.random.default_rng(seed)
    name, clean = draw_image(data, generator)
    clip = generator.uniform() < 1 / 8
    alpha, gamma = draw_darkening(clean, generator)
    kind, drawn = draw_noise(generator, clip)
    frames = CLIP_FRAMES if clip else 1
    dark = quantised(darken(clean[None].expand(frames, -1, -1, -1), alpha, gamma))
    truth = NoiseValues.from_values(drawn, dtype=torch.float32)
    real = _noise_map(dark, truth, seed * 7 + 1)
    started = time.perf_counter()
    found = estimate(dark + real, network, source=f"case {seed}")
    seconds = time.perf_counter() - started
    values = found.profile.noise.to(dtype=torch.float32)
    synthetic = _noise_map(dark, values, seed * 7 + 2)
    return {
        "seed": seed,
        "image": name,
        "kind": kind,
        "clip": clip,
        "jpeg": float(drawn.get("compression", 0.0)),
        "alpha": round(alpha, 4),
        "gamma": round(gamma, 3),
        "mean_level": round(float(dark.mean()), 4),
        "true_std_8bit": round(float(real.std()) * 255, 3),
        "clipped_share": round(float((dark + real <= 0.5 / 255).float().mean()), 4),
        "seconds": round(seconds, 2),
        "warnings": found.warnings,
        "measurement": {key: found.profile.meta.get("spectrum", {}).get(key) for key in MEASUREMENT_KEYS},
        **compare(real, synthetic, dark),
    }


def summarise(cases: list[dict[str, Any]]) -> None:
    errors = np.asarray([abs(c["std_ratio"] - 1.0) for c in cases])
    off = [c for c in cases if not 0.5 <= c["std_ratio"] <= 2.0]
    silent = [c for c in off if not c["warnings"]]
    print(
        f"\n{len(cases)} cases: |std ratio - 1| median {np.median(errors):.3f}, 90th percentile "
        f"{np.percentile(errors, 90):.3f}, worst {errors.max():.3f}"
    )
    print(f"off by more than 2x: {len(off)} ({len(silent)} without a warning: seeds {[c['seed'] for c in silent]})")
    channel = np.abs(np.asarray([c["channel_ratio"] for c in cases]) - 1.0)
    print(f"per channel |ratio - 1| median {np.median(channel):.3f}, 90th percentile {np.percentile(channel, 90):.3f}")
    quartiles = np.asarray([[q if q is not None else np.nan for q in c["quartile_ratio"]] for c in cases])
    print(
        "per intensity quartile, median ratio (dark to bright):", np.round(np.nanmedian(quartiles, axis=0), 3).tolist()
    )
    for component in ("brightness", "colour"):
        bands = np.asarray([c[f"{component}_bands"] for c in cases])
        print(f"median {component} band ratio (fine to coarse):", np.round(np.nanmedian(bands, axis=0), 3).tolist())
    for key in ("kind", "jpeg", "clip"):
        groups: dict[Any, list[float]] = {}
        for c in cases:
            groups.setdefault(c[key], []).append(abs(c["std_ratio"] - 1.0))
        print(f"by {key}:", {k: f"{np.median(v):.3f} (n={len(v)})" for k, v in sorted(groups.items())})

    def lattice_read(case: dict[str, Any]) -> float | None:
        read: float | None = (case["measurement"].get("jpeg_lattice") or {}).get("lattice_read")
        return read

    compressed = [c for c in cases if c["jpeg"] > 0]
    read = [c for c in compressed if lattice_read(c) is not None]
    right = [c for c in read if lattice_read(c) == c["jpeg"]]
    misread = [c["seed"] for c in cases if c["jpeg"] == 0 and lattice_read(c) is not None]
    print(
        f"JPEG strength read off the DCT lattice: {len(read)} of {len(compressed)} JPEG cases, {len(right)} right; "
        f"read where there was none: {misread}; chosen right by the fit or the read: "
        f"{sum(c['measurement']['compression_chosen'] == c['jpeg'] for c in cases)} of {len(cases)}"
    )
    dark = [abs(c["std_ratio"] - 1.0) for c in cases if c["mean_level"] < 0.06]
    if dark:
        print(f"mean level under 0.06: median {np.median(dark):.3f} (n={len(dark)})")
    clips = [c["lag1"] for c in cases if "lag1" in c]
    if clips:
        gaps = np.abs(np.asarray(clips)[:, 0] - np.asarray(clips)[:, 1])
        print(f"clips: lag-1 correlation gap median {np.median(gaps):.3f}, worst {gaps.max():.3f} (n={len(clips)})")
    print(f"estimate seconds: median {np.median([c['seconds'] for c in cases]):.2f}")


def run_cases(
    seeds: Iterable[int],
    run: Callable[[int], dict[str, Any]],
    line: Callable[[int, dict[str, Any]], str],
    out: Path | None,
) -> list[dict[str, Any]]:
    """Every seed's case run, printed as its ``line`` as it finishes and, with ``out``, written there as a JSON
    line at once (a long run that is stopped keeps what it did)."""
    cases = []
    with out.open("w") if out else contextlib.nullcontext() as stream:
        for seed in seeds:
            case = run(seed)
            cases.append(case)
            print(line(seed, case), flush=True)
            if stream is not None:
                stream.write(json.dumps(case) + "\n")
                stream.flush()
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--first-seed", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=None, help="write each case as a JSON line")
    parser.add_argument("--threads", type=int, default=2)
    arguments = parser.parse_args()
    torch.set_num_threads(arguments.threads)
    print(cpu_summary())
    network = load_weights(default_weights_path())

    def line(seed: int, case: dict[str, Any]) -> str:
        return (
            f"{seed} {case['kind']:10s} {'clip' if case['clip'] else 'image'} jpeg {case['jpeg']:.1f} level "
            f"{case['mean_level']:.3f} true std {case['true_std_8bit']:5.2f} ratio {case['std_ratio']:.3f} "
            f"clipped {case['clipped_share']:.2f} warnings {len(case['warnings'])} {case['image']}"
        )

    seeds = range(arguments.first_seed, arguments.first_seed + arguments.cases)
    summarise(run_cases(seeds, lambda seed: run_case(arguments.data, network, seed), line, arguments.out))


if __name__ == "__main__":
    main()
