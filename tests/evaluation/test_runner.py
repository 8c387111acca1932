"""darksynth.evaluation.run.runner: evaluate_pairs on small sets made on the spot, without the CLI."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.evaluation.methods.method import NoiseMethod
from darksynth.evaluation.run import runner
from darksynth.evaluation.run.options import EvaluationOptions
from darksynth.evaluation.run.runner import evaluate_pairs
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


def _scaled_real_noise(name: str, gain: float) -> NoiseMethod:
    """An oracle that replays the pair's own real noise times ``gain``, on 8-bit levels."""

    def synthesize(clean: torch.Tensor, noise: object, generator: torch.Generator) -> torch.Tensor:
        assert isinstance(noise, torch.Tensor)
        return ((clean + gain * noise) * 255.0).round().clamp(0, 255) / 255.0

    return NoiseMethod(name, f"real noise x{gain}", lambda noisy, clean: noisy - clean, synthesize, oracle=True)


def test_channel_statistics_of_copied_and_doubled_real_noise(
    make_pair_set: MakeSet, monkeypatch: pytest.MonkeyPatch
) -> None:
    methods = {"copy": _scaled_real_noise("copy", 1.0), "double": _scaled_real_noise("double", 2.0)}
    monkeypatch.setattr(runner, "build_methods", lambda names, **kwargs: (methods, []))
    root = make_pair_set("independent", count=4, sigma=8.0, size=96)
    outcome = runner.evaluate_pairs([root], EvaluationOptions(methods=list(methods), inception=False))
    report = outcome.results["sets"]["independent"]
    real = report["real"]
    # The set's noise is white Gaussian of 8 levels, drawn independently per channel.
    for channel in "rgb":
        assert real["noise_std"][channel] * 255.0 == pytest.approx(8.0, rel=0.05)
    assert set(real["channel_correlation"]) == {"rg", "gb", "rb"}
    assert all(abs(value) < 0.05 for value in real["channel_correlation"].values())
    copy, double = report["methods"]["copy"], report["methods"]["double"]
    assert copy["level_ratio"] == {"r": 1.0, "g": 1.0, "b": 1.0}
    assert copy["channel_correlation"] == real["channel_correlation"]
    assert copy["kld_naflow"] == 0.0 and copy["akld"] == 0.0 and copy["kld_naflow_ci95"] == [0.0, 0.0]
    for channel in "rgb":
        assert double["level_ratio"][channel] == pytest.approx(2.0, rel=0.02)
    assert double["channel_correlation"] == pytest.approx(real["channel_correlation"], abs=0.01)
    # Twice the std: KL(N(0, s^2) || N(0, 4 s^2)) = log 2 + 1/8 - 1/2 = 0.32, give or take the window's scatter.
    assert double["akld"] == pytest.approx(0.32, abs=0.03)
    assert double["kld_naflow"] > 0.2
    assert set(double["per_camera"]["camA"]) >= {"kld_naflow", "kld_naflow_ci95", "akld", "akld_ci95"}
    assert set(outcome.results["metrics"]) >= {"kld_naflow", "akld", "noise_std", "level_ratio", "channel_correlation"}


def test_band_statistics_of_copied_and_doubled_real_noise(
    make_pair_set: MakeSet, monkeypatch: pytest.MonkeyPatch
) -> None:
    methods = {"copy": _scaled_real_noise("copy", 1.0), "double": _scaled_real_noise("double", 2.0)}
    monkeypatch.setattr(runner, "build_methods", lambda names, **kwargs: (methods, []))
    root = make_pair_set("white", count=4, sigma=8.0, size=128)
    outcome = runner.evaluate_pairs([root], EvaluationOptions(methods=list(methods), inception=False))
    report = outcome.results["sets"]["white"]
    real = report["real"]
    # White noise: as much power in every band as white noise of its variance (the coarsest band of a 128-pixel
    # image holds few frequencies, hence the wider bound there).
    for component in ("brightness", "colour"):
        assert real["band_white_ratio"][component][:4] == pytest.approx([1.0] * 4, rel=0.12)
        assert real["band_white_ratio"][component][4] == pytest.approx(1.0, rel=0.3)
        assert real["band_power"][component][0] == pytest.approx((8.0 / 255.0) ** 2, rel=0.1)
    copy, double = report["methods"]["copy"], report["methods"]["double"]
    assert copy["band_ratio"] == {"brightness": [1.0] * 5, "colour": [1.0] * 5}
    assert copy["band_rms_log_error"] == 0.0 and copy["channel_correlation_gap"] == 0.0
    # Twice the std is four times the power in every band: the RMS log error is ln 4.
    for component in ("brightness", "colour"):
        assert double["band_ratio"][component] == pytest.approx([4.0] * 5, rel=0.03)
    assert double["band_rms_log_error"] == pytest.approx(math.log(4.0), abs=0.02)
    assert double["channel_correlation_gap"] < 0.01
    assert set(outcome.results["metrics"]) >= {"band_ratio", "band_rms_log_error", "band_white_ratio"}
