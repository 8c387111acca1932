"""Colour cast of `apply`'s output against the reference's, with and without ``--match-colour``.

Makes: docs/darkening-estimate.md, "Colour cast matched per input (`--match-colour`, off by default)" (the table of
the colour gap and the luminance gap, median and worst, as before and matched).

Run from the repo root::

    PYTHONPATH=src .venv/bin/python scripts/light/colour_match_check.py

Options: ``[--data ../shared/data] [--images 6]``. It imports ``exposure_match_check`` from its own folder (on the
path when the file is run as a script).

For every shared real low-light reference (LOL and LIME images, the first frame of each phone clip and of the
starlight video), its tone target (:func:`darksynth.light.tones.tone_quantiles`, ``median_noise``, ``colour_cast``),
then the first ``--images`` Kodak images darkened to it as ``apply`` does (``matched_darkening``), with the
shipped profile's noise, (a) as today and (b) with the colour matched (``matched_colour``). Printed per reference
and over all pairs: the colour gap, the mean absolute difference between the output's channel shares
(:func:`darksynth.light.tones.colour_cast`) and the reference's, and the luminance gap of
``scripts/light/exposure_match_check.py``, which the colour match must not worsen.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import torch

from darksynth.estimation.reference import load_reference
from darksynth.exposure import matched_colour, matched_darkening
from darksynth.io.images import read_image
from darksynth.light.tones import ToneTarget, colour_cast, median_noise, tone_quantiles
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer

# The same references and luminance measure as the exposure check (this script's folder is on the path).
from exposure_match_check import KINDS, luminance_quantiles, references  # isort: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--images", type=int, default=6)
    args = parser.parse_args()
    noise = load_profile(default_profile_path()).noise
    cleans = [
        torch.from_numpy(np.array(read_image(p).pixels)).permute(2, 0, 1).contiguous()
        for p in sorted((args.data / "clean" / "images" / "kodak24").glob("*.png"))[: args.images]
    ]
    totals: dict[str, list[float]] = {"colour as today": [], "colour matched": [], "luma today": [], "luma matched": []}
    for name, path, clip in references(args.data, KINDS):
        reference = load_reference(path, clip=clip, max_frames=1)[:1]
        cast = colour_cast(reference)
        if cast is None or luminance_quantiles(reference[0])[-1] < 2.0 / 255.0:
            print(f"{name:<30} skipped: black or grey")
            continue
        tone = ToneTarget(tuple(tone_quantiles(reference)), median_noise(reference), cast)
        target = luminance_quantiles(reference[0])
        rows: dict[str, list[float]] = {key: [] for key in totals}
        for index, clean in enumerate(cleans):
            darkening = matched_darkening(clean, tone, source=name)
            if darkening is None:
                continue
            plain = ClipParameters(noise, darkening)
            colour = matched_colour(clean, tone, darkening)
            matched = (
                plain if colour is None else dataclasses.replace(plain, colour_scale=colour[0], darkening=colour[1])
            )
            for label, parameters in (("today", plain), ("matched", matched)):
                synthesizer = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(index))
                output = synthesizer.image(clean).to(torch.float32) / 255.0
                own = colour_cast(output[None])
                rows[f"colour {'as today' if label == 'today' else 'matched'}"].append(
                    float(np.abs(np.subtract(own, cast)).mean()) if own is not None else float("nan")
                )
                rows[f"luma {label}"].append(float(np.abs(luminance_quantiles(output) - target).mean()))
        for key, values in rows.items():
            totals[key].extend(values)
        shares = " ".join(f"{c:.2f}" for c in cast)
        print(
            f"{name:<30} cast {shares}  colour gap {np.median(rows['colour as today']):.3f} -> "
            f"{np.median(rows['colour matched']):.3f}  luma gap {np.median(rows['luma today']):.3f} -> "
            f"{np.median(rows['luma matched']):.3f}"
        )
    for key, values in totals.items():
        print(f"{key:<16} over {len(values)} pairs: median {np.nanmedian(values):.3f}, worst {np.nanmax(values):.3f}")


if __name__ == "__main__":
    main()
