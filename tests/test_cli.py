"""The command line (darksynth.cli): each command builds its job's options once, with the library's defaults (no
flag, the options' default); the installed entry point exits with a real status and one error line."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

import darksynth.datasets
import darksynth.evaluation.run.job
import darksynth.training.corpus
import darksynth.training.loop
import darksynth.training.weights
from darksynth.apply import ApplyOptions, ApplyReport
from darksynth.cli import app, synthesis
from darksynth.datasets import ConversionReport, ConvertOptions, Shard
from darksynth.errors import DarksynthError
from darksynth.estimation.assemble import EstimateOptions
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.evaluation.run.job import EvaluationRun
from darksynth.evaluation.run.options import EvaluationOptions
from darksynth.io.video_encoding import VideoEncoding
from darksynth.models.den import DENConfig
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import ClipRecipe
from darksynth.training.loop import TrainConfig
from darksynth.training.weights import DENChoice, default_weights_path
from tests.command_line import assert_one_line_error, run_cli


def _flag_defaults(command: str) -> dict[str, Any]:
    group = typer.main.get_command(app)
    assert isinstance(group, typer.core.TyperGroup)
    return {param.name: param.default for param in group.commands[command].params if param.name}


@pytest.mark.parametrize(
    ("command", "expected"),
    [
        (
            "train",
            {
                "variant": DENConfig().variant,
                "model": DENConfig().noise_model,
                "width": DENConfig().width,
                "depth": DENConfig().depth,
                "steps": TrainConfig().steps,
                "batch": TrainConfig().batch,
                "frames": TrainConfig().frames,
                "crop": TrainConfig().crop,
                "learning_rate": TrainConfig().learning_rate,
                "lambda_parameters": TrainConfig().lambda_parameters,
                "lambda_reconstruction": TrainConfig().lambda_reconstruction,
                "validate_every": TrainConfig().validate_every,
                "bright_fraction": TrainConfig().bright_fraction,
                "lambda_level": TrainConfig().lambda_level,
                "seed": TrainConfig().seed,
                "device": TrainConfig().device,
            },
        ),
        (
            "estimate",
            {
                "variant": DENChoice().variant,
                "model": DENChoice().noise_model,
                "clip": EstimateOptions().clip,
                "device": NoiseEstimateOptions().device,
            },
        ),
        (
            "evaluate",
            {
                "seed": EvaluationOptions().seed,
                "device": EvaluationOptions().device,
                "inception": EvaluationOptions().inception,
                "downstream_steps": EvaluationOptions().downstream_steps,
            },
        ),
    ],
)
def test_flag_defaults_are_the_library_defaults(command: str, expected: dict[str, Any]) -> None:
    defaults = _flag_defaults(command)
    assert {name: defaults[name] for name in expected} == expected


def test_train_help_shows_the_training_defaults() -> None:
    result = CliRunner().invoke(app, ["train", "--help"], env={"COLUMNS": "200", "TERMINAL_WIDTH": "200"})
    assert result.exit_code == 0
    # One entry per option: click wraps an option's help onto indented continuation lines.
    entries = " ".join(result.stdout.split()).split(" --")
    for flag, default in (
        ("--steps", TrainConfig().steps),
        ("--validate-every", TrainConfig().validate_every),
        ("--width", DENConfig().width),
    ):
        (entry,) = [e for e in entries if e.startswith(flag[2:] + " ")]
        assert f"[default: {default}]" in entry or f"[default: {default};" in entry, entry


RECIPE_CHOICES_WITH_OPTIONS = ("jitter", "blur", "flicker", "match_colour", "camera")
"""The recipe's choices that are one option each (the profile is --profile, the darkening --alpha, --gamma and
--no-darken)."""


@pytest.mark.parametrize(("command", "names"), [("apply", None), ("convert", None), ("preview", ("jitter",))])
def test_every_recipe_choice_is_an_option_with_the_recipe_s_default(
    command: str, names: tuple[str, ...] | None
) -> None:
    # The recipe is the one declaration of a clip's choices: a command's option takes its field's default, and a
    # field added to it without its option fails here (preview shows the profile as measured: no --jitter).
    fields = {f.name: f.default for f in dataclasses.fields(ClipRecipe)}
    assert set(RECIPE_CHOICES_WITH_OPTIONS) == set(fields) - {"profile", "darkening"}
    group = typer.main.get_command(app)
    assert isinstance(group, typer.core.TyperGroup)
    parameters = {p.name: p for p in group.commands[command].params}
    for name in RECIPE_CHOICES_WITH_OPTIONS:
        if names is not None and name in names:
            assert name not in parameters, (command, name)
            continue
        assert parameters[name].default == fields[name], (command, name, parameters[name].default)


def test_apply_without_flags_builds_the_default_options(
    monkeypatch: pytest.MonkeyPatch, rgb_image: Path, profile_file: Path, tmp_path: Path
) -> None:
    built: list[ApplyOptions] = []

    def run(input_path: Path, output_path: Path, options: ApplyOptions, *, quiet: bool) -> ApplyReport:
        assert not quiet
        built.append(options)
        return ApplyReport()

    monkeypatch.setattr(synthesis, "run_with_progress", run)
    code, _, err = run_cli("apply", rgb_image, tmp_path / "out.png", "-p", profile_file)
    assert code == 0, err
    (options,) = built
    # Without --seed a random seed is drawn (and recorded): the one field without a default.
    assert options == ApplyOptions(
        recipe=ClipRecipe(load_profile(profile_file)), seed=options.seed, profile_source=str(profile_file)
    )


def test_apply_with_a_camera_alone_takes_the_default_profile(
    monkeypatch: pytest.MonkeyPatch, rgb_image: Path, tmp_path: Path
) -> None:
    built: list[ApplyOptions] = []

    def run(input_path: Path, output_path: Path, options: ApplyOptions, *, quiet: bool) -> ApplyReport:
        built.append(options)
        return ApplyReport()

    monkeypatch.setattr(synthesis, "run_with_progress", run)
    code, _, err = run_cli("apply", rgb_image, tmp_path / "out.png", "--camera", "dslr", "--seed", "2")
    assert code == 0, err
    default = default_profile_path()
    assert built == [
        ApplyOptions(recipe=ClipRecipe(load_profile(default), camera="dslr"), seed=2, profile_source=str(default))
    ]


@pytest.mark.parametrize("command", ["apply", "preview"])
def test_neither_a_profile_nor_a_camera_is_one_line(command: str, rgb_image: Path, tmp_path: Path) -> None:
    arguments = (rgb_image, tmp_path / "out.png") if command == "apply" else (rgb_image,)
    code, _, err = run_cli(command, *arguments)
    assert_one_line_error(code, err, "give --profile", "or --camera NAME")


@pytest.mark.parametrize("command", ["apply", "convert", "preview"])
def test_an_unknown_camera_is_one_line_naming_the_choices(command: str, rgb_image: Path, tmp_path: Path) -> None:
    arguments = {
        "apply": (rgb_image, tmp_path / "out.png"),
        "convert": (tmp_path / "ds", tmp_path / "out", "-f", "folder"),
        "preview": (rgb_image,),
    }[command]
    code, _, err = run_cli(command, *arguments, "--camera", "nikon")
    assert_one_line_error(code, err, "--camera must be one of prior, phone, dslr, dslr-jpeg, got 'nikon'")


def test_convert_without_flags_builds_the_default_options(
    monkeypatch: pytest.MonkeyPatch, profile_file: Path, tmp_path: Path
) -> None:
    built: list[ConvertOptions] = []

    def convert(options: ConvertOptions, **callbacks: Any) -> ConversionReport:
        built.append(options)
        return ConversionReport()

    monkeypatch.setattr(darksynth.datasets, "convert_dataset", convert)
    dataset, output = tmp_path / "ds", tmp_path / "out"
    code, _, err = run_cli("convert", dataset, output, "-p", profile_file, "-f", "folder")
    assert code == 0, err
    assert built == [ConvertOptions(dataset, output, ClipRecipe(load_profile(profile_file)), "folder")]


def test_convert_flags_reach_the_options(monkeypatch: pytest.MonkeyPatch, profile_file: Path, tmp_path: Path) -> None:
    built: list[ConvertOptions] = []

    def convert(options: ConvertOptions, **callbacks: Any) -> ConversionReport:
        built.append(options)
        return ConversionReport()

    monkeypatch.setattr(darksynth.datasets, "convert_dataset", convert)
    code, _, err = run_cli(
        "convert", tmp_path / "ds", tmp_path / "out", "-p", profile_file, "-f", "coco", "--seed", "4", "--jitter",
        "--workers", "2", "--shard", "2/3", "--images-root", "pictures", "--overwrite", "--codec", "ffv1",
        "--crf", "0", "--device", "meta", "--camera", "phone",
    )  # fmt: skip
    assert code == 0, err
    expected = ConvertOptions(
        tmp_path / "ds",
        tmp_path / "out",
        ClipRecipe(load_profile(profile_file), jitter=True, camera="phone"),
        "coco",
        seed=4,
        workers=2,
        shard=Shard(2, 3),
        images_root=Path("pictures"),
        overwrite=True,
        encoding=VideoEncoding(codec="ffv1", crf=0),
        device="meta",
    )
    assert built == [expected]


class _TinyCorpus(SimpleNamespace):
    def __len__(self) -> int:
        return 1


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        ([], TrainConfig()),
        (["--model", "paper"], TrainConfig(den=DENConfig(noise_model="paper", log_levels=False))),
        (
            ["--variant", "v2", "--width", "8", "--steps", "7", "--lr", "1e-3"],
            TrainConfig(den=DENConfig(variant="v2", width=8), steps=7, learning_rate=1e-3),
        ),
    ],
)
def test_train_builds_the_training_config_from_its_flags(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, flags: list[str], expected: TrainConfig
) -> None:
    built: list[TrainConfig] = []

    def train(corpus: object, held: object, config: TrainConfig, out: Path, **_: object) -> dict[str, object]:
        built.append(config)
        return {"steps": 0}

    monkeypatch.setattr(darksynth.training.loop, "train", train)
    monkeypatch.setattr(darksynth.training.corpus, "load_corpus", lambda *_, **__: _TinyCorpus(images=[], clips=[]))
    code, _, err = run_cli("train", tmp_path, "--out", tmp_path / "den.safetensors", *flags)
    assert code == 0, err
    assert built == [expected]


def test_estimate_without_flags_loads_the_default_shipped_den(monkeypatch: pytest.MonkeyPatch, rgb_image: Path) -> None:
    loaded: list[Path] = []

    def load_weights(path: Path, **_: object) -> None:
        loaded.append(path)
        raise DarksynthError("stopped after choosing the weights")

    monkeypatch.setattr(darksynth.training.weights, "load_weights", load_weights)
    code, _, err = run_cli("estimate", rgb_image)
    assert code == 1 and "stopped after choosing the weights" in err
    assert loaded == [DENChoice().path()] == [default_weights_path("v3", "srgb")]


def test_evaluate_without_flags_builds_the_default_options(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    built: list[EvaluationOptions] = []

    def run(pairs: list[Path], out: Path, options: EvaluationOptions, **_: object) -> EvaluationRun:
        built.append(options)
        return EvaluationRun({"problems": [], "sets": {}}, (out / "a", out / "b", out / "c"))

    monkeypatch.setattr(darksynth.evaluation.run.job, "run_evaluation", run)
    code, _, err = run_cli("evaluate", "--pairs", tmp_path / "pairs", "--out", tmp_path / "out")
    assert code == 0, err
    (options,) = built
    assert dataclasses.replace(options, command="") == EvaluationOptions()
    assert f"--methods {','.join(EvaluationOptions().methods)} --seed 0 --device cpu --out" in options.command


def test_bad_downstream_steps_is_one_error_line(tmp_path: Path) -> None:
    code, _, err = run_cli("evaluate", "--pairs", tmp_path, "--out", tmp_path / "out", "--downstream-steps", "0")
    assert code == 1
    assert err.strip() == "darksynth: error: --downstream-steps must be at least 1, got 0"


def test_console_script_exit_code_and_single_line(tmp_path: Path, profile_file: Path) -> None:
    """The installed entry point, not only the in-process runner: real exit status and stderr."""
    missing = tmp_path / "missing.png"
    completed = subprocess.run(
        [sys.executable, "-m", "darksynth", "apply", str(missing), str(tmp_path / "o.png"), "-p", str(profile_file)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert completed.returncode == 1
    assert completed.stderr.strip().splitlines() == [f"darksynth: error: {missing}: no such file or folder"]


@pytest.mark.parametrize(
    ("arguments", "status", "said"),
    [
        (["apply", "in.png", "out.png", "-p", "p.json", "--workers", "0"], 1, "apply: Invalid value for '--workers'"),
        (["convert", "d", "o", "-p", "p.json", "-f", "coco", "--crf", "99"], 1, "convert: Invalid value for '--crf'"),
        (["apply", "in.png", "out.png", "-p", "p.json", "--wrkers", "2"], 2, "apply: No such option: --wrkers"),
        (["apply", "in.png"], 2, "apply: Missing argument 'OUTPUT'"),
        (["aply"], 2, "No such command 'aply'"),
    ],
)
def test_command_line_mistakes_are_one_line_errors(arguments: list[str], status: int, said: str) -> None:
    """A bad value exits 1 like every other bad value; a malformed command line exits 2; both in one line."""
    code, out, err = run_cli(*arguments)
    assert code == status
    assert out == ""
    (line,) = err.splitlines()
    assert line.startswith("darksynth: error: ") and said in line, line


def test_help_is_plain_text_that_keeps_brackets_and_shows_no_bool_values() -> None:
    result = CliRunner().invoke(app, ["convert", "--help"], env={"COLUMNS": "200", "TERMINAL_WIDTH": "200"})
    assert result.exit_code == 0
    assert "darksynth[ray]" in result.stdout
    assert "<bool>" not in result.stdout and "╭" not in result.stdout
    (jitter,) = [line for line in result.stdout.splitlines() if "--jitter" in line]
    assert jitter.split()[0] == "--jitter", jitter
