"""'darksynth evaluate' end to end on small sets made on the spot: results, report, and every bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from darksynth.errors import DarksynthError
from darksynth.evaluation.run.job import rank_by_kld, run_evaluation
from darksynth.evaluation.run.options import EvaluationOptions
from tests.command_line import run_cli
from tests.evaluation.conftest import MakeSet


def test_cli_writes_results_markdown_and_report(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set("setA", count=2)
    out = tmp_path / "out"
    code, _, stderr = run_cli("evaluate", "--pairs", root, "--methods", "awgn,pg-oracle", "--no-fid", "--out", out)
    assert code == 0, stderr
    results = json.loads((out / "results.json").read_text())
    assert set(results["sets"]["setA"]["methods"]) == {"awgn", "pg-oracle"}
    assert "darksynth evaluate --pairs" in results["command"]
    assert "--methods awgn,pg-oracle" in results["command"]
    assert "setA" in (out / "results.md").read_text()
    assert (out / "report.html").read_text().lstrip().lower().startswith("<!doctype html")
    assert "setA (2 pairs), kld: pg-oracle" in stderr


def test_bad_pairs_and_names_are_reported_and_the_rest_runs(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set("messy", count=4)
    (root / "clean" / "pair_1.png").unlink()  # missing partner
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(root / "clean" / "pair_2.png")  # mismatched size
    (root / "noisy" / "readme.txt").write_text("not an image")
    out = tmp_path / "out"
    code, _, stderr = run_cli(
        "evaluate", "--pairs", root, "--pairs", tmp_path / "absent", "--methods", "awgn,nope,den-v2",
        "--weights", f"den-v2={tmp_path / 'absent.safetensors'}",
        "--no-fid", "--out", out,
    )  # fmt: skip
    assert code == 0, stderr
    results = json.loads((out / "results.json").read_text())
    assert results["sets"]["messy"]["pairs"] == 2
    problems = "\n".join(results["problems"])
    for expected in ("pair_1.png: no clean partner", "pair_2.png: size", "readme.txt: not an image", "absent",
                     "nope: unknown method", "den-v2: no trained weights at"):  # fmt: skip
        assert expected in problems
        assert expected in stderr
    assert "Traceback" not in stderr


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--methods", "nope"], "no method can run: nope: unknown method"),
        (["--weights", "den-v2"], "expected METHOD=FILE"),
        (["--downstream-net", "huge"], "--downstream-net 'huge': one of small, dncnn"),
    ],
)
def test_fatal_inputs_give_one_error_line(
    make_pair_set: MakeSet, tmp_path: Path, arguments: list[str], message: str
) -> None:
    root = make_pair_set(count=1)
    code, _, stderr = run_cli("evaluate", "--pairs", root, "--no-fid", "--out", tmp_path / "out", *arguments)
    assert code == 1
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("darksynth: error: ") and message in lines[0]
    assert not (tmp_path / "out" / "results.json").exists()


def test_no_readable_set_is_fatal(tmp_path: Path) -> None:
    code, _, stderr = run_cli("evaluate", "--pairs", tmp_path / "absent", "--methods", "awgn", "--out", tmp_path / "o")
    assert code == 1
    assert "no set of pairs could be read" in stderr and "absent: no such folder" in stderr


def test_a_dncnn_sized_downstream_net_is_asked_by_name(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set("setN", count=1)
    code, _, stderr = run_cli(
        "evaluate", "--pairs", root, "--methods", "awgn", "--no-fid", "--out", tmp_path / "out",
        "--downstream", root / "clean", "--downstream-steps", "1", "--downstream-net", "dncnn",
    )  # fmt: skip
    assert code == 0, stderr
    settings = json.loads((tmp_path / "out" / "results.json").read_text())["downstream"]["settings"]
    assert (settings["width"], settings["depth"]) == (64, 17)


def test_downstream_check_lands_in_the_results(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set("setD", count=2)
    out = tmp_path / "out"
    code, _, stderr = run_cli(
        "evaluate", "--pairs", root, "--methods", "awgn,pg-oracle", "--no-fid", "--out", out,
        "--downstream", root / "clean", "--downstream-steps", "3",
    )  # fmt: skip
    assert code == 0, stderr
    results = json.loads((out / "results.json").read_text())
    downstream = results["downstream"]
    assert downstream["settings"]["steps"] == 3
    assert set(downstream["setD"]) >= {"awgn", "pg-oracle", "noisy input"}
    assert "--downstream-steps 3 --downstream-net small" in results["command"]
    assert (downstream["settings"]["width"], downstream["settings"]["depth"]) == (16, 5)
    # Two pairs: the real-pair ceiling, trained on one and tested on the other, is a row too (never ranked).
    assert downstream["setD"]["real pairs (other folds)"]["pairs"] == 2
    assert downstream["setD"]["awgn"]["psnr"] > 0 and 0 < downstream["setD"]["awgn"]["ssim"] <= 1
    assert "noisy input" in (out / "results.md").read_text()


def test_reports_state_the_headline_plainly(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set("loud", count=2, sigma=14.0)
    out = tmp_path / "out"
    code, _, stderr = run_cli("evaluate", "--pairs", root, "--methods", "den,awgn,pg", "--no-fid", "--out", out)
    assert code == 0, stderr
    results = json.loads((out / "results.json").read_text())
    methods = results["sets"]["loud"]["methods"]
    holds = methods["den"]["kld"] < min(methods["awgn"]["kld"], methods["pg"]["kld"])
    verdict = "loud: yes" if holds else "loud: NO, the headline does not hold here"
    assert verdict in (out / "results.md").read_text()
    assert verdict in (out / "report.html").read_text()


@pytest.mark.slow  # every method on every pair, shipped networks included (~5-9 s)
def test_reports_check_den_against_every_blind_method_the_oracle_and_the_paper_model(
    make_pair_set: MakeSet, tmp_path: Path
) -> None:
    root = make_pair_set("loud", count=2, sigma=14.0)
    out = tmp_path / "out"
    code, _, stderr = run_cli(
        "evaluate", "--pairs", root, "--methods", "den,den-paper,awgn,pg-blind,pg-oracle", "--out", out
    )
    assert code == 0, stderr
    methods = json.loads((out / "results.json").read_text())["sets"]["loud"]["methods"]
    den = methods["den"]
    best = min(("awgn", "pg-blind"), key=lambda name: methods[name]["kld"])
    below = "yes" if den["kld"] < methods[best]["kld"] else "NO"
    within = "yes" if den["kld"] <= 2 * methods["pg-oracle"]["kld"] else "NO"
    fid = "yes" if den["fid"] < methods["den-paper"]["fid"] else "NO"
    markdown, html = (out / "results.md").read_text(), (out / "report.html").read_text()
    for line in (
        f"loud: kld below every blind method: {below} (den {den['kld']:.3f}, best blind {best}",
        f"loud: kld at most 2x pg-oracle: {within}",
        f"loud: fid below den-paper: {fid}",
    ):
        assert line in markdown and line in html


def test_run_evaluation_writes_the_three_files_and_ranks_by_kld(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set("strong", count=2, sigma=14.0, size=64)
    out = tmp_path / "deep" / "out"
    options = EvaluationOptions(methods=["awgn", "pg-oracle"], inception=False, command="darksynth evaluate ...")
    run = run_evaluation([root], out, options)
    assert run.files == (out / "results.json", out / "results.md", out / "report.html")
    assert json.loads(run.files[0].read_text()) == run.results
    assert run.results["command"] == "darksynth evaluate ..." and run.results["downstream"] is None
    ranking = rank_by_kld(run.results)
    assert [name for name, _ in ranking["strong"]] == ["pg-oracle", "awgn"]
    methods = run.results["sets"]["strong"]["methods"]
    assert ranking["strong"] == [("pg-oracle", methods["pg-oracle"]["kld"]), ("awgn", methods["awgn"]["kld"])]


def test_an_output_that_cannot_be_written_is_one_error_line(make_pair_set: MakeSet, tmp_path: Path) -> None:
    root = make_pair_set(count=1)
    blocked = tmp_path / "file"
    blocked.write_text("a file where the output folder should go")
    with pytest.raises(DarksynthError, match=f"^{blocked}: "):
        run_evaluation([root], blocked, EvaluationOptions(methods=["awgn"], inception=False))
    code, _, stderr = run_cli("evaluate", "--pairs", root, "--methods", "awgn", "--no-fid", "--out", blocked)
    assert code == 1
    assert stderr.strip().splitlines() == [f"darksynth: error: {blocked}: File exists"]
