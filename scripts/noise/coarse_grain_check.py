"""A warning tried for the round trip's silent low readings, and why it does not ship: a brightness spectrum that
rises steeply over the only two octaves a reference shows.

Makes: docs/spectral-noise.md, "Why the silent misses read low", its paragraph on the steep-rise rule.

Run from the repo root::

    .venv/bin/python scripts/noise/coarse_grain_check.py --roundtrip 0 100     # development seeds
    .venv/bin/python scripts/noise/coarse_grain_check.py --roundtrip 1000 100  # held-out seeds
    .venv/bin/python scripts/noise/coarse_grain_check.py --real                # every real reference, some pairs

Options: ``[--data ../shared/data] (--roundtrip FIRST COUNT | --real)``.

The rule: the probe reads at most two brightness octaves (``meta.spectrum.read_octaves.brightness``: periods under
about 11 px) and the estimated brightness power rises more than 8x from the finest octave to the next; the coarser
octaves are then held at the second one's level, which on noise correlated over several pixels misses most of its
power. It would warn "the profile's noise is likely weaker than the reference's".

``--roundtrip``: the cases of ``benchmarks/estimate_roundtrip.py`` (the same seeds give the same cases), each
case's std ratio (estimated over true) and whether the rule fires. ``--real``: every LIME, LOL and DICM photo and
every phone clip (whether it fires), and every sidd pair, every 4th of sidd-phones and nam-cc60, every 3rd of
nam-cc15 and every 5th of polyu, where a fire can be judged: the profile applied with ``apply --no-darken`` to the
clean image, its noise std over the real noise's (a fire is right where that is under 1). Printed: one line per
case, then per group how often the rule fires and the ratios where it does and where it does not.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import torch

from darksynth.apply import ApplyOptions, synthesize_image
from darksynth.estimation.assemble import Estimate, estimate
from darksynth.estimation.reference import load_reference
from darksynth.io.arrays import chw_to_hwc, hwc_to_chw
from darksynth.models.den import DEN
from darksynth.noise.spectral import OCTAVES
from darksynth.recipe import ClipRecipe
from darksynth.training.weights import default_weights_path, load_weights

STEEP_RISE = 8.0
"""The rise of brightness power from the finest octave to the next above which the rule calls it steep."""

SHORT_READ = 2
"""At most this many brightness octaves read: the rule's second condition."""

PAIR_EVERY = {"sidd": 1, "sidd-phones": 4, "nam-cc15": 3, "nam-cc60": 4, "polyu": 5}


def steep_rise(found: Estimate) -> tuple[int | None, float | None, bool]:
    """The brightness octaves read, the rise from the finest to the next, and whether the rule fires."""
    read = (found.profile.meta.get("spectrum", {}).get("read_octaves") or {}).get("brightness")
    if read is None:
        return None, None, False
    power = found.profile.noise["octave_power"].reshape(OCTAVES, 3)[:, 0].clamp_min(1e-30)
    rise = float(power[1] / power[0])
    return read, rise, read <= SHORT_READ and rise > STEEP_RISE


def _summary(groups: dict[str, list[dict[str, Any]]]) -> None:
    print()
    for group, rows in groups.items():
        fired = [r["ratio"] for r in rows if r["fires"] and r["ratio"] is not None]
        quiet = [r["ratio"] for r in rows if not r["fires"] and r["ratio"] is not None]
        line = f"{group:12s} {len(rows):4d} cases, fires on {sum(r['fires'] for r in rows)}"
        if fired:
            line += f"; ratio where it fires {min(fired):.2f}-{max(fired):.2f} (median {statistics.median(fired):.2f})"
        if quiet:
            line += f", elsewhere median {statistics.median(quiet):.2f}"
        print(line)


def run_roundtrip(data: Path, network: DEN, first: int, count: int) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import estimate_roundtrip as roundtrip  # the benchmark's own cases

    captured: dict[str, Estimate] = {}

    def estimate_and_keep(*arguments: Any, **keywords: Any) -> Estimate:
        captured["found"] = estimate(*arguments, **keywords)
        return captured["found"]

    roundtrip.estimate = estimate_and_keep
    rows = []
    for seed in range(first, first + count):
        case = roundtrip.run_case(data, network, seed)
        read, rise, fires = steep_rise(captured["found"])
        rows.append({"ratio": case["std_ratio"], "fires": fires})
        shown = f"{case['kind']:10s} read {read} rise {rise or 0:10.2f} fires {fires!s:5s}"
        print(f"{seed:5d} {shown} ratio {case['std_ratio']:.2f}", flush=True)
    _summary({"round trip": rows})


def _level_ratio(found: Estimate, noisy: torch.Tensor, clean: torch.Tensor, name: str) -> float:
    pixels = (clean[0] * 255).round().clamp(0, 255).to(torch.uint8)
    options = ApplyOptions(recipe=ClipRecipe(found.profile, darkening=None), seed=0)
    synthetic = hwc_to_chw(synthesize_image(chw_to_hwc(pixels), name, options)[0]).float() / 255
    return float((synthetic - clean[0]).std() / (noisy[0] - clean[0]).std())


def run_real(data: Path, network: DEN) -> None:
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)

    def record(group: str, name: str, found: Estimate, ratio: float | None) -> None:
        read, rise, fires = steep_rise(found)
        groups[group].append({"ratio": ratio, "fires": fires})
        shown = "" if ratio is None else f" level {ratio:.2f}"
        print(f"{group:12s} {name:40s} read {read} rise {rise or 0:10.2f} fires {fires!s:5s}{shown}", flush=True)

    for folder in ("lime", "lol", "dicm"):
        for path in sorted((data / "real-lowlight/images" / folder).iterdir()):
            record(folder, path.name, estimate(load_reference(path), network, source=path.name), None)
    for clip in sorted((data / "real-lowlight/clips").iterdir()):
        record("clips", clip.name, estimate(load_reference(clip, clip=True), network, source=clip.name), None)
    for pair_set, every in PAIR_EVERY.items():
        for noisy_path in sorted((data / "real-pairs" / pair_set / "noisy").iterdir())[::every]:
            clean_path = data / "real-pairs" / pair_set / "clean" / noisy_path.name
            noisy, clean = load_reference(noisy_path), load_reference(clean_path)
            found = estimate(noisy, network, source=noisy_path.name)
            record(pair_set, noisy_path.name, found, _level_ratio(found, noisy, clean, clean_path.name))
    _summary(groups)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--roundtrip", type=int, nargs=2, metavar=("FIRST", "COUNT"))
    parser.add_argument("--real", action="store_true")
    arguments = parser.parse_args()
    torch.set_num_threads(1)
    network = load_weights(default_weights_path())
    if arguments.roundtrip:
        run_roundtrip(arguments.data, network, *arguments.roundtrip)
    if arguments.real:
        run_real(arguments.data, network)


if __name__ == "__main__":
    main()
