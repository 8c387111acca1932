"""How much of each pixel-noise parameter a reference reveals at all: bounds for the DEN's round trip.

Makes: docs/den.md, "Measured acceptance" (the list "How far a blind estimator could go": the clean-image oracle's
R^2 for shot and read, and the share of quantization noise).

Run from the repo root::

    .venv/bin/python scripts/den/identifiability.py

Options: ``[--trials 48] [--pixels 60000] [--seed 0] [--data ../shared/data]``.

1. Clean-image oracle for shot and read noise: on held-out Kodak images darkened with alpha, gamma from the
   paper's ranges and given shot and read noise from the training ranges (8-bit, clipped), fit (shot, read)
   by maximum likelihood *knowing the dark clean image* (censored Gaussian on the 8-bit levels). This is
   an upper bound for any blind estimator in the same setting; R^2 per parameter is printed.
2. The share of quantization noise U(0, q) in the pixel-noise variance of a darkened reference, over the
   training prior: q^2 / 12 against shot^2 * x + read^2 + q^2 / 12 at the image's mean dark level. A blind
   estimator cannot use the mean shift q / 2 (it is confounded with the unknown darkening), so the variance
   share is all it can see.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

from darksynth.io.images import read_image
from darksynth.light.darkening import darken
from darksynth.noise.sampling import random_darkening_values, random_noise_values
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.training.loop import r_squared

HALF_LEVEL = 0.5 / 255.0


def censored_fit(dark: torch.Tensor, noisy: torch.Tensor) -> tuple[float, float]:
    """Maximum-likelihood (shot, read) of 8-bit noisy levels around a known dark signal."""
    normal = torch.distributions.Normal(0.0, 1.0)
    log_parameters = torch.tensor([-2.0, -3.0], dtype=torch.float64, requires_grad=True)
    optimiser = torch.optim.LBFGS([log_parameters], max_iter=100, line_search_fn="strong_wolfe")

    def negative_log_likelihood() -> torch.Tensor:
        optimiser.zero_grad()
        shot, read = log_parameters.exp()
        std = (shot * shot * dark + read * read).sqrt()
        upper = torch.where(noisy >= 1.0, 1.0, normal.cdf((noisy + HALF_LEVEL - dark) / std))
        lower = torch.where(noisy <= 0.0, 0.0, normal.cdf((noisy - HALF_LEVEL - dark) / std))
        loss = -(upper - lower).clamp_min(1e-300).log().mean()
        loss.backward()  # type: ignore[no-untyped-call]
        return loss

    optimiser.step(negative_log_likelihood)  # type: ignore[no-untyped-call]
    shot, read = log_parameters.detach().exp()
    return float(shot), float(read)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=48)
    parser.add_argument("--pixels", type=int, default=60000, help="pixels sampled per image for the fit")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    paths = sorted((args.data / "clean" / "images" / "kodak24").glob("*.png"))
    if not paths:
        print(f"{args.data}: held-out Kodak images not found", file=sys.stderr)
        return 1
    generator = torch.Generator().manual_seed(args.seed)
    truth, fitted, shares = [], [], []
    for trial in range(args.trials):
        pixels = read_image(paths[trial % len(paths)]).pixels
        clean = torch.from_numpy(pixels.astype(np.float64) / 255.0).permute(2, 0, 1)[None]
        values = random_noise_values(generator=generator, dtype=torch.float64, noise_model="paper")
        alpha, gamma = random_darkening_values(generator=generator)
        dark = darken(clean, float(alpha), float(gamma))
        pixel_only = NoiseValues.from_values({"shot": values["shot"], "read": values["read"]}, dtype=torch.float64)
        noisy = (add_noise(dark, pixel_only, generator=generator) * 255.0).round() / 255.0
        sample = torch.randperm(dark.numel(), generator=generator)[: args.pixels]
        fitted.append(censored_fit(dark.flatten()[sample], noisy.flatten()[sample]))
        shot, read, q = (float(values[k][0]) for k in ("shot", "read", "quantization"))
        truth.append((shot, read))
        q_variance = q * q / 12.0
        shares.append(q_variance / (shot * shot * float(dark.mean()) + read * read + q_variance + 1e-12))
        print(f"trial {trial + 1}/{args.trials}", file=sys.stderr, end="\r")
    r2 = r_squared(torch.tensor(fitted), torch.tensor(truth))
    share = np.array(shares)
    summary = {
        "oracle_r2": {"shot": round(float(r2[0]), 3), "read": round(float(r2[1]), 3)},
        "quantization_share": {
            "median": round(float(np.median(share)), 4),
            "p90": round(float(np.quantile(share, 0.9)), 4),
            "fraction_above_0.1": round(float((share > 0.1).mean()), 3),
        },
        "trials": args.trials,
        "seed": args.seed,
    }
    print(f"clean-image oracle, {args.trials} trials: R2 shot {r2[0]:.3f}, read {r2[1]:.3f}")
    print(
        f"quantization share of pixel-noise variance: median {np.median(share):.4f}, "
        f"90th percentile {np.quantile(share, 0.9):.4f}, above 10% in {(share > 0.1).mean():.1%} of draws"
    )
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
