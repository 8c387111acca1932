"""Measure the darkening estimate (darksynth.light.tone_fit, on darksynth.light.tones) and make its tone prior.

Makes: docs/darkening-estimate.md, "Accuracy" (the table of alpha, gamma, mean level and tone-curve errors on
held-out Kodak against the paper's fixed darkening, with and without noise) and "Real references (same command)";
``prior`` makes the table TONE_PRIOR_LOG_QUANTILES in src/darksynth/light/tone_fit.py.

Run from the repo root::

    .venv/bin/python scripts/light/evaluate_darkening.py prior                                 # the prior table
    .venv/bin/python scripts/light/evaluate_darkening.py evaluate                              # noise as drawn
    .venv/bin/python scripts/light/evaluate_darkening.py evaluate --noise-scale 0 --no-real    # without noise

Options: ``{prior,evaluate} [--block 4] [--draws 4] [--seed 0] [--noise-scale 1] [--no-paper-prior] [--no-real]``.

``prior``: the mean log tone quantiles of the clean training images (cbsd68, mcmaster, mirflickr).
``evaluate``: held-out Kodak images darkened with alpha ~ U(0.05, 0.3), gamma ~ U(0.1, 1) (the paper's ranges),
noise drawn from the DEN's training ranges (random_noise_values + add_noise), rounded to 8 bits; the
estimate is compared with the truth on alpha, gamma, the mean level and the tone curve of the darkened clean
image, next to the paper's fixed mid-range darkening as a baseline. Then the estimates on the real low-light
references (LOL, LIME).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.estimation.darkening_reading import estimate_darkening, estimate_darkening_spread
from darksynth.estimation.reference import load_reference
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening, darken
from darksynth.light.tone_fit import TONE_PRIOR_LOG_QUANTILES
from darksynth.light.tones import PROBABILITIES, TONE_BLOCK, tone_quantiles
from darksynth.noise.components import model_parameters
from darksynth.noise.sampling import random_noise_values
from darksynth.noise.simulate import add_noise

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
TRAINING_SETS = ("cbsd68", "mcmaster", "mirflickr")
HELD_OUT = "kodak24"
REAL_SETS = ("lol", "lime")
CURVE_LEVELS = torch.linspace(0.05, 0.95, 19, dtype=torch.float64)


def _images(name: str) -> list[Path]:
    return sorted((DATA / "clean" / "images" / name).glob("*.png"))


def measure_prior(block: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation over the clean training images of their log tone quantiles."""
    logs = []
    for name in TRAINING_SETS:
        for path in _images(name):
            quantiles = tone_quantiles(load_reference(path), block=block)
            logs.append(np.log(np.maximum(quantiles, 0.5 / 255.0)))
    stacked = np.asarray(logs)
    return stacked.mean(axis=0), stacked.std(axis=0)


def _r2(truth: list[float], estimate: list[float]) -> float:
    t, e = np.asarray(truth), np.asarray(estimate)
    return float(1.0 - np.sum((e - t) ** 2) / np.sum((t - t.mean()) ** 2))


def _relative(truth: list[float], estimate: list[float]) -> np.ndarray:
    errors: np.ndarray = np.abs(np.asarray(estimate) / np.asarray(truth) - 1.0)
    return errors


def _curve_error(clean: torch.Tensor, estimated: Darkening, true: Darkening) -> tuple[float, float, float]:
    """Mean levels of the clean image darkened both ways, and the tone-curve error: the mean absolute
    difference of their quantiles at 5%, 10%, ..., 95%, relative to the true darkened image's mean level."""
    ours = darken(clean, estimated.alpha, estimated.gamma).flatten().double()
    theirs = darken(clean, true.alpha, true.gamma).flatten().double()
    difference = (torch.quantile(ours, CURVE_LEVELS) - torch.quantile(theirs, CURVE_LEVELS)).abs().mean()
    level = float(theirs.mean())
    return float(ours.mean()), level, float(difference) / level


def evaluate(
    block: int, draws: int, seed: int, prior: np.ndarray, noise_scale: float = 1.0, use_prior: bool = True
) -> None:
    generator = torch.Generator().manual_seed(seed)
    baseline = Darkening(alpha=sum(ALPHA_RANGE) / 2, gamma=sum(GAMMA_RANGE) / 2)
    rows: dict[str, list[float]] = {
        k: [] for k in ("alpha", "alpha_hat", "gamma", "gamma_hat", "level", "level_hat", "level_base", "curve", "base")
    }
    rows |= {"rms": [], "confidence": [], "failed": []}
    for path in _images(HELD_OUT):
        clean = load_reference(path)[0]
        for _ in range(draws):
            alpha = float(torch.empty(()).uniform_(*ALPHA_RANGE, generator=generator))
            gamma = float(torch.empty(()).uniform_(*GAMMA_RANGE, generator=generator))
            drawn = random_noise_values(generator=generator, noise_model="paper")
            values = drawn.replace(**{p.name: drawn[p.name] * noise_scale for p in model_parameters("paper")})
            noisy = add_noise(darken(clean, alpha, gamma)[None], values, generator=generator)[0]
            noisy = (noisy * 255).round() / 255
            true = Darkening(alpha, gamma)
            try:
                result = estimate_darkening(noisy, block=block, prior=prior, use_prior=use_prior, source=path.name)
            except DarksynthError:
                rows["failed"].append(1.0)
                continue
            ours, level, curve = _curve_error(clean, result.darkening, true)
            base, _, base_curve = _curve_error(clean, baseline, true)
            for key, value in (
                ("alpha", alpha),
                ("alpha_hat", result.darkening.alpha),
                ("gamma", gamma),
                ("gamma_hat", result.darkening.gamma),
                ("level", level),
                ("level_hat", ours),
                ("level_base", base),
                ("curve", curve),
                ("base", base_curve),
                ("rms", result.fit_rms),
                ("confidence", result.confidence),
            ):
                rows[key].append(value)
    n = len(rows["alpha"])
    print(f"held-out {HELD_OUT}: {n} darkened noisy images ({len(rows['failed'])} refused), block {block}")
    print("quantity        R^2    median rel. err   90th pct rel. err")
    for name, truth, guess in (
        ("alpha", rows["alpha"], rows["alpha_hat"]),
        ("gamma", rows["gamma"], rows["gamma_hat"]),
        ("mean level", rows["level"], rows["level_hat"]),
        ("  baseline", rows["level"], rows["level_base"]),
    ):
        errors = _relative(truth, guess)
        print(
            f"{name:<14} {_r2(truth, guess):6.3f}   {np.median(errors):8.3f}          {np.percentile(errors, 90):8.3f}"
        )
    for name, key in (("tone curve", "curve"), ("  baseline", "base")):
        errors = np.asarray(rows[key])
        print(f"{name:<14}    -     {np.median(errors):8.3f}          {np.percentile(errors, 90):8.3f}")
    log_alpha = np.log(rows["alpha_hat"]) - np.log(rows["alpha"])
    print(f"log(alpha_hat / alpha): median {np.median(log_alpha):+.3f}")
    order = np.argsort(rows["confidence"])
    half = len(order) // 2
    low, high = np.asarray(rows["curve"])[order[:half]], np.asarray(rows["curve"])[order[half:]]
    print(f"tone-curve error, median: lower-confidence half {np.median(low):.3f}, upper half {np.median(high):.3f}")


def real(block: int, prior: np.ndarray) -> None:
    print(
        "\nreal references: mean level, alpha, gamma, quantiles used, fit rms, confidence, region alpha/gamma p10-p90"
    )
    for name in REAL_SETS:
        for path in sorted((DATA / "real-lowlight" / "images" / name).glob("*.png"), key=lambda p: int(p.stem)):
            frames = load_reference(path)
            label = f"{name}/{path.name}"
            try:
                result = estimate_darkening(frames, block=block, prior=prior, source=label)
            except DarksynthError as error:
                print(f"{label:<12} {float(frames.mean()):.3f}  refused: {error}")
                continue
            spread = estimate_darkening_spread(frames, block=block)
            alphas = [e.darkening.alpha for e in spread] or [float("nan")]
            gammas = [e.darkening.gamma for e in spread] or [float("nan")]
            d = result.darkening
            print(
                f"{label:<12} {float(frames.mean()):.3f}  alpha {d.alpha:.3f}  gamma {d.gamma:.3f}  "
                f"{result.quantiles_used:2d}  {result.fit_rms:.3f}  {result.confidence:.2f}  "
                f"[{np.percentile(alphas, 10):.3f}, {np.percentile(alphas, 90):.3f}] "
                f"[{np.percentile(gammas, 10):.3f}, {np.percentile(gammas, 90):.3f}]"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=("prior", "evaluate"))
    parser.add_argument("--block", type=int, default=TONE_BLOCK)
    parser.add_argument("--draws", type=int, default=4, help="darkenings per held-out image")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--noise-scale", type=float, default=1.0, help="scale the drawn noise (0: none)")
    parser.add_argument("--no-paper-prior", action="store_true", help="fit without the prior on alpha, gamma")
    parser.add_argument("--no-real", action="store_true", help="skip the real references")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.command == "prior":
        mean, spread = measure_prior(args.block)
        print(f"# block {args.block}, p = {PROBABILITIES[0]} .. {PROBABILITIES[-1]}")
        for name, table in (("TONE_PRIOR_LOG_QUANTILES", mean), ("TONE_PRIOR_LOG_SPREAD", spread)):
            print(f"{name}: tuple[float, ...] = (")
            for start in range(0, len(table), 8):
                print("    " + " ".join(f"{v:.4f}," for v in table[start : start + 8]))
            print(")")
        return
    shipped = args.block == TONE_BLOCK and len(TONE_PRIOR_LOG_QUANTILES) == len(PROBABILITIES)
    prior = np.asarray(TONE_PRIOR_LOG_QUANTILES) if shipped else measure_prior(args.block)[0]
    evaluate(args.block, args.draws, args.seed, prior, args.noise_scale, not args.no_paper_prior)
    if not args.no_real:
        real(args.block, prior)


if __name__ == "__main__":
    main()
