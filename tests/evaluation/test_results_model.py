"""Parsing the results document: the typed model keeps what the runner wrote and tolerates what it may leave out."""

from __future__ import annotations

import math

from darksynth.evaluation.results_model import CameraScores, MethodScores, parse_results
from tests.evaluation.test_report import make_results


def test_parse_keeps_the_runners_values() -> None:
    results = parse_results(make_results())
    assert results.command.startswith("darksynth evaluate --pairs data/polyu")
    assert results.seed == 0 and results.seconds is None
    assert results.method_order == ("den", "awgn", "pg-oracle", "starlight")
    assert results.oracles == {"pg-oracle"}
    assert results.problems[0] == "polyu/noisy/x_1.png: no clean partner"
    assert results.provenance["inception"].endswith("sha256 0123abcd")
    assert results.not_evaluated("polyu") == ["starlight"] and results.not_evaluated("sidd") == []
    den = results.sets["polyu"].methods["den"]
    assert den == MethodScores(
        kld=0.05,
        kld_ci95=(0.8 * 0.05, 1.2 * 0.05),
        kld_srgb=0.09,
        kld_srgb_ci95=(0.8 * 0.09, 1.2 * 0.09),
        fid=12.5,
        kid=0.004,
        kid_std=0.001,
        oracle=None,
        per_camera={
            "Canon5D2": CameraScores(8, 0.04, (0.9 * 0.04, 1.1 * 0.04), 0.08, (0.08, 0.08)),
            "Sony_A7II": CameraScores(4, 0.07, (0.9 * 0.07, 1.1 * 0.07), 0.1, (0.1, 0.1)),
        },
    )
    assert results.sets["sidd"].methods["starlight"].fid is None


def test_parse_splits_the_downstream_document_into_sets_settings_notes_and_references() -> None:
    downstream = parse_results(make_results()).downstream
    assert downstream is not None
    assert list(downstream.sets) == ["polyu"]
    assert downstream.sets["polyu"]["den"].psnr == 38.25 and downstream.sets["polyu"]["den"].pairs == 12
    assert downstream.settings == {"network": "DnCNN-S", "epochs": "3"}
    assert downstream.notes == {"lpips": "not computed: no backbone weights", "seconds": "12.5"}
    assert downstream.problems == ("polyu/noisy/y.png: unreadable",)
    assert downstream.references == {"noisy input"}


def test_parse_tolerates_missing_and_odd_parts() -> None:
    assert parse_results({}).sets == {} and parse_results({}).downstream is None
    results = parse_results(
        {
            "command": ["darksynth", "evaluate"],
            "seed": "zero",
            "seconds": math.inf,
            "methods": "den",
            "problems": [{"file": "a.png", "why": "unreadable"}, "plain"],
            "sets": {
                "s": {
                    "pairs": "many",
                    "methods": {
                        "den": {"kld": math.nan, "kld_ci95": [0.1, math.nan], "fid": "12", "kid": True},
                        "x-oracle": {"kld": 1, "oracle": 0},
                        "weird": "not a mapping",
                    },
                },
                "broken": None,
            },
            "downstream": "skipped",
        }
    )
    assert results.command == '[\n "darksynth",\n "evaluate"\n]'
    assert results.seed is None and results.seconds is None and results.methods == {}
    assert results.problems == ('{\n "file": "a.png",\n "why": "unreadable"\n}', "plain")
    den = results.sets["s"].methods["den"]
    assert den.kld is not None and math.isnan(den.kld)  # shown as nan, ranked nowhere
    assert den.kld_ci95 is None and den.fid is None and den.kid is None
    assert results.sets["s"].methods["x-oracle"].kld == 1.0
    assert results.sets["s"].methods["weird"] == MethodScores()
    assert results.sets["s"].pairs is None and results.sets["broken"].methods == {}
    assert results.oracles == frozenset()  # x-oracle says it is not one
    assert results.downstream is None
