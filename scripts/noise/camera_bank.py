"""The bank of real cameras: the spectral model fitted with the clean image on every shared real pair.

Makes: src/darksynth/data/camera_bank.json, the records the camera prior (src/darksynth/cameras/prior.py) is fitted
on, and through it docs/camera-prior.md's figures. Each record is one pair's clean-aided fit
(:func:`darksynth.estimation.noise.spectral_fit.oracle_spectral_fit`, seed 0) with its set, camera and ISO: fitted
numbers, not the pairs' pixels (the pairs' licences keep their images out of the repository).

Run from the repo root (about 4 s a pair, 173 pairs, 12 minutes on one core)::

    PYTHONPATH=src .venv/bin/python scripts/noise/camera_bank.py --data ../shared/data

Options: ``--sets`` (comma-separated, default every folder of real-pairs/), ``--limit N`` pairs a set (0: all),
``--out`` (default the shipped file).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from darksynth.cameras.bank import BANK_FORMAT, BANK_PATH, BANK_VERSION
from darksynth.estimation.noise.spectral_fit import oracle_spectral_fit
from darksynth.evaluation.pairs import list_pair_set, load_pair
from darksynth.io.atomic import write_text_atomic

DIGITS = 5
"""Significant digits kept per value: the fits' own spread between seeds is far larger."""


def _rounded(tensor: torch.Tensor) -> list[float]:
    return [float(f"{float(value):.{DIGITS}g}") for value in tensor.reshape(-1)]


def fit_set(root: Path, limit: int) -> list[dict[str, object]]:
    """One record per pair of the set at ``root`` (the first ``limit`` by name; 0: all)."""
    pair_set = list_pair_set(root)
    pairs = pair_set.pairs[:limit] if limit else pair_set.pairs
    records: list[dict[str, object]] = []
    for index, pair in enumerate(pairs):
        started = time.perf_counter()
        loaded = load_pair(pair)
        values = oracle_spectral_fit(loaded.noisy.to(torch.float32), loaded.clean.to(torch.float32))
        records.append(
            {
                "set": pair_set.name,
                "name": pair.name,
                "camera": pair.camera,
                "iso": pair.iso,
                "values": {name: _rounded(tensor) for name, tensor in sorted(values.items())},
            }
        )
        print(f"{pair_set.name} {index + 1}/{len(pairs)} {pair.name} {time.perf_counter() - started:.1f} s", flush=True)
    return records


def bank_text(bank: dict[str, object]) -> str:
    """The bank as JSON with one record a line: a diff of a refit shows which pairs moved."""
    records = bank["records"]
    assert isinstance(records, list)
    head = json.dumps({key: value for key, value in bank.items() if key != "records"}, indent=1)[:-2]
    lines = ",\n".join("  " + json.dumps(record) for record in records)
    return f'{head},\n "records": [\n{lines}\n ]\n}}\n'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--sets", default="")
    parser.add_argument("--limit", type=int, default=0)
    parser.add_argument("--out", type=Path, default=BANK_PATH)
    arguments = parser.parse_args()
    torch.set_num_threads(1)
    root = arguments.data / "real-pairs"
    names = arguments.sets.split(",") if arguments.sets else sorted(p.name for p in root.iterdir() if p.is_dir())
    records = [record for name in names for record in fit_set(root / name, arguments.limit)]
    bank = {
        "format": BANK_FORMAT,
        "version": BANK_VERSION,
        "fit": "darksynth.estimation.noise.spectral_fit.oracle_spectral_fit, seed 0, on each pair's noisy and "
        "clean image",
        "source": "../shared/data/real-pairs (sidd, nam-cc15, nam-cc60, polyu): fitted numbers only",
        "records": records,
    }
    write_text_atomic(arguments.out, bank_text(bank))
    print(f"wrote {len(records)} records to {arguments.out}")


if __name__ == "__main__":
    main()
