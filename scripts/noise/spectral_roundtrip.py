"""Blind round trip of the spectral estimate on Kodak: random spectra from the table's prior, estimated back.

Makes: docs/spectral-noise.md, "Measured" (the bullet "Blind round trip on Kodak": the median band ratios for
brightness and colour and the share of images within 0.8-1.25 per band).

Run from the repo root::

    .venv/bin/python scripts/noise/spectral_roundtrip.py --images 8

Options: ``[--data ../shared/data] [--images 8] [--brightness 0.3]``.

For each of the first ``--images`` Kodak images (scaled by ``--brightness``, as a dark scene, on 8-bit levels):
the spectral parameters (``level_curve``, ``octave_power``, ``octave_correlation``) drawn uniformly within their
training ranges (``noise.sampling.random_noise_values``, the spectral model), that noise added, the spectrum
estimated from the noisy image alone (``estimation.noise.spectrum.estimate_spectrum``), and new noise of the estimate
drawn on the same clean image. Printed: per image and band (fine to coarse, the evaluation's band measure) the
power of the estimate's noise over the truth's, for brightness and colour, and the std ratio per channel; then
the median over images and the share of bands within 0.8-1.25.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.noise.spectrum import estimate_spectrum
from darksynth.evaluation.measures.structure import band_powers, band_ratios
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import read_image
from darksynth.noise.sampling import random_noise_values
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues

SPECTRAL = ("level_curve", "octave_power", "octave_correlation")


def prior_draw(seed: int) -> NoiseValues:
    drawn = random_noise_values(generator=torch.Generator().manual_seed(seed), noise_model="spectral")
    return NoiseValues.from_values({name: drawn[name] for name in SPECTRAL}, dtype=torch.float32)


def noise_map(clean: torch.Tensor, values: NoiseValues, seed: int) -> np.ndarray:
    noisy = quantised(add_noise(clean[None, None], values, generator=torch.Generator().manual_seed(seed))[0, 0])
    return (noisy - clean).permute(1, 2, 0).double().numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--images", type=int, default=8)
    parser.add_argument("--brightness", type=float, default=0.3)
    arguments = parser.parse_args()
    rows = []
    kodak = sorted((arguments.data / "clean" / "images" / "kodak24").glob("*"))
    for index, path in enumerate(kodak[: arguments.images]):
        image = read_image(path).pixels
        clean = quantised(arguments.brightness * hwc_to_chw(image).to(torch.float32) / 255.0)
        truth = prior_draw(index)
        real = noise_map(clean, truth, 1000 + index)
        noisy = torch.from_numpy(real).permute(2, 0, 1).float() + clean
        found = estimate_spectrum(noisy[None], name=path.name)
        synthetic = noise_map(clean, NoiseValues.from_values(found.values, dtype=torch.float32), 2000 + index)
        ratio = band_ratios(band_powers(synthetic), band_powers(real))
        rows.append(ratio)
        level = synthetic.std(axis=(0, 1)) / real.std(axis=(0, 1))
        print(
            f"{path.name:14s} brightness {np.round(ratio['brightness'], 2)} colour {np.round(ratio['colour'], 2)} "
            f"std {np.round(level, 2)} {'; '.join(found.warnings)}",
            flush=True,
        )
    for component in ("brightness", "colour"):
        stacked = np.array([row[component] for row in rows])
        inside = np.mean((stacked > 0.8) & (stacked < 1.25), axis=0)
        median = np.round(np.median(stacked, axis=0), 2)
        print(f"median {component:10s} {median}  share within 0.8-1.25 {np.round(inside, 2)}")


if __name__ == "__main__":
    main()
