"""How far real noise is from white: the figures behind the analysis in docs/results.md.

Makes: docs/results.md, "The paper's headline" / "Why" (the table of real noise std, std over fine-scale std,
channel correlation, mean level and den std over real std per set); with ``--weights`` the synthetic / real std of
docs/den.md, "The sRGB model"; docs/noise-model.md ("The sRGB model: structure of the heteroscedastic noise")
cites it.

Run from the repo root::

    .venv/bin/python scripts/noise/real_noise_structure.py

Options: ``[--data ../shared/data] [--method den] [--weights W]``.

For up to 16 pairs of each set in ``real-pairs``, on the real noise map noisy - clean:

- spatial correlation: the noise std divided by the std that fine-scale statistics see (vertical differences,
  sqrt(var(n[y+1] - n[y]) / 2)); 1.00 for white noise, larger when neighbouring pixels are correlated;
- chromatic correlation: the mean correlation coefficient between the noise of two colour channels, and per
  pair (red-green, green-blue, red-blue);
- per-channel level: the std of red and of blue noise relative to green;
- brightness: the mean level of the noisy image (the shipped DEN was trained on darkened images, mean <= 0.3);
- the std of the ``--method``'s synthetic noise divided by the real noise std (1.00 when the level is right).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from darksynth.evaluation.methods.catalogue import build_method
from darksynth.evaluation.pairs import list_pair_set, load_pair


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--method", default="den", help="whose synthetic noise std to compare (default: den)")
    parser.add_argument("--weights", type=Path, help="weights file for a DEN method (default: the shipped one)")
    args = parser.parse_args()
    den = build_method(args.method, weights={args.method: args.weights} if args.weights else None)
    for root in sorted(p for p in (args.data / "real-pairs").iterdir() if (p / "noisy").is_dir()):
        pair_set = list_pair_set(root)
        ratios, levels, correlations, stds, den_ratios = [], [], [], [], []
        pairwise, gains = [], []
        for pair in pair_set.pairs[:: max(1, len(pair_set.pairs) // 16)]:
            loaded = load_pair(pair)
            noise = loaded.noise
            fine = ((noise[:, 1:, :] - noise[:, :-1, :]).var() / 2).sqrt()
            ratios.append(float(noise.std() / fine))
            stds.append(float(noise.std()) * 255)
            levels.append(float(loaded.noisy.mean()))
            matrix = torch.corrcoef(noise.reshape(3, -1))
            correlations.append(float((matrix[0, 1] + matrix[0, 2] + matrix[1, 2]) / 3))
            pairwise.append([float(matrix[0, 1]), float(matrix[1, 2]), float(matrix[0, 2])])
            channel_std = noise.reshape(3, -1).std(dim=1)
            gains.append([float(channel_std[0] / channel_std[1]), float(channel_std[2] / channel_std[1])])
            synthetic = den.synthesize(
                loaded.clean, den.fit(loaded.noisy, loaded.clean), torch.Generator().manual_seed(0)
            )
            den_ratios.append(float((synthetic - loaded.clean).std() / noise.std()))
        print(
            f"{pair_set.name:10s} pairs {len(ratios):3d}  noise std {np.median(stds):5.2f}/255  "
            f"std / fine-scale std {np.median(ratios):.2f}  channel correlation {np.mean(correlations):.2f}  "
            f"mean level {np.mean(levels):.2f}  den std / real std {np.median(den_ratios):.2f}"
        )
        rg, gb, rb = np.median(pairwise, axis=0)
        red, blue = np.median(gains, axis=0)
        print(
            f"{'':10s} channel correlation red-green {rg:.2f} green-blue {gb:.2f} red-blue {rb:.2f}  "
            f"std red/green {red:.2f} blue/green {blue:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
