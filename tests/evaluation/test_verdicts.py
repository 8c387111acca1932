"""Verdicts on small hand-built results: the best blind method per column, the headline, the checks beyond it."""

from __future__ import annotations

import math
from typing import Any

import pytest

from darksynth.evaluation.report.results_model import parse_results
from darksynth.evaluation.report.summary import beyond_paper_lines, headline_lines
from darksynth.evaluation.report.verdicts import (
    BeyondPaperCheck,
    Headline,
    best_methods,
    best_per_camera,
    best_per_downstream_metric,
    best_per_metric,
    beyond_paper_checks,
    headlines,
)


def results_with(sets: dict[str, dict[str, dict[str, Any]]], **extra: Any) -> dict[str, Any]:
    """A results document: set name -> method -> its metrics."""
    return {"sets": {name: {"pairs": 4, "methods": methods} for name, methods in sets.items()}, **extra}


def test_best_methods_ranks_finite_values_only_and_leaves_the_excluded_out() -> None:
    values = {"den": 0.2, "awgn": 0.5, "pg-oracle": 0.1, "broken": math.nan, "absent": None}
    assert best_methods(values) == {"pg-oracle"}
    assert best_methods(values, excluded={"pg-oracle"}) == {"den"}
    assert best_methods(values, excluded={"pg-oracle"}, higher_is_better=True) == {"awgn"}
    assert best_methods({"a": 0.3, "b": 0.3, "c": 0.4}) == {"a", "b"}  # a tie: both are best
    assert best_methods({"a": math.nan, "b": None}) == frozenset()
    assert best_methods({"a": -math.inf, "b": 1.0}) == {"b"}


def test_best_per_metric_skips_oracles_flagged_or_named_so() -> None:
    results = parse_results(
        results_with(
            {
                "s": {
                    "den": {"kld": 0.3, "kld_srgb": 0.2, "fid": 10.0, "kid": 0.01},
                    "awgn": {"kld": 0.2, "kld_srgb": 0.4, "fid": None, "kid": -0.001},
                    "pg-oracle": {"kld": 0.01, "kld_srgb": 0.01, "fid": 1.0, "kid": -0.01},
                    "fitted": {"kld": 0.001, "kld_srgb": 0.001, "fid": 0.1, "kid": -0.1, "oracle": True},
                }
            }
        )
    )
    assert results.oracles == {"pg-oracle", "fitted"}
    best = {
        "kld_naflow": set(),
        "akld": set(),
        "band_rms_log_error": set(),
        "channel_correlation_gap": set(),
        "kld_srgb": {"den"},
        "kld": {"awgn"},
        "fid": {"den"},
        "kid": {"awgn"},
    }
    assert best_per_metric(results, "s") == best


def test_a_method_named_oracle_but_flagged_blind_is_ranked() -> None:
    results = parse_results(
        {
            "methods": {"pg-oracle": {"oracle": False}, "den": {"oracle": False}},
            "sets": {"s": {"methods": {"pg-oracle": {"kld": 0.01}, "den": {"kld": 0.1}}}},
        }
    )
    assert best_per_metric(results, "s")["kld"] == {"pg-oracle"}


def test_best_per_camera_compares_only_the_methods_with_that_camera() -> None:
    def camera(kld: float, kld_srgb: float) -> dict[str, Any]:
        return {"pairs": 2, "kld": kld, "kld_srgb": kld_srgb}

    results = parse_results(
        results_with(
            {
                "s": {
                    "den": {"kld": 0.1, "per_camera": {"A": camera(0.2, 0.9), "B": camera(0.5, 0.5)}},
                    "awgn": {"kld": 0.2, "per_camera": {"A": camera(0.1, 0.8)}},
                    "pg-oracle": {"kld": 0.0, "per_camera": {"A": camera(0.0, 0.0), "B": camera(0.0, 0.0)}},
                }
            }
        )
    )
    assert best_per_camera(results, "s", "kld") == {"A": {"awgn"}, "B": {"den"}}
    assert best_per_camera(results, "s", "kld_srgb") == {"A": {"awgn"}, "B": {"den"}}
    with pytest.raises(ValueError, match="fid"):
        best_per_camera(results, "s", "fid")


def test_best_downstream_method_is_the_highest_and_never_the_noisy_input_or_an_oracle() -> None:
    document = results_with({"s": {"den": {"kld": 0.1}, "awgn": {"kld": 0.2}, "pg-oracle": {"kld": 0.0}}})
    document["downstream"] = {
        "settings": {"steps": 3},
        "s": {
            "noisy input": {"psnr": 45.0, "ssim": 0.999, "pairs": 4},
            "den": {"psnr": 30.0, "ssim": 0.8, "pairs": 4},
            "awgn": {"psnr": 31.0, "ssim": 0.7, "pairs": 4},
            "pg-oracle": {"psnr": 40.0, "ssim": 0.99, "pairs": 4},
        },
    }
    results = parse_results(document)
    assert best_per_downstream_metric(results, "s") == {"psnr": {"awgn"}, "ssim": {"den"}, "pairs": frozenset()}
    results = parse_results({**document, "downstream": None})
    with pytest.raises(ValueError, match="no downstream"):
        best_per_downstream_metric(results, "s")


def test_headline_holds_only_where_den_is_below_awgn_and_pg() -> None:
    results = parse_results(
        results_with(
            {
                "den-best": {"den": {"kld": 0.1}, "awgn": {"kld": 0.3}, "pg": {"kld": 0.2}},
                "pg-best": {"den": {"kld": 0.25}, "awgn": {"kld": 0.3}, "pg": {"kld": 0.2}},
                "tied": {"den": {"kld": 0.2}, "awgn": {"kld": 0.3}, "pg": {"kld": 0.2}},
                "no-pg": {"den": {"kld": 0.1}, "awgn": {"kld": 0.3}},
                "den-nan": {"den": {"kld": math.nan}, "awgn": {"kld": 0.3}, "pg": {"kld": 0.2}},
            }
        )
    )
    assert headlines(results) == [
        Headline("den-best", True, 0.1, 0.3, 0.2),
        Headline("pg-best", False, 0.25, 0.3, 0.2),
        Headline("tied", False, 0.2, 0.3, 0.2),  # "lower than", not "as low as"
    ]
    assert headline_lines(results) == [
        "den-best: yes (den 0.100, awgn 0.300, pg 0.200)",
        "pg-best: NO, the headline does not hold here (den 0.250, awgn 0.300, pg 0.200)",
        "tied: NO, the headline does not hold here (den 0.200, awgn 0.300, pg 0.200)",
    ]


def test_beyond_paper_checks_compare_den_with_the_best_blind_method_the_oracle_and_den_paper() -> None:
    results = parse_results(
        results_with(
            {
                "good": {
                    "den": {"kld": 0.1, "fid": 10.0, "kid": 0.01},
                    "awgn-blind": {"kld": 0.4},
                    "starlight": {"kld": 0.2},
                    "pg-oracle": {"kld": 0.05},  # 2x = 0.1: den at exactly twice still passes
                    "den-paper": {"kld": 0.01, "fid": 12.0, "kid": 0.005},  # not a blind method
                },
                "bad": {
                    "den": {"kld": 0.3, "fid": None, "kid": 0.02},
                    "pg": {"kld": 0.25},
                    "pg-oracle": {"kld": 0.1},
                    "den-paper": {"fid": 5.0, "kid": 0.01},
                },
                "no-den": {"awgn": {"kld": 0.1}},
            }
        )
    )
    assert beyond_paper_checks(results) == [
        BeyondPaperCheck("good", "blind", "kld", True, 0.1, "starlight", 0.2),
        BeyondPaperCheck("good", "oracle", "kld", True, 0.1, "pg-oracle", 0.1),
        BeyondPaperCheck("good", "paper", "fid", True, 10.0, "den-paper", 12.0),
        BeyondPaperCheck("good", "paper", "kid", False, 0.01, "den-paper", 0.005),
        BeyondPaperCheck("bad", "blind", "kld", False, 0.3, "pg", 0.25),
        BeyondPaperCheck("bad", "oracle", "kld", False, 0.3, "pg-oracle", 0.2),
        BeyondPaperCheck("bad", "paper", "kid", False, 0.02, "den-paper", 0.01),  # no FID for den: no FID check
    ]
    assert beyond_paper_lines(results)[:2] == [
        "good: kld below every blind method: yes (den 0.100, best blind starlight 0.200)",
        "good: kld at most 2x pg-oracle: yes (den 0.100, 2x pg-oracle 0.100)",
    ]
    assert beyond_paper_lines(results)[-1] == "bad: kid below den-paper: NO (den 0.020, den-paper 0.010)"


def test_verdict_lines_accept_the_raw_document_too() -> None:
    document = results_with({"s": {"den": {"kld": 0.5}, "awgn": {"kld": 0.3}, "pg": {"kld": 0.2}}})
    assert headline_lines(document) == ["s: NO, the headline does not hold here (den 0.500, awgn 0.300, pg 0.200)"]
    assert beyond_paper_lines(document) == ["s: kld below every blind method: NO (den 0.500, best blind pg 0.200)"]
