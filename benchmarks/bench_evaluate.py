"""Wall time and peak memory of `darksynth evaluate` on the shared real-pair sets with every method.

Run: ``.venv/bin/python benchmarks/bench_evaluate.py [--data ../shared/data] [--methods LIST]``. The command
runs in a child process (start-up, model loading and report writing included; wall time and peak RSS from
os.wait4). The target: the three shared sets with every method in under 10 minutes on the 2-core CPU. The last
line is ``evaluate_s=<seconds> peak_rss_mib=<MiB> sets=<n> pairs=<n>``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from darksynth.evaluation.methods.catalogue import DEFAULT_METHODS
from machine import cpu_summary


def main() -> int:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    parser.add_argument("--methods", default=",".join(DEFAULT_METHODS))
    args = parser.parse_args()
    sets = sorted(p for p in (args.data / "real-pairs").iterdir() if (p / "noisy").is_dir())
    if not sets:
        print(f"{args.data / 'real-pairs'}: no sets of pairs", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "evaluation"
        command = [sys.executable, "-m", "darksynth", "evaluate", "--methods", args.methods, "--out", str(out)]
        for root in sets:
            command += ["--pairs", str(root)]
        started = time.perf_counter()
        child = os.spawnv(os.P_NOWAIT, sys.executable, command)
        _, status, usage = os.wait4(child, 0)
        seconds = time.perf_counter() - started
        if os.waitstatus_to_exitcode(status) != 0:
            print("darksynth evaluate failed", file=sys.stderr)
            return 1
        results = json.loads((out / "results.json").read_text())
    pairs = sum(report["pairs"] for report in results["sets"].values())
    print(f"methods: {args.methods}; problems: {len(results['problems'])}")
    print(f"evaluate_s={seconds:.1f} peak_rss_mib={usage.ru_maxrss / 1024:.0f} sets={len(sets)} pairs={pairs}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
