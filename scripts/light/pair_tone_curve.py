"""The tone curve between the low- and normal-light images of real enhancement pairs: ``low = a * high ** p``, fitted
in log on 8-px block means, per pair; ``p = 1 / gamma`` of darksynth's darkening ``alpha * x ** (1 / gamma)``.

Makes: docs/tutorial.md, "An enhancer that sees its input at one exposure", its bullets on the tone curve's exponent
and on what the gap is.

Run from the repo root::

    .venv/bin/python scripts/light/pair_tone_curve.py --pairs ../shared/data/enhance-pairs/lol

Blocks whose normal-light mean lies in 0.05-0.9 (off the crushed black and the clipped white) and whose low-light
mean is above 2 levels enter the fit. Printed: per pair, its gain (mean over mean), a and p; then the exponent
``estimate`` reads from the low image alone (against the tones of average clean scenes,
:func:`~darksynth.estimation.darkening_reading.estimate_darkening`), and the exponent the normal-light image itself
reads against those tones (:func:`~darksynth.light.tone_fit.fit_darkening` without the paper's prior: 1 for a scene
with the average scene's tones). A reading from the low image is the pair's p times the high image's own exponent
when the high image is not an average scene: what a reference cannot show is the tone its pair's target has.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from darksynth.estimation.darkening_reading import estimate_darkening
from darksynth.light.tone_fit import fit_darkening
from darksynth.light.tones import tone_quantiles

BLOCK = 8


def block_means(image: np.ndarray) -> np.ndarray:
    """(H / BLOCK, W / BLOCK, C) means of an (H, W, C) image's whole blocks."""
    height, width = image.shape[0] // BLOCK * BLOCK, image.shape[1] // BLOCK * BLOCK
    blocks = image[:height, :width].reshape(height // BLOCK, BLOCK, width // BLOCK, BLOCK, -1)
    return blocks.mean(axis=(1, 3))


def tone_curve(low: np.ndarray, high: np.ndarray) -> tuple[float, float]:
    """(a, p) of ``low = a * high ** p`` on the block means of two (H, W, 3) images in [0, 1]."""
    low_means, high_means = block_means(low).ravel(), block_means(high).ravel()
    used = (high_means > 0.05) & (high_means < 0.9) & (low_means > 2.0 / 255.0)
    design = np.vstack([np.ones(int(used.sum())), np.log(high_means[used])]).T
    (log_a, p), *_ = np.linalg.lstsq(design, np.log(low_means[used]), rcond=None)
    return float(np.exp(log_a)), float(p)


def read_exponents(low: np.ndarray, high: np.ndarray) -> tuple[float, float]:
    """(the exponent 1 / gamma read from ``low`` alone, the exponent ``high`` reads against average scenes)."""
    low_reading = estimate_darkening(torch.from_numpy(low).permute(2, 0, 1).float())
    high_reading = fit_darkening(tone_quantiles(torch.from_numpy(high).permute(2, 0, 1).float()), use_prior=False)
    return 1.0 / low_reading.darkening.gamma, 1.0 / high_reading.darkening.gamma


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=Path, required=True)
    arguments = parser.parse_args()
    exponents, low_reads, high_reads = [], [], []
    for low_path in sorted((arguments.pairs / "low").iterdir()):
        low = np.asarray(Image.open(low_path).convert("RGB"), dtype=np.float64) / 255.0
        high = np.asarray(Image.open(arguments.pairs / "high" / low_path.name).convert("RGB"), dtype=np.float64) / 255.0
        a, p = tone_curve(low, high)
        low_read, high_read = read_exponents(low, high)
        exponents.append(p)
        low_reads.append(low_read)
        high_reads.append(high_read)
        print(
            f"{low_path.name:12s} gain {high.mean() / low.mean():5.1f}x  low = {a:.3f} * high ** {p:.2f}  "
            f"read from low {low_read:.2f}  high against average scenes {high_read:.2f}  p * that {p * high_read:.2f}"
        )
    print(
        f"median p {np.median(exponents):.2f}, read from low {np.median(low_reads):.2f}, "
        f"high against average scenes {np.median(high_reads):.2f}"
    )


if __name__ == "__main__":
    main()
