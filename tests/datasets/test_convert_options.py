"""ConvertOptions: the one list of conversion options, its fingerprint (what a resumed run must share) and checks."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import darksynth.console_progress
from darksynth.datasets import SCHEDULING_OPTIONS, ConvertOptions, Shard, fixed_darkening
from darksynth.datasets.ray_convert import convert_dataset_with_ray
from darksynth.errors import DarksynthError
from darksynth.io.video_encoding import VideoEncoding
from darksynth.profile import load_profile, profile_to_dict
from darksynth.recipe import ClipRecipe
from tests.command_line import run_cli


@pytest.fixture
def options(tmp_path: Path, ranged_profile: Path) -> ConvertOptions:
    return ConvertOptions(tmp_path / "ds", tmp_path / "out", ClipRecipe(load_profile(ranged_profile)), "coco", seed=3)


def test_fingerprint_is_the_state_earlier_runs_recorded(options: ConvertOptions) -> None:
    """Outputs written before the options became one object must still resume: the same keys, the same values.

    The keys added since are pix_fmt (the default pixel format of H.264 went from 4:4:4 to 4:2:0 with it, so a
    conversion begun before must not resume: its videos and the new ones would differ), and blur, flicker,
    match_colour and camera, which an earlier state without them reads at their defaults, as before them, and
    darkening, which the recipe holds for ``apply`` (always "profile" for a conversion, as before it)."""
    assert options.fingerprint() == {
        "dataset": str(options.dataset),
        "format": "coco",
        "profile": profile_to_dict(options.recipe.profile),
        "darkening": "profile",
        "seed": 3,
        "jitter": False,
        "images_root": None,
        "codec": None,
        "crf": None,
        "pix_fmt": None,
        "device": "cpu",
        "blur": True,
        "flicker": True,
        "match_colour": False,
        "camera": None,
    }


def test_only_scheduling_options_leave_the_fingerprint_unchanged(options: ConvertOptions) -> None:
    names = {option.name for option in dataclasses.fields(ConvertOptions)} - {"encoding", "recipe"}
    # The encoding's and the recipe's choices are recorded one by one.
    recipe = {option.name for option in dataclasses.fields(ClipRecipe)}
    assert set(options.fingerprint()) == names - SCHEDULING_OPTIONS | {"codec", "crf", "pix_fmt"} | recipe
    scheduled = dataclasses.replace(options, output=Path("elsewhere"), workers=4, shard=Shard(1, 2), overwrite=True)
    assert scheduled.fingerprint() == options.fingerprint()
    for change in (
        {"seed": 4},
        {"recipe": dataclasses.replace(options.recipe, jitter=True)},
        {"encoding": VideoEncoding(codec="ffv1")},
        {"encoding": VideoEncoding(crf=3)},
        {"encoding": VideoEncoding(pix_fmt="yuv444p")},
        {"images_root": Path("x")},
        {"recipe": dataclasses.replace(options.recipe, camera="prior")},
    ):
        assert dataclasses.replace(options, **change).fingerprint() != options.fingerprint(), change


def test_checked_options_have_absolute_paths(
    tmp_path: Path, options: ConvertOptions, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    relative = dataclasses.replace(options, dataset=Path("ds"), output=Path("out"))
    checked = relative.checked()
    assert checked.dataset == tmp_path.resolve() / "ds" and checked.output == tmp_path.resolve() / "out"
    assert dataclasses.replace(checked, dataset=Path("ds"), output=Path("out")) == relative


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"format": "voc"}, "unknown dataset format 'voc'; use one of coco, yolo, folder, video-folder"),
        ({"workers": 0}, "--workers must be at least 1, got 0"),
    ],
)
def test_bad_options_are_refused_by_check(options: ConvertOptions, change: dict[str, object], message: str) -> None:
    with pytest.raises(DarksynthError, match=message):
        dataclasses.replace(options, **change).checked()


def test_an_unknown_camera_is_refused_by_the_recipe(options: ConvertOptions) -> None:
    with pytest.raises(DarksynthError, match="unknown camera 'nikon'; choose one of prior, phone, dslr, dslr-jpeg"):
        dataclasses.replace(options.recipe, camera="nikon")


def test_apply_options_fix_the_parameters_unless_jitter(options: ConvertOptions) -> None:
    fixed = options.apply_options()
    assert fixed.recipe is options.recipe and not fixed.recipe.jitter
    drawn_from, darkening = fixed.recipe.drawn_from()
    assert drawn_from.ranges == {} and darkening == fixed_darkening(options.recipe.profile)
    jittered = dataclasses.replace(options, recipe=dataclasses.replace(options.recipe, jitter=True)).apply_options()
    assert jittered.recipe.drawn_from() == (options.recipe.profile, "profile")
    assert (fixed.seed, fixed.workers, fixed.encoding, fixed.device) == (3, 1, VideoEncoding(), "cpu")
    encoded = dataclasses.replace(options, encoding=VideoEncoding(codec="ffv1", crf=None)).apply_options()
    assert encoded.encoding == VideoEncoding(codec="ffv1")


@pytest.mark.parametrize(
    ("change", "named"),
    [({"workers": 2}, "--workers"), ({"shard": Shard(1, 2)}, "--shard"), ({"device": "cuda"}, "--device")],
)
def test_ray_refuses_the_options_it_decides_itself(
    options: ConvertOptions, change: dict[str, object], named: str
) -> None:
    """Refused before Ray is imported or started: one line naming the option given."""
    with pytest.raises(DarksynthError) as raised:
        convert_dataset_with_ray(dataclasses.replace(options, **change))
    message = str(raised.value)
    assert message.startswith("--ray schedules the work itself") and f"(got {named})" in message
    assert "\n" not in message


def test_convert_reports_progress_in_a_log_and_nothing_with_quiet(
    monkeypatch: pytest.MonkeyPatch, folder_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    monkeypatch.setattr(darksynth.console_progress, "LOG_INTERVAL", 0.0)
    code, _, err = run_cli("convert", folder_dataset, tmp_path / "a", "-p", profile_path, "-f", "folder")
    assert code == 0, err
    progress = [line for line in err.splitlines() if line.startswith("convert: ")]
    assert progress and progress[-1].startswith("convert: 4/4 files (100%)"), err
    code, out, err = run_cli("convert", folder_dataset, tmp_path / "b", "-p", profile_path, "-f", "folder", "-q")
    assert (code, out, err) == (0, "", "")
