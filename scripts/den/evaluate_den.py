"""Round-trip acceptance of the DEN on held-out clean images: apply known parameters, estimate, compare.

Makes: docs/den.md, "Measured acceptance" (the table of R^2 per parameter, single image and 8-frame clip, against
the target 0.9).

Run from the repo root::

    .venv/bin/python scripts/den/evaluate_den.py --trials 48

Options: ``[--model srgb|paper] [--weights W] [--trials 48] [--frames 8] [--seed 0] [--data ../shared/data]``.

Held-out material: the 24 Kodak images (never used in training). Each trial picks an image, draws alpha and
gamma from the paper's ranges and every noise parameter of the model from its training range (all components
on; the sRGB model's shape parameters too), makes the low-light reference exactly as ``darksynth apply`` does (the
8-bit path, through a PNG file), and runs ``estimate`` on it. Three settings: single images (T = 1), static clips of
8 frames (noise redrawn every frame, temporal banding held), and for shot and read the same single images. Prints
R^2 per parameter and a JSON line with everything.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import torch

from darksynth.apply import ApplyOptions, apply
from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.light.darkening import Darkening
from darksynth.noise.components import NoiseModel
from darksynth.noise.sampling import random_darkening_values, random_noise_values
from darksynth.noise.values import NoiseValues, model_vector
from darksynth.profile import Profile
from darksynth.recipe import ClipRecipe
from darksynth.training.loop import r_squared, vector_names
from darksynth.training.weights import default_weights_path, load_weights


def draw_profile(generator: torch.Generator, model: NoiseModel) -> Profile:
    """Every parameter of the noise model from its training range (the others neutral), the paper's darkening."""
    noise = random_noise_values(generator=generator, dtype=torch.float64, noise_model=model)
    alpha, gamma = random_darkening_values(generator=generator)
    return Profile(
        noise=NoiseValues.from_values(noise),
        darkening=Darkening(float(alpha), float(gamma)),
    )


def vector(profile: Profile, model: NoiseModel) -> list[float]:
    return [float(v) for v in model_vector(profile.noise, model)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--weights", type=Path, default=None, help="default: the shipped DEN of --model")
    parser.add_argument("--model", choices=("srgb", "paper"), default="srgb")
    parser.add_argument("--trials", type=int, default=48)
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    images = sorted((args.data / "clean" / "images" / "kodak24").glob("*.png"))
    if not images:
        print(f"{args.data}: held-out Kodak images not found", file=sys.stderr)
        return 1
    args.weights = args.weights or default_weights_path("v3", args.model)
    model = load_weights(args.weights)
    generator = torch.Generator().manual_seed(args.seed)
    results: dict[str, dict[str, list[list[float]]]] = {
        "image": {"true": [], "estimated": []},
        "clip": {"true": [], "estimated": []},
    }
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        for trial in range(args.trials):
            source = images[trial % len(images)]
            profile = draw_profile(generator, model.noise_model)
            seed = int(torch.randint(0, 2**31, (), generator=generator))
            options = ApplyOptions(recipe=ClipRecipe(profile), seed=seed)
            single = work / f"single_{trial}.png"
            apply(source, single, options)
            clip_in, clip_out = work / f"clip_in_{trial}", work / f"clip_out_{trial}"
            clip_in.mkdir()
            for frame in range(args.frames):
                (clip_in / f"{frame:02d}.png").symlink_to(source)
            apply(clip_in, clip_out, ApplyOptions(recipe=ClipRecipe(profile), seed=seed, clip=True))
            for setting, reference in (
                ("image", load_reference(single)),
                ("clip", load_reference(clip_out, clip=True)),
            ):
                estimated = estimate(reference, model).profile
                results[setting]["true"].append(vector(profile, model.noise_model))
                results[setting]["estimated"].append(vector(estimated, model.noise_model))
            print(f"trial {trial + 1}/{args.trials}", file=sys.stderr, end="\r")
    summary = {}
    for setting, pairs in results.items():
        r2 = r_squared(torch.tensor(pairs["estimated"]), torch.tensor(pairs["true"]))
        summary[setting] = {
            name: round(float(v), 3) for name, v in zip(vector_names(model.noise_model), r2, strict=True)
        }
    print(f"weights {args.weights}, {args.trials} trials, clips of {args.frames} frames, seed {args.seed}")
    print(f"{'parameter':18s} {'R2 image':>9s} {'R2 clip':>9s}")
    for name in vector_names(model.noise_model):
        print(f"{name:18s} {summary['image'][name]:9.3f} {summary['clip'][name]:9.3f}")
    print(json.dumps({"summary": summary, "trials": args.trials, "frames": args.frames, "seed": args.seed}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
