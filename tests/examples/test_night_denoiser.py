"""The example of the user's workflow (examples/night_denoiser.py) runs end to end with a few steps."""

import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tests.examples.drawn_images import smooth_scene, write_png
from tests.script_modules import load_script

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "night_denoiser.py"


def _example() -> ModuleType:
    return load_script(EXAMPLE)


@pytest.fixture()
def folders(tmp_path: Path) -> tuple[Path, Path]:
    """A pair set of one camera "_CAM_" (3 pairs, 160 px, Gaussian noise of 8 levels) and 2 clean images."""
    generator = np.random.default_rng(0)
    pairs = tmp_path / "pairs"
    for index in range(3):
        clean = smooth_scene(generator, 160)
        noisy = clean + generator.normal(0, 8 / 255, clean.shape)
        write_png(pairs / "clean" / f"scene{index}_CAM_.png", clean)
        write_png(pairs / "noisy" / f"scene{index}_CAM_.png", noisy)
    for index in range(2):
        write_png(tmp_path / "clean" / f"image{index}.png", smooth_scene(generator, 96))
    return pairs, tmp_path / "clean"


def test_the_example_trains_each_method_and_writes_its_comparison(folders: tuple[Path, Path], tmp_path: Path) -> None:
    pairs, clean = folders
    out = tmp_path / "out"
    arguments = ["--pairs", str(pairs), "--camera", "_CAM_", "--references", "1", "--pick", "first"]
    arguments += [
        "--clean",
        str(clean),
        "--steps",
        "3",
        "--batch",
        "2",
        "--crop",
        "32",
        "--workers",
        "0",
        "--out",
        str(out),
    ]
    arguments += ["--methods", "darksynth,gaussian,albu-gauss,albu-iso,albu-gauss-jpeg"]
    assert _example().main(arguments) == 0
    record = json.loads((out / "results.json").read_text())
    assert record["test_pairs"] == ["scene1_CAM_.png", "scene2_CAM_.png"]
    expected = {"noisy input", "darksynth", "gaussian", "albu-gauss", "albu-iso", "albu-gauss-jpeg"}
    assert set(record["results"]) == expected
    for scores in record["results"].values():
        assert 5.0 < scores["psnr"] < 60.0 and 0.0 < scores["ssim"] <= 1.0, scores
    # The noisy input's PSNR is that of 8 levels of Gaussian noise (about 30 dB), whatever was trained.
    assert abs(record["results"]["noisy input"]["psnr"] - 20 * np.log10(255 / 8)) < 1.0
    assert (out / "profiles" / "scene0_CAM_.json").is_file()
    assert (out / "comparison.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_references_spread_over_the_camera_s_pairs_and_the_rest_are_the_test(folders: tuple[Path, Path]) -> None:
    pairs, _ = folders
    references, test_pairs = _example().camera_pairs(pairs, "_CAM_", 1, "spread")
    assert [path.name for path in references] == ["scene1_CAM_.png"]
    assert [pair.name for pair in test_pairs] == ["scene0_CAM_.png", "scene2_CAM_.png"]
    references, test_pairs = _example().camera_pairs(pairs, "_CAM_", 2, "first")
    assert [path.name for path in references] == ["scene0_CAM_.png", "scene1_CAM_.png"]
    assert [pair.name for pair in test_pairs] == ["scene2_CAM_.png"]


def test_the_same_seed_gives_the_same_training_crops(folders: tuple[Path, Path]) -> None:
    example = _example()
    _, clean = folders
    images = example.read_clean_images([clean], 32)
    first = example.NoisyCrops(images, example.gaussian_noise, 32, 4, seed=5)
    again = example.NoisyCrops(images, example.gaussian_noise, 32, 4, seed=5)
    other = example.NoisyCrops(images, example.gaussian_noise, 32, 4, seed=6)
    for index in range(4):
        assert all(a.equal(b) for a, b in zip(first[index], again[index], strict=True))
    assert not first[0][0].equal(other[0][0])


def test_a_camera_with_too_few_pairs_is_one_line_and_exit_2(
    folders: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pairs, clean = folders
    arguments = ["--pairs", str(pairs), "--camera", "_CAM_", "--references", "3", "--clean", str(clean)]
    assert _example().main([*arguments, "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and error[0].startswith(f"error: {pairs}: 3 pairs name '_CAM_'"), error
    missing = ["--pairs", str(tmp_path / "none"), "--clean", str(clean), "--out", str(tmp_path / "out2")]
    assert _example().main(missing) == 2
    assert str(tmp_path / "none") in capsys.readouterr().err
