"""Quick check of blind methods against the real pairs (validation only, nothing is fitted to them).

Makes: nothing a current doc shows. Its figures are quoted in docs/refine.md ("Version 2 of the steps" table and
"Version 3: the default", the subsample ``den 10``), run at the time with the retired ``den-refined`` and
``srgb-oracle`` methods. Kept as a development harness: a one-minute subsample of ``darksynth evaluate`` to compare
estimator changes before the full run.

Run from the repo root::

    .venv/bin/python scripts/noise/blind_real_check.py den,den-network,spectral-oracle 10

Arguments (positional, no options): ``[METHODS [POLYU_STEP]]``: comma-separated evaluation methods (default
``den,den-network,spectral-oracle``), every POLYU_STEP-th polyu pair (default 10), every nam-cc15 and sidd pair.
Prints, per set and method, the mean Noise Flow kld and kld_srgb, the synthetic / real noise std per channel
(pooled), the mean channel correlation of the synthetic noise beside the real one's, and the fit + synthesis time
per pair.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from darksynth.evaluation.measures.metrics import channel_correlations, kl_divergence_noise_flow, kl_divergence_srgb
from darksynth.evaluation.methods.catalogue import build_method
from darksynth.evaluation.pairs import list_pair_set, load_pair
from darksynth.seeding import seeded_generator

ROOT = Path(__file__).resolve().parents[3] / "shared" / "data" / "real-pairs"


def main() -> int:
    methods = sys.argv[1].split(",") if len(sys.argv) > 1 else ["den", "den-network", "spectral-oracle"]
    steps = {"polyu": int(sys.argv[2]) if len(sys.argv) > 2 else 10, "nam-cc15": 1, "sidd": 1}
    built = {name: build_method(name) for name in methods}
    for set_name, step in steps.items():
        pairs = list_pair_set(ROOT / set_name).pairs[::step]
        rows = {
            m: {"kld": [], "kld_srgb": [], "var": np.zeros(3), "real": np.zeros(3), "corr": [], "s": 0.0}
            for m in methods
        }
        real_corr = []
        for index, pair in enumerate(pairs):
            loaded = load_pair(pair)
            real = (loaded.noisy - loaded.clean).numpy()
            real_corr.append(np.mean(list(channel_correlations(real).values())))
            for name in methods:
                start = time.perf_counter()
                values = built[name].fit(loaded.noisy, loaded.clean)
                synthetic = built[name].synthesize(loaded.clean, values, seeded_generator(index))
                row = rows[name]
                row["s"] += time.perf_counter() - start
                noise = (synthetic - loaded.clean).numpy()
                row["kld"].append(kl_divergence_noise_flow(real, noise))
                row["kld_srgb"].append(kl_divergence_srgb(real, noise))
                row["var"] += noise.var(axis=(1, 2))
                row["real"] += real.var(axis=(1, 2))
                row["corr"].append(np.mean(list(channel_correlations(noise).values())))
        for name, row in rows.items():
            ratio = np.sqrt(row["var"] / row["real"])
            print(
                f"{set_name:9s} n={len(pairs):3d} {name:14s} kld {np.mean(row['kld']):.3f} "
                f"kld_srgb {np.mean(row['kld_srgb']):.3f} std ratio {np.round(ratio, 2).tolist()} "
                f"corr {np.mean(row['corr']):.2f} (real {np.mean(real_corr):.2f}) {row['s'] / len(pairs):.1f} s/pair",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
