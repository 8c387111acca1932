"""Noise that follows texture on the real pairs: the clean-aided fit's texture_gain and texture_scale, and the
textured-to-flat noise std ratio of the real noise and of the fitted model's.

Makes: docs/spectral-noise.md, "Noise that follows texture" (the table of median fitted gain and scale and the real
and synthetic textured-to-flat ratio per set).

Run from the repo root::

    .venv/bin/python scripts/noise/texture_check.py --pairs ../shared/data/real-pairs/polyu --limit 30

Options: ``--pairs DIR`` (repeatable) ``[--limit N] [--seed 0]``.

Per set, the first ``--limit`` pairs in name order (all without it), each through the ``spectral-oracle`` method of
``darksynth evaluate`` as the evaluation runs it (its fit, its synthesis, the evaluation's seed for the pair), and
the evaluation's measure (``evaluation.measures.texture.textured_flat_ratio``) on the real and the synthetic noise.
Printed: one line per pair, then per set the medians over pairs.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from darksynth.evaluation.measures.texture import textured_flat_ratio
from darksynth.evaluation.methods.catalogue import build_methods
from darksynth.evaluation.pairs import list_pair_set, load_pair
from darksynth.seeding import derive_seed, seeded_generator

METHOD = "spectral-oracle"


def check_set(root: Path, limit: int | None, seed: int) -> dict[str, float]:
    """Fit, synthesize and measure the first ``limit`` pairs of one set; the medians over its pairs."""
    methods, problems = build_methods([METHOD], weights={}, device="cpu")
    if problems:
        raise SystemExit("; ".join(problems))
    method = methods[METHOD]
    pair_set = list_pair_set(root)
    pairs = sorted(pair_set.pairs, key=lambda pair: pair.name)[:limit]
    rows = []
    for pair in pairs:
        started = time.perf_counter()
        loaded = load_pair(pair)
        values = method.fit(loaded.noisy, loaded.clean)
        generator = seeded_generator(derive_seed("darksynth", seed, f"{pair_set.name}/{pair.name}/{METHOD}"))
        synthetic = method.synthesize(loaded.clean, values, generator)
        row = {
            "gain": values.scalar("texture_gain"),
            "scale": values.scalar("texture_scale"),
            "real": textured_flat_ratio(loaded.noise, loaded.clean),
            "synthetic": textured_flat_ratio(synthetic - loaded.clean, loaded.clean),
        }
        rows.append(row)
        print(
            f"{pair_set.name} {pair.name}: gain {row['gain']:.3f} scale {row['scale']:.3f} ratio real "
            f"{row['real']:.3f} synthetic {row['synthetic']:.3f} ({time.perf_counter() - started:.1f} s)",
            flush=True,
        )
    medians = {key: statistics.median(row[key] for row in rows) for key in ("gain", "scale", "real", "synthetic")}
    print(
        f"{pair_set.name} ({len(rows)} pairs) median: gain {medians['gain']:.3f} scale {medians['scale']:.4f} "
        f"ratio real {medians['real']:.3f} synthetic {medians['synthetic']:.3f}",
        flush=True,
    )
    return medians


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=Path, action="append", required=True)
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    arguments = parser.parse_args()
    for root in arguments.pairs:
        check_set(root, arguments.limit, arguments.seed)


if __name__ == "__main__":
    main()
