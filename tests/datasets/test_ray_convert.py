"""The Ray Data path on a local Ray instance: the same output tree, byte for byte, as a local conversion."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from darksynth.datasets import ConvertOptions, convert_dataset
from darksynth.datasets.ray_convert import convert_dataset_with_ray
from darksynth.profile import load_profile
from darksynth.recipe import ClipRecipe
from tests.command_line import run_cli
from tests.datasets.conftest import tree_bytes, write_image

ray = pytest.importorskip("ray", reason="the Ray path is an optional extra: pip install 'darksynth[ray]'")


@pytest.fixture(scope="module")
def local_ray() -> Iterator[None]:
    """A local two-CPU Ray instance for this module (started once: it takes several seconds)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


@pytest.mark.slow
def test_ray_conversion_equals_a_local_one_and_resumes(
    local_ray: None, coco_dataset: Path, ranged_profile: Path, tmp_path: Path
) -> None:
    local, distributed = tmp_path / "local", tmp_path / "ray"
    expected = convert_dataset(
        ConvertOptions(coco_dataset, local, ClipRecipe(load_profile(ranged_profile), jitter=True), "coco", seed=3)
    )
    report = convert_dataset_with_ray(
        ConvertOptions(coco_dataset, distributed, ClipRecipe(load_profile(ranged_profile), jitter=True), "coco", seed=3)
    )
    assert report.converted == expected.converted > 0
    assert report.failures == expected.failures
    assert report.manifest is not None
    assert tree_bytes(distributed) == tree_bytes(local)

    # A lost output is converted again on the next run, and only it.
    victim = next(p for p in sorted(distributed.rglob("*.jpg")) if ".darksynth" not in p.parts)
    victim.unlink()
    again = convert_dataset_with_ray(
        ConvertOptions(coco_dataset, distributed, ClipRecipe(load_profile(ranged_profile), jitter=True), "coco", seed=3)
    )
    assert (again.converted, again.already_done) == (1, expected.converted - 1)
    assert tree_bytes(distributed) == tree_bytes(local)


@pytest.mark.slow
def test_ray_conversion_reports_a_broken_file_and_converts_the_rest(
    local_ray: None, profile_path: Path, tmp_path: Path
) -> None:
    dataset = tmp_path / "folder"
    for index in range(3):
        write_image(dataset / "cats" / f"{index}.png", index)
    (dataset / "cats" / "broken.png").write_bytes(b"not a png")
    report = convert_dataset_with_ray(
        ConvertOptions(dataset, tmp_path / "out", ClipRecipe(load_profile(profile_path)), "folder")
    )
    assert report.converted == 3
    assert len(report.failures) == 1 and "broken.png" in report.failures[0]
    assert not (tmp_path / "out" / "cats" / "broken.png").exists()


@pytest.mark.slow
def test_cli_ray_flag_converts_and_refuses_local_scheduling_options(
    local_ray: None, folder_dataset: Path, profile_path: Path, tmp_path: Path
) -> None:
    code, out, err = run_cli("convert", folder_dataset, tmp_path / "out", "-p", profile_path, "-f", "folder", "--ray")
    assert code == 0, err
    assert "4 new" in out + err
    assert (tmp_path / "out" / "darksynth-manifest.json").is_file()
    code, _, err = run_cli(
        "convert", folder_dataset, tmp_path / "out2", "-p", profile_path, "-f", "folder", "--ray", "--workers", "2"
    )
    assert code == 1
    assert err.strip().count("\n") == 0 and "--ray" in err
