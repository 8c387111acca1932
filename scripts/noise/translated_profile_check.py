"""How version-2 and version-3 profiles draw: per-channel std and octave-band power of their noise.

Makes: docs/spectral-noise.md, "Version-2 and version-3 profiles" (the table of std R / G / B and brightness and
colour bands per profile, translated over recorded), and the record tests/noise/retired_srgb_drawing.json that
tests/noise/test_translation.py loads this file for.

Run from the repo root::

    .venv/bin/python scripts/noise/translated_profile_check.py

Options: ``[--record OUT.json] [--seed 0]``. Do not point ``--record`` at the committed record: it was made with the
retired version-3 drawing, which no code draws any more.

Twelve profiles of the version-3 sRGB model (:data:`PROFILES`), spread over its parameter ranges (channel gains far
from 1, correlation lengths up to 2 px, colour lengths up to 3 px, negative channel correlations, JPEG at three
strengths, two of them version-2 profiles without a colour length), each drawn with ``darksynth.synthesize`` on the
same darkened clean images (:func:`clean_images`, fixed seeds). For each profile the noise maps (noisy - darkened
clean) give, pooled over the images, each channel's std and the mean band power of brightness and colour in the five
bands of :func:`darksynth.evaluation.structure.band_powers` (fine to coarse), the bands the round-trip harness
reports.

``--record`` writes those figures as JSON. ``tests/noise/retired_srgb_drawing.json`` is that record made with the
version-3 model's own drawing (Gaussian kernels, channel mixing, colour length), before that drawing was retired: the
measured reference that ``tests/noise/test_translation.py`` holds the translated drawing to. Without ``--record``
the figures of the drawing as it is now are printed beside the record's, as ratios.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch

from darksynth.evaluation.measures.structure import band_powers
from darksynth.light.darkening import Darkening, darken
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.synthesize import synthesize

ROOT = Path(__file__).resolve().parents[2]
RECORD = ROOT / "tests" / "noise" / "retired_srgb_drawing.json"

SIDE = 512
IMAGES = 4
DARKENINGS = (Darkening(alpha=0.25, gamma=0.8), Darkening(alpha=0.45, gamma=0.6))

PROFILES: dict[str, dict[str, Any]] = {
    "v2 gains only": {"shot": 0.05, "read": 0.01, "channel_gain": [1.3, 0.8]},
    "v2 mild": {
        "shot": 0.06,
        "read": 0.008,
        "channel_gain": [1.2, 1.4],
        "correlation_length": 0.7,
        "channel_correlation": [0.5, 0.4, 0.3],
    },
    "v2 long": {
        "shot": 0.08,
        "read": 0.01,
        "correlation_length": 2.0,
        "channel_correlation": [0.6, 0.6, 0.6],
    },
    "v3 colour blotches": {
        "shot": 0.07,
        "read": 0.012,
        "channel_gain": [1.3, 1.5],
        "correlation_length": 0.8,
        "channel_correlation": [0.5, 0.5, 0.4],
        "chroma_length": 3.0,
    },
    "v3 long and coarse colour": {
        "shot": 0.05,
        "read": 0.02,
        "channel_gain": [0.7, 2.0],
        "correlation_length": 2.0,
        "channel_correlation": [0.3, 0.4, 0.2],
        "chroma_length": 3.0,
    },
    "v3 gains far": {
        "shot": 0.04,
        "read": 0.006,
        "channel_gain": [2.0, 0.7],
        "correlation_length": 0.3,
        "channel_correlation": [0.2, 0.1, 0.0],
        "chroma_length": 1.0,
    },
    "v3 negative correlation": {
        "shot": 0.06,
        "read": 0.01,
        "channel_gain": [1.1, 0.9],
        "correlation_length": 1.0,
        "channel_correlation": [-0.3, 0.2, -0.4],
        "chroma_length": 0.5,
    },
    "v3 jpeg light": {
        "shot": 0.07,
        "read": 0.01,
        "channel_gain": [1.2, 1.3],
        "correlation_length": 0.6,
        "channel_correlation": [0.4, 0.4, 0.4],
        "chroma_length": 1.5,
        "compression": 0.2,
    },
    "v3 jpeg medium": {
        "shot": 0.09,
        "read": 0.015,
        "channel_gain": [1.5, 1.5],
        "correlation_length": 1.2,
        "channel_correlation": [0.3, 0.5, 0.2],
        "chroma_length": 2.5,
        "compression": 0.5,
    },
    "v2 jpeg strong": {
        "shot": 0.1,
        "read": 0.02,
        "channel_gain": [1.4, 1.2],
        "correlation_length": 0.9,
        "channel_correlation": [0.5, 0.5, 0.5],
        "compression": 0.7,
    },
    "v3 shot dominated": {
        "shot": 0.15,
        "read": 0.002,
        "channel_gain": [1.1, 1.3],
        "correlation_length": 1.5,
        "channel_correlation": [0.6, 0.5, 0.4],
    },
    "v3 read dominated": {
        "shot": 0.01,
        "read": 0.05,
        "channel_gain": [0.8, 1.6],
        "correlation_length": 0.4,
        "channel_correlation": [0.7, 0.7, 0.7],
        "chroma_length": 2.0,
    },
}
"""Version-2 and version-3 noise values by profile name (everything else neutral)."""


def clean_images() -> list[torch.Tensor]:
    """:data:`IMAGES` clean (3, SIDE, SIDE) float images on 8-bit levels: smooth gradients with a disc and a few
    random rectangles (seeded), so the darkened levels span the dark range where low-light noise lies."""
    generator = np.random.default_rng(2024)
    y, x = np.mgrid[0:SIDE, 0:SIDE].astype(np.float64) / SIDE
    images = []
    for index in range(IMAGES):
        pixels = np.stack([0.1 + 0.8 * x, 0.15 + 0.7 * y, 0.5 + 0.4 * np.sin(6 * (x + y) + index)], axis=0)
        for _ in range(6):
            top, left = generator.integers(0, SIDE - 64, size=2)
            pixels[:, top : top + 64, left : left + 64] = generator.uniform(0.05, 0.95, size=(3, 1, 1))
        images.append(torch.from_numpy(np.round(np.clip(pixels, 0, 1) * 255) / 255).to(torch.float32))
    return images


def measure(values: dict[str, Any], seed: int) -> dict[str, list[float]]:
    """Per-channel std and brightness / colour band powers (fine to coarse) of one profile's noise, pooled over the
    clean images, each darkened by each of :data:`DARKENINGS` and drawn with its own seed from ``seed``."""
    profile = Profile(noise=NoiseValues.from_values(values))
    squares, brightness, colour, count = np.zeros(3), [], [], 0
    for index, clean in enumerate(clean_images()):
        for offset, darkening in enumerate(DARKENINGS):
            generator = torch.Generator().manual_seed(seed + 10 * index + offset)
            noisy = synthesize(clean, profile, generator=generator, darkening=darkening).image
            dark = darken(clean, darkening.alpha, darkening.gamma)
            noise = (torch.as_tensor(noisy) - dark).double().numpy()
            squares += np.square(noise - noise.mean(axis=(1, 2), keepdims=True)).sum(axis=(1, 2))
            count += noise[0].size
            powers = band_powers(noise.transpose(1, 2, 0))
            brightness.append(powers["brightness"])
            colour.append(powers["colour"])
    return {
        "channel_std": np.sqrt(squares / count).tolist(),
        "brightness_bands": np.mean(brightness, axis=0).tolist(),
        "colour_bands": np.mean(colour, axis=0).tolist(),
    }


def measure_all(seed: int) -> dict[str, dict[str, list[float]]]:
    return {name: measure(values, seed + 1000 * index) for index, (name, values) in enumerate(PROFILES.items())}


def ratios(now: dict[str, list[float]], recorded: dict[str, list[float]]) -> dict[str, list[float]]:
    """Per figure, now over recorded."""
    return {key: (np.asarray(now[key]) / np.asarray(recorded[key])).tolist() for key in recorded}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", type=Path, default=None, help="write the figures to this JSON file")
    parser.add_argument("--seed", type=int, default=0, help="the first seed (the record's is 0)")
    arguments = parser.parse_args()
    torch.set_num_threads(1)
    figures = measure_all(arguments.seed)
    if arguments.record is not None:
        document = {"profiles": PROFILES, "seed": arguments.seed, "figures": figures}
        arguments.record.write_text(json.dumps(document, indent=1) + "\n")
        return
    recorded = json.loads(RECORD.read_text())["figures"]
    worst = 0.0
    for name, now in figures.items():
        found = ratios(now, recorded[name])
        worst = max(worst, *(abs(r - 1.0) for values in found.values() for r in values))
        print(name, {key: np.round(values, 3).tolist() for key, values in found.items()})
    print(f"largest |ratio - 1|: {worst:.3f}")
    sys.exit(0)


if __name__ == "__main__":
    main()
