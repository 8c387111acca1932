"""Exposure of `apply`'s output against the reference's: the block-median match, the match fitted on the output's
luminance quantiles, and the best global darkening found in hindsight.

Makes: docs/darkening-estimate.md, "Exposure fitted on the output's luminance quantiles" / "Figures" (the table of
the median gap per set: block medians, output quantiles, hindsight floor), and the earlier table of "Exposure
matched per input (issue 25, first step)".

Run from the repo root::

    PYTHONPATH=src .venv/bin/python scripts/light/exposure_match_check.py --data ../shared/data --images 6
    PYTHONPATH=src .venv/bin/python scripts/light/exposure_match_check.py --data ../shared/data --images 6 \
        --skip-images 6 --kinds lime clip video

Options: ``[--data ../shared/data] [--images 6] [--skip-images 0] [--kinds lol lime clip video]``.
``scripts/light/colour_match_check.py`` imports its references and luminance measure.

For every shared real low-light reference (LOL and LIME images, the first frame of each phone clip, the starlight
video's first frame): the profile ``estimate`` writes, then Kodak images (8-bit, as ``apply`` reads them; the
first ``--images`` after ``--skip-images``) through ``darksynth.synthesize`` with the same seed per image, darkened
(a) by the block-median match alone (the profile's tone without its luminance quantiles, as profiles before them
are read), (b) by the match fitted on the output's luminance quantiles (the profile as ``estimate`` writes it now)
and (c) by the best global alpha and gamma for the pair, found in hindsight by a direct search on the synthesized
output: a grid over alpha in [0.005, 1] and gamma in [0.1, 2], then a compass search from the best of the grid,
(a) and (b). The gap: the mean absolute difference of the 8-bit output's luminance quantiles at 5, 10, ..., 95%
and the reference's, on the [0, 1] scale. Printed: per reference the median gap over the images for each, then
the median and worst over all (reference, image) pairs and the ratios of the medians to (c)'s.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.exposure import compass_search
from darksynth.io.images import read_image
from darksynth.light.darkening import Darkening
from darksynth.profile import Profile
from darksynth.synthesize import synthesize
from darksynth.tensors import luminance
from darksynth.training.weights import default_weights_path, load_weights

LEVELS = np.arange(0.05, 0.951, 0.05)
GRID_ALPHA = np.geomspace(0.005, 1.0, 9)
GRID_GAMMA = np.geomspace(0.1, 2.0, 7)
KINDS = ("lol", "lime", "clip", "video")


def luminance_quantiles(image: torch.Tensor) -> np.ndarray:
    """Quantiles at 5-95% of the luminance of (..., 3, H, W) in [0, 1]."""
    return np.quantile(luminance(image.to(torch.float32)).flatten().numpy(), LEVELS)


def references(data: Path, kinds: tuple[str, ...]) -> list[tuple[str, Path, bool]]:
    lowlight = data / "real-lowlight"
    found = [(f"lol {p.name}", p, False) for p in sorted((lowlight / "images" / "lol").glob("*.png"))]
    found += [(f"lime {p.name}", p, False) for p in sorted((lowlight / "images" / "lime").glob("*.png"))]
    found += [(f"clip {p.name}", p, True) for p in sorted((lowlight / "clips").iterdir()) if p.is_dir()]
    found += [(f"video {p.name}", p, False) for p in sorted((lowlight / "videos").iterdir())]
    return [item for item in found if item[0].split()[0] in kinds]


def hindsight_best(gap: Callable[[Darkening], float], starts: list[Darkening]) -> tuple[float, Darkening]:
    """The least gap over a grid of alpha and gamma, refined by a compass search in (log alpha, log gamma) from
    the best of the grid and ``starts``."""
    candidates = [Darkening(float(a), float(g)) for a in GRID_ALPHA for g in GRID_GAMMA] + starts
    best = min(candidates, key=gap)

    def at(point: np.ndarray) -> Darkening:
        return Darkening(float(np.clip(np.exp(point[0]), 0.005, 1.0)), float(np.clip(np.exp(point[1]), 0.1, 2.0)))

    point = compass_search(lambda p: gap(at(p)), np.log([best.alpha, best.gamma]), 0.25, 0.008)
    return gap(at(point)), at(point)


def pair_gaps(clean: torch.Tensor, profile: Profile, target: np.ndarray, seed: int) -> dict[str, float]:
    """The three gaps of one (reference, image) pair."""

    def run(chosen: Profile, darkening: Darkening | str) -> tuple[float, Darkening]:
        result = synthesize(clean, chosen, darkening=darkening, generator=torch.Generator().manual_seed(seed))  # type: ignore[arg-type]
        output = torch.as_tensor(result.image).to(torch.float32) / 255.0
        used = result.parameters["darkening"]  # type: ignore[call-overload]
        return float(np.abs(luminance_quantiles(output) - target).mean()), Darkening(used["alpha"], used["gamma"])

    assert profile.tone is not None
    block_only = dataclasses.replace(profile, tone=dataclasses.replace(profile.tone, luminance=None))
    before, before_darkening = run(block_only, "profile")
    after, after_darkening = run(profile, "profile")
    best, _ = hindsight_best(lambda d: run(profile, d)[0], [before_darkening, after_darkening])
    return {"block medians": before, "output quantiles": after, "hindsight": min(best, before, after)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--images", type=int, default=6)
    parser.add_argument("--skip-images", type=int, default=0)
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    args = parser.parse_args()
    network = load_weights(default_weights_path())
    paths = sorted((args.data / "clean" / "images" / "kodak24").glob("*.png"))
    cleans = [
        torch.from_numpy(np.array(read_image(p).pixels)).permute(2, 0, 1).contiguous()
        for p in paths[args.skip_images : args.skip_images + args.images]
    ]
    gaps: dict[str, list[float]] = {"block medians": [], "output quantiles": [], "hindsight": []}
    for name, path, clip in references(args.data, tuple(args.kinds)):
        reference = load_reference(path, clip=clip, max_frames=4 if clip else 16)[:1]
        target = luminance_quantiles(reference[0])
        if target[-1] < 2.0 / 255.0:
            print(f"{name:<28} skipped: black (95% luminance quantile {target[-1] * 255:.1f} levels)")
            continue
        profile = estimate(reference, network, source=name).profile
        if profile.tone is None:
            print(f"{name:<28} skipped: no tone target (too dark to read)")
            continue
        rows: dict[str, list[float]] = {label: [] for label in gaps}
        for index, clean in enumerate(cleans):
            found = pair_gaps(clean, profile, target, index)
            print(
                f"  {name} kodak {args.skip_images + index + 1}: " + ", ".join(f"{k} {v:.4f}" for k, v in found.items())
            )
            for label, gap in found.items():
                rows[label].append(gap)
                gaps[label].append(gap)
        print(f"{name:<28} median gap: " + ", ".join(f"{k} {np.median(v):.3f}" for k, v in rows.items()), flush=True)
    floor = float(np.median(gaps["hindsight"]))
    for label, values in gaps.items():
        print(
            f"{label:<17} over {len(values)} pairs: median {np.median(values):.4f}, worst {np.max(values):.3f}, "
            f"median / hindsight's {np.median(values) / floor:.2f}"
        )


if __name__ == "__main__":
    main()
