"""Leave-one-set-out check of the camera prior on the bank: what it expects of the texture gain and the coarse
octaves, given what a blind estimate measures, against each pair's clean-aided fit.

Makes: docs/camera-prior.md, "Leave one set out: what the prior expects" (the table per set).

Run from the repo root::

    PYTHONPATH=src .venv/bin/python scripts/noise/camera_prior_check.py

Options: ``--bank FILE`` (default the shipped bank).

For every record of a set, the prior fitted without the set and the sets of the same cameras
(:func:`darksynth.cameras.prior.held_out_sets`) is conditioned on the record's own level curve and finer octaves
(:func:`darksynth.cameras.prior.measured_entries`, without the JPEG strength, as the fit's constraint is) -- the
best a blind estimate could give it -- and its conditional mean is compared with the record: the texture gain, and
the power of each coarse octave (23, 45, 90 px) in brightness and the two colour components, as the median over the
set's records of expected over fitted.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from darksynth.cameras.bank import BANK_PATH, CameraRecord, read_bank, without_sets
from darksynth.cameras.prior import BLIND_OCTAVES, fit_prior, held_out_sets, measured_entries
from darksynth.noise.spectral import OCTAVES


def check_set(bank: tuple[CameraRecord, ...], judged: str) -> str:
    """One table row: the set, its records, the texture gain expected and fitted (medians), the coarse octaves'
    expected over fitted power."""
    prior = fit_prior(without_sets(bank, held_out_sets(judged)))
    parts = prior.slices()
    expected_gain, fitted_gain, ratios = [], [], []
    for record in (record for record in bank if record.set == judged):
        values = {name: torch.tensor(value, dtype=torch.float64) for name, value in record.values.items()}
        known, mask = measured_entries(values)
        known.pop("compression", None)
        expected, fitted = prior.conditional_mean(known, mask), prior.features(values)
        if "texture_gain" in parts:
            expected_gain.append(float(expected[parts["texture_gain"]]))
            fitted_gain.append(float(fitted[parts["texture_gain"]]))
        power = parts["octave_power"]
        gap = expected[power].reshape(OCTAVES, 3)[BLIND_OCTAVES:] - fitted[power].reshape(OCTAVES, 3)[BLIND_OCTAVES:]
        ratios.append(gap.exp())
    median = torch.stack(ratios).median(0).values
    bands = " / ".join(" ".join(f"{float(v):.2f}" for v in median[:, component]) for component in range(3))
    gains = (
        f"{torch.tensor(expected_gain).median():.2f} vs {torch.tensor(fitted_gain).median():.2f}"
        if expected_gain
        else "-"
    )
    return f"| {judged} | {len(ratios)} | {', '.join(prior.sets)} | {gains} | {bands} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bank", type=Path, default=BANK_PATH)
    arguments = parser.parse_args()
    bank = read_bank(arguments.bank)
    print(
        "| set judged | records | prior fitted on | texture gain: expected vs fitted | coarse power expected / "
        "fitted: brightness / colour 1 / colour 2 (23, 45, 90 px) |"
    )
    print("|---|---|---|---|---|")
    for judged in sorted({record.set for record in bank}):
        print(check_set(bank, judged))


if __name__ == "__main__":
    main()
