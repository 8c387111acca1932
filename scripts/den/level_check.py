"""How well a DEN gets the overall noise level of bright, structured synthetic references.

Makes: docs/den.md, "The sRGB model" (the table of estimated / true noise std per setting, sRGB model and paper
model).

Run from the repo root::

    .venv/bin/python scripts/den/level_check.py                                         # the shipped sRGB model
    .venv/bin/python scripts/den/level_check.py src/darksynth/data/den_v3.safetensors   # the paper model

Options: ``[WEIGHTS] [--data ../shared/data] [--images 6]``.

For each of three settings like the real pairs' noise (low correlated JPEG noise, low correlated PNG noise,
strong sidd-like noise), the first ``--images`` held-out Kodak images (not darkened, as bright as the real
pairs) get that noise through ``add_noise`` and 8-bit rounding; ``estimate`` reads the profile back from the
noisy image alone, and the std its values imply on that image (``noise.level.mean_noise_variance``) is divided
by the std of the noise actually added (1.00: the level is right).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from darksynth.estimation.assemble import estimate
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import read_image
from darksynth.noise.level import mean_noise_variance
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels
from darksynth.training.weights import default_weights_path, load_weights

SETTINGS: tuple[dict[str, float | tuple[float, ...]], ...] = (
    {"read": 0.015, "shot": 0.02, "correlation_length": 0.8, "channel_correlation": (0.6, 0.6, 0.6),
     "channel_gain": (1.2, 1.2), "compression": 0.35},
    {"read": 0.02, "shot": 0.02, "correlation_length": 0.9, "channel_correlation": (0.4, 0.4, 0.4),
     "channel_gain": (1.4, 1.3)},
    {"read": 0.05, "shot": 0.1, "correlation_length": 0.6, "channel_correlation": (0.25, 0.2, 0.55),
     "channel_gain": (1.4, 1.5)},
)  # fmt: skip


def _values(setting: dict[str, float | tuple[float, ...]]) -> NoiseValues:
    return NoiseValues.from_values(setting, batch_shape=(1,), dtype=torch.float32)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("weights", type=Path, nargs="?", default=default_weights_path())
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--images", type=int, default=6)
    args = parser.parse_args()
    model = load_weights(args.weights)
    files = sorted((args.data / "clean" / "images" / "kodak24").glob("*"))[: args.images]
    for setting in SETTINGS:
        ratios = []
        for index, path in enumerate(files):
            image = read_image(path)
            scale = 255.0 if image.pixels.dtype == np.uint8 else 65535.0
            clean = (hwc_to_chw(image.pixels).float() / scale)[:, :384, :512][None, None]
            generator = torch.Generator().manual_seed(index)
            noisy = to_8bit_levels(add_noise(clean, _values(setting), generator=generator))
            true_std = float((noisy - clean).std())
            estimated = estimate(noisy[0], model).profile.noise
            values = estimated.map(lambda t: t[None]).to(dtype=torch.float32)
            ratios.append(float(mean_noise_variance(values, clean).sqrt()) / true_std)
        listed = " ".join(f"{r:.2f}" for r in ratios)
        print(f"{setting}: estimated / true std {listed} (median {np.median(ratios):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
