"""Exposure of `apply`'s output against the reference's: the profile's one darkening against one matched per input.

Run: ``.venv/bin/python scripts/exposure_match_check.py [--data ../shared/data] [--images 6]``.

For every shared real low-light reference (LOL and LIME images, the first frame of each phone clip, the starlight
video's first frame): the profile ``estimate`` writes, then the first ``--images`` Kodak images through
``darksynth.synthesize`` with (a) the profile's darkening (the estimate's alpha and gamma, what ``apply`` does
today) and (b) the darkening matched to that image by :func:`darksynth.exposure.match_darkening`. The
gap (issue 25's measure): the mean absolute difference of the output's luminance quantiles at 5, 10, ..., 95%
and the reference's, on the [0, 1] scale. Printed: per reference the median gap over the images for (a) and (b),
then the median and worst over all (reference, image) pairs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from darksynth.darkening import Darkening
from darksynth.errors import DarksynthError
from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.exposure import match_darkening
from darksynth.io.images import read_image
from darksynth.synthesize import synthesize
from darksynth.tones import median_noise, tone_quantiles
from darksynth.training.weights import default_weights_path, load_weights

LEVELS = np.arange(0.05, 0.951, 0.05)
LUMA = torch.tensor([0.2126, 0.7152, 0.0722])


def luminance_quantiles(image: torch.Tensor) -> np.ndarray:
    """Quantiles at 5-95% of the luminance of (..., 3, H, W) in [0, 1]."""
    luma = torch.einsum("c,...chw->...hw", LUMA, image.to(torch.float32)).flatten().numpy()
    return np.quantile(luma, LEVELS)


def references(data: Path) -> list[tuple[str, Path, bool]]:
    lowlight = data / "real-lowlight"
    found = [(f"lol {p.name}", p, False) for p in sorted((lowlight / "images" / "lol").glob("*.png"))]
    found += [(f"lime {p.name}", p, False) for p in sorted((lowlight / "images" / "lime").glob("*.png"))]
    found += [(f"clip {p.name}", p, True) for p in sorted((lowlight / "clips").iterdir()) if p.is_dir()]
    found += [(f"video {p.name}", p, False) for p in sorted((lowlight / "videos").iterdir())]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--images", type=int, default=6)
    args = parser.parse_args()
    network = load_weights(default_weights_path())
    cleans = [
        torch.from_numpy(np.array(read_image(p).pixels)).permute(2, 0, 1).to(torch.float32) / 255.0
        for p in sorted((args.data / "clean" / "images" / "kodak24").glob("*.png"))[: args.images]
    ]
    gaps: dict[str, list[float]] = {"profile": [], "matched": []}
    for name, path, clip in references(args.data):
        reference = load_reference(path, clip=clip, max_frames=4 if clip else 16)[:1]
        target = luminance_quantiles(reference[0])
        if target[-1] < 2.0 / 255.0:
            print(f"{name:<28} skipped: black (95% luminance quantile {target[-1] * 255:.1f} levels)")
            continue
        profile = estimate(reference, network, source=name).profile
        quantiles, noise = tone_quantiles(reference), median_noise(reference)
        rows: dict[str, list[float]] = {"profile": [], "matched": []}
        for index, clean in enumerate(cleans):
            generator = torch.Generator().manual_seed(index)
            try:
                matched: Darkening | str = match_darkening(quantiles, noise, clean, source=name).darkening
            except DarksynthError as error:
                print(f"{name:<28} {error}")
                matched = "profile"
            for label, darkening in (("profile", "profile"), ("matched", matched)):
                result = synthesize(clean, profile, darkening=darkening, generator=generator)  # type: ignore[arg-type]
                output = torch.as_tensor(result.image)
                gap = float(np.abs(luminance_quantiles(output) - target).mean())
                rows[label].append(gap)
                gaps[label].append(gap)
        print(
            f"{name:<28} median gap: profile's darkening {np.median(rows['profile']):.3f}, matched "
            f"{np.median(rows['matched']):.3f}"
        )
    for label, values in gaps.items():
        print(f"{label:<8} over {len(values)} pairs: median {np.median(values):.3f}, worst {np.max(values):.3f}")


if __name__ == "__main__":
    main()
