"""Parsing the results document: the typed model keeps what the runner wrote and tolerates what it may leave out."""

from __future__ import annotations

import math

from darksynth.evaluation.report.results_model import (
    BandStatistics,
    CameraScores,
    ChannelStatistics,
    MethodScores,
    parse_results,
)
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
        kld_naflow=0.1,
        kld_naflow_ci95=(1.5 * 0.05, 2.5 * 0.05),
        akld=0.05 + 0.1,
        akld_ci95=(0.05, 0.05 + 0.2),
        band_rms_log_error=3 * 0.05,
        channel_correlation_gap=0.05 + 0.02,
        fid=12.5,
        kid=0.004,
        kid_std=0.001,
        oracle=None,
        per_camera={
            "Canon5D2": CameraScores(8, 0.04, (0.9 * 0.04, 1.1 * 0.04), 0.08, (0.08, 0.08)),
            "Sony_A7II": CameraScores(4, 0.07, (0.9 * 0.07, 1.1 * 0.07), 0.1, (0.1, 0.1)),
        },
        channels=ChannelStatistics(
            noise_std={"r": 0.02 * 0.5, "g": 0.02 * 1.1 * 0.5, "b": 0.02 * 0.9 * 0.5},
            level_ratio={"r": 0.5, "g": 1.1 * 0.5, "b": 0.9 * 0.5},
            correlation={"rg": 0.1, "gb": 0.2, "rb": -0.05},
        ),
        bands=BandStatistics(
            power={"brightness": (4e-4 * 0.5,) * 5, "colour": (1e-4, 2e-4, 4e-4, 8e-4, None)},
            white_ratio={},
            ratio={"brightness": (0.5, 0.5, 1.0, 1.0, 0.5), "colour": (0.5, 1.0, 0.5, 0.25, None)},
            texture_ratio=1.0,
        ),
    )
    real = results.sets["polyu"].real
    assert real == ChannelStatistics(
        noise_std={"r": 0.02, "g": 0.02, "b": 0.02}, level_ratio={}, correlation={"rg": 0.3, "gb": 0.25, "rb": 0.2}
    )
    assert results.sets["polyu"].real_bands is not None
    assert results.sets["polyu"].real_bands.white_ratio["colour"] == (0.5, 1.5, 8.0, 30.0, 75.0)
    assert results.sets["polyu"].real_bands.texture_ratio == 1.94
    assert results.sets["sidd"].real is None and results.sets["sidd"].real_bands is None
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
                        "x-oracle": {"kld": 1, "oracle": 0, "level_ratio": "high", "noise_std": {"r": "a", "g": 0.01}},
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
    assert results.sets["s"].methods["den"].channels is None
    channels = results.sets["s"].methods["x-oracle"].channels
    assert channels == ChannelStatistics(
        noise_std={"r": None, "g": 0.01, "b": None}, level_ratio={}, correlation={"rg": None, "gb": None, "rb": None}
    )
    assert results.sets["s"].pairs is None and results.sets["broken"].methods == {}
    assert results.oracles == frozenset()  # x-oracle says it is not one
    assert results.downstream is None
