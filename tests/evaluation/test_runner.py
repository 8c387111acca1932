"""darksynth.evaluation.runner: evaluate_pairs on small sets made on the spot, without the CLI."""

from __future__ import annotations

from darksynth.evaluation.options import EvaluationOptions
from darksynth.evaluation.runner import evaluate_pairs
from tests.evaluation.conftest import MakeSet


def test_results_have_the_documented_shape_and_rank_methods_sensibly(make_pair_set: MakeSet) -> None:
    root = make_pair_set("strong", count=4, sigma=14.0, size=96)
    outcome = evaluate_pairs([root], EvaluationOptions(methods=["awgn", "pg-oracle", "awgn-blind"], inception=False))
    report = outcome.results["sets"]["strong"]
    assert report["pairs"] == 4
    assert set(report["methods"]) == {"awgn", "pg-oracle", "awgn-blind"}
    for entry in report["methods"].values():
        low, high = entry["kld_ci95"]
        assert low <= entry["kld"] <= high
        assert set(entry["per_camera"]) == {"camA", "camB"}
        assert entry["per_camera"]["camA"]["pairs"] == 2
        assert entry["fid"] is None and entry["kid"] is None
    methods = report["methods"]
    # Real noise is white Gaussian of 14/255: the clean-aided fit matches it, a fixed 5/255 does not.
    assert methods["pg-oracle"]["oracle"] is True and methods["awgn"]["oracle"] is False
    assert methods["pg-oracle"]["kld"] < 0.05 < methods["awgn"]["kld"]
    assert methods["pg-oracle"]["kld_srgb"] < methods["awgn"]["kld_srgb"]
    assert outcome.results["problems"] == []
    assert [e.pair_name for e in outcome.examples] == ["pair_0.png", "pair_1.png"]
    assert set(outcome.examples[0].noisy) == {"real", "awgn", "pg-oracle", "awgn-blind"}


def test_same_seed_same_results(make_pair_set: MakeSet) -> None:
    root = make_pair_set(count=2)
    options = EvaluationOptions(methods=["awgn", "pg-blind"], inception=False, seed=3)
    first = evaluate_pairs([root], options).results["sets"]
    second = evaluate_pairs([root], options).results["sets"]
    assert first == second
