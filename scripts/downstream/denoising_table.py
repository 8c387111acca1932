"""The downstream denoising table: `evaluate --downstream`'s check over several seeds, with the mean and spread of
each row, and each method's gap to the best other blind method, the oracle and the real-pair ceiling.

Makes: docs/tutorial.md, "Downstream denoising on every pair set" (the tables and verdicts), and the JSON record
``--out``.

Run from the repo root::

    .venv/bin/python scripts/downstream/denoising_table.py --sets sidd,sidd-phones,nam-cc15,nam-cc60,polyu \
        --seeds 0,1,2 --out downstream.json

Options: ``--methods`` (default: every blind method a user compares and pg-oracle), ``--steps`` (1500), ``--clean``
(repeatable; default the shared Kodak and CBSD68), ``--device``, ``--net small|dncnn`` (DnCNN's size with
``--device cuda`` and tens of thousands of steps), ``--data``.

Every seed runs :func:`darksynth.evaluation.measures.downstream.run_downstream` (the function behind `darksynth
evaluate --downstream`; the same denoiser, steps and clean images) in one process, so each noisy image is estimated
once for every seed. Rows: each method trained on parameters fitted on every pair of the set (as `evaluate` runs
it), ``den (other images)`` trained on profiles of the other fold's noisy images only, and ``real pairs (other
folds)``, trained on the other fold's real pairs (the ceiling; both tested only on pairs their training never saw).
Blind methods are those that read no clean image (not ``oracle``), the noisy input is the reference row. A method
"beats" another when its mean PSNR is higher by more than the larger of the two spreads (std over seeds).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from darksynth.evaluation.measures.denoiser import DENOISER_SIZES, DownstreamSettings
from darksynth.evaluation.measures.downstream import NOISY_INPUT, REAL_PAIRS, run_downstream
from darksynth.io.atomic import write_text_atomic
from machine import cpu_summary

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"
METHODS = "den,den-paper,den-network,awgn-blind,pg-blind,albu-gauss,albu-iso,albu-gauss-jpeg,pg-oracle"
ORACLES = frozenset({"pg-oracle", "spectral-oracle"})
"""Methods that read the clean image (never counted among the blind ones)."""


def summarise(runs: list[dict[str, Any]], set_name: str) -> dict[str, dict[str, float]]:
    """Per row, mean and std over the seeds of PSNR and SSIM."""
    rows: dict[str, dict[str, list[float]]] = {}
    for run in runs:
        for name, scores in run.get(set_name, {}).items():
            if scores.get("psnr") is not None:
                entry = rows.setdefault(name, {"psnr": [], "ssim": []})
                entry["psnr"].append(float(scores["psnr"]))
                entry["ssim"].append(float(scores["ssim"]))
    return {
        name: {
            "psnr": float(np.mean(values["psnr"])),
            "psnr_spread": float(np.std(values["psnr"])),
            "ssim": float(np.mean(values["ssim"])),
            "seeds": len(values["psnr"]),
        }
        for name, values in rows.items()
    }


def verdict(table: dict[str, dict[str, float]], method: str = "den") -> str:
    """How ``method`` stands against the best other blind method, the oracle and the ceiling."""
    if method not in table:
        return f"{method}: not run"
    own = table[method]
    blind = {
        name: row
        for name, row in table.items()
        if name not in (method, NOISY_INPUT, REAL_PAIRS) and name not in ORACLES and "(other images)" not in name
    }
    lines = []
    if blind:
        best = max(blind, key=lambda name: blind[name]["psnr"])
        margin = own["psnr"] - blind[best]["psnr"]
        spread = max(own["psnr_spread"], blind[best]["psnr_spread"])
        word = "beats" if margin > spread else "does not beat"
        lines.append(f"{method} {word} the best other blind method {best} by {margin:+.2f} dB (spread {spread:.2f})")
    for reference in ("pg-oracle", REAL_PAIRS, f"{method} (other images)"):
        if reference in table:
            lines.append(f"{reference}: {table[reference]['psnr'] - own['psnr']:+.2f} dB from {method}")
    return "; ".join(lines)


def markdown(set_name: str, table: dict[str, dict[str, float]]) -> str:
    lines = [f"**{set_name}**", "", "| training noise | PSNR (dB) | spread | SSIM | seeds |", "|---|---|---|---|---|"]
    for name, row in sorted(table.items(), key=lambda item: -item[1]["psnr"]):
        lines.append(f"| {name} | {row['psnr']:.2f} | {row['psnr_spread']:.2f} | {row['ssim']:.4f} | {row['seeds']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=SHARED)
    parser.add_argument("--sets", default="sidd,sidd-phones,nam-cc15,nam-cc60,polyu")
    parser.add_argument("--methods", default=METHODS)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--clean", type=Path, action="append", default=None)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--net", choices=tuple(DENOISER_SIZES), default="small")
    parser.add_argument("--out", type=Path, required=True)
    arguments = parser.parse_args(argv)
    clean = arguments.clean or [arguments.data / "clean" / "images" / name for name in ("kodak24", "cbsd68")]
    roots = [arguments.data / "real-pairs" / name for name in arguments.sets.split(",") if name]
    methods = [name for name in arguments.methods.split(",") if name]
    seeds = [int(seed) for seed in arguments.seeds.split(",") if seed]
    print(cpu_summary(), flush=True)
    runs = []
    for seed in seeds:
        width, depth = DENOISER_SIZES[arguments.net]
        settings = DownstreamSettings(
            steps=arguments.steps, seed=seed, device=arguments.device, width=width, depth=depth
        )
        runs.append(
            run_downstream(roots, methods, clean, settings, progress=lambda message: print(f"  {message}", flush=True))
        )
    tables = {root.name: summarise(runs, root.name) for root in roots}
    for name, table in tables.items():
        print(f"\n{markdown(name, table)}\n\n{verdict(table)}", flush=True)
    record = {
        "command": " ".join(sys.argv),
        "cpu": cpu_summary(),
        "seeds": seeds,
        "steps": arguments.steps,
        "net": arguments.net,
        "tables": tables,
        "verdicts": {name: verdict(table) for name, table in tables.items()},
        "problems": sorted({problem for run in runs for problem in run.get("problems", [])}),
        "seconds": [run.get("seconds") for run in runs],
    }
    write_text_atomic(arguments.out, json.dumps(record, indent=2) + "\n")
    print(f"\nwrote {arguments.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
