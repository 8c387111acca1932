"""Noise that follows texture on the real pairs: the fitted texture_gain and texture_scale, the textured-to-flat
noise std ratio of the real noise and of the fitted model's, and the synthetic-over-real std on the flat and on the
textured blocks.

Makes: docs/spectral-noise.md, "Noise that follows texture" (the table of median fitted gain and scale and the real
and synthetic textured-to-flat ratio per set, ``--method spectral-oracle``) and "What falls short, and what was
tried", its bullet on polyu's noise on texture (``--method den``).

Run from the repo root::

    .venv/bin/python scripts/noise/texture_check.py --pairs ../shared/data/real-pairs/polyu --limit 30
    .venv/bin/python scripts/noise/texture_check.py --method den --pairs ../shared/data/real-pairs/polyu --every 5

Options: ``--pairs DIR`` (repeatable) ``[--method spectral-oracle|den] [--limit N] [--every K] [--seed 0]``.

Per set, the first ``--limit`` pairs in name order (all without it; with ``--every K`` each K-th of them), each
through the method of ``darksynth evaluate`` as the evaluation runs it (its fit, its synthesis, the evaluation's
seed for the pair), and the evaluation's measure (``evaluation.measures.texture_ratio``: the noise's std on the
flat and on the textured blocks and their ratio) on the real and the synthetic noise. With ``den`` (the blind
estimate on the noisy image) also what a blind read of texture's noise would start from: the same ratio of the
residual of non-local means (``noisy - D(noisy)``, its strength by the estimate's rule,
``flat_blocks.denoiser_strength``, read on the whole image), on the real noisy image and on the synthetic one.
Printed: one line per pair, then per set the medians over pairs.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import torch

from darksynth.estimation.noise.flat_blocks import denoiser_strength
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.evaluation.measures.texture_ratio import flat_and_textured_std, textured_flat_ratio
from darksynth.evaluation.methods.catalogue import build_methods
from darksynth.evaluation.pairs import list_pair_set, load_pair
from darksynth.seeding import derive_seed, seeded_generator

METHODS = ("spectral-oracle", "den")
"""The clean-aided fit, and the blind estimate on the noisy image."""


def residual_ratio(noisy: torch.Tensor, clean: torch.Tensor, strength: float) -> float:
    """The textured-to-flat ratio of the non-local-means residual of ``noisy`` (C, H, W) at ``strength`` 8-bit
    levels, with the blocks of ``clean``: what a blind read of texture's noise sees."""
    return textured_flat_ratio(noisy - nlm_denoise(noisy[None], strength)[0], clean)


def check_pair(method_name: str, method: Any, pair_set: Any, pair: Any, seed: int) -> dict[str, float]:
    """One pair's fit, synthesis and figures."""
    loaded = load_pair(pair)
    values = method.fit(loaded.noisy, loaded.clean)
    generator = seeded_generator(derive_seed("darksynth", seed, f"{pair_set.name}/{pair.name}/{method_name}"))
    synthetic = method.synthesize(loaded.clean, values, generator)
    (real_flat, real_textured), (made_flat, made_textured) = (
        flat_and_textured_std(noise, loaded.clean) for noise in (loaded.noise, synthetic - loaded.clean)
    )
    row = {
        "gain": values.scalar("texture_gain"),
        "scale": values.scalar("texture_scale"),
        "real": real_textured / real_flat,
        "synthetic": made_textured / made_flat,
        "flat_level": made_flat / real_flat,
        "textured_level": made_textured / real_textured,
    }
    if method_name == "den":
        strength = denoiser_strength(loaded.noisy[None])
        row["residual_real"] = residual_ratio(loaded.noisy, loaded.clean, strength)
        row["residual_synthetic"] = residual_ratio(synthetic, loaded.clean, strength)
    return row


def check_set(root: Path, method_name: str, limit: int | None, every: int, seed: int) -> dict[str, float]:
    """Fit, synthesize and measure the first ``limit`` pairs of one set (each ``every``-th); the medians."""
    methods, problems = build_methods([method_name], weights={}, device="cpu")
    if problems:
        raise SystemExit("; ".join(problems))
    pair_set = list_pair_set(root)
    pairs = sorted(pair_set.pairs, key=lambda pair: pair.name)[:limit][::every]
    rows = []
    for pair in pairs:
        started = time.perf_counter()
        row = check_pair(method_name, methods[method_name], pair_set, pair, seed)
        rows.append(row)
        figures = " ".join(f"{key} {value:.3f}" for key, value in row.items())
        print(f"{pair_set.name} {pair.name}: {figures} ({time.perf_counter() - started:.1f} s)", flush=True)
    medians = {key: statistics.median(row[key] for row in rows) for key in rows[0]}
    figures = " ".join(f"{key} {value:.3f}" for key, value in medians.items())
    print(f"{pair_set.name} ({len(rows)} pairs, {method_name}) median: {figures}", flush=True)
    return medians


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=Path, action="append", required=True)
    parser.add_argument("--method", choices=METHODS, default=METHODS[0])
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--every", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    arguments = parser.parse_args()
    for root in arguments.pairs:
        check_set(root, arguments.method, arguments.limit, arguments.every, arguments.seed)


if __name__ == "__main__":
    main()
