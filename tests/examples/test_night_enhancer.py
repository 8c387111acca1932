"""The enhancement example (examples/night_enhancer.py) runs end to end with a few steps, scores as stated, and
refuses bad input with one line."""

import json
import math
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
import torch

import darksynth
from tests.examples.drawn_images import smooth_scene, write_png
from tests.script_modules import load_script

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "night_enhancer.py"


def _example() -> ModuleType:
    return load_script(EXAMPLE)


@pytest.fixture()
def folders(tmp_path: Path) -> tuple[Path, Path, Path]:
    """Two low/normal-light pairs (low: a tenth of the light and 2 levels of noise), a folder of the camera's dark
    photos holding the two test images and one other, and two clean training images."""
    generator = np.random.default_rng(0)
    pairs, references = tmp_path / "pairs", tmp_path / "references"
    for index in range(3):
        high = smooth_scene(generator, 160)
        low = 0.1 * high + generator.normal(0, 2 / 255, high.shape)
        write_png(references / f"{index}.png", low)
        if index < 2:
            write_png(pairs / "high" / f"{index}.png", high)
            write_png(pairs / "low" / f"{index}.png", low)
    for index in range(2):
        write_png(tmp_path / "clean" / f"image{index}.png", smooth_scene(generator, 96))
    return pairs, references, tmp_path / "clean"


def _reference_profiles(tmp_path: Path, seed: int, exposures: dict[str, Any]) -> list[Path]:
    """Profiles (srgb) of dark photos of one smooth scene, each at its exposure (a factor, or one per channel),
    with 1-level noise, written in order from one generator of ``seed``."""
    generator = np.random.default_rng(seed)
    scene = smooth_scene(generator, 160)
    references = []
    for name, exposure in exposures.items():
        references.append(tmp_path / f"{name}.png")
        write_png(references[-1], exposure * scene + generator.normal(0, 1 / 255, scene.shape))
    return list(_example().estimate_profiles(references, tmp_path / "profiles", "srgb", "cpu"))


def _two_step_run(folders: tuple[Path, Path, Path], out: Path) -> list[str]:
    """The example's arguments for a run of two steps on 32-px crops of the test folders, written to ``out``."""
    pairs, references, clean = folders
    arguments = ["--pairs", str(pairs), "--references", str(references), "--clean", str(clean), "--steps", "2"]
    return [*arguments, "--batch", "2", "--crop", "32", "--workers", "0", "--out", str(out)]


def test_the_example_trains_each_method_on_the_other_photos_and_writes_its_comparison(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    assert _example().main([*_two_step_run(folders, out), "--seeds", "0,1"]) == 0
    record = json.loads((out / "results.json").read_text())
    # The profiles come from the one photo that is not a test image, with both noise models.
    assert [Path(path).name for path in record["references"]] == ["2.png"]
    assert (out / "profiles" / "srgb" / "2.json").is_file() and (out / "profiles" / "paper" / "2.json").is_file()
    assert set(record["results"]) == {"low input", *_example().METHODS}
    for name, scores in record["results"].items():
        assert 3.0 < scores["psnr"] < 60.0 and 0.0 < scores["ssim"] <= 1.0, (name, scores)
        assert len(scores["per_seed"]["psnr"]) == (1 if name == "low input" else 2)
        assert set(scores["per_pair"]) == {"0.png", "1.png"}
    # The pairs need a gain of about 10 (a tenth of the light).
    gains = [entry["gain"] for entry in record["results"]["low input"]["per_pair"].values()]
    assert all(8.0 < gain < 12.0 for gain in gains), gains
    assert (out / "comparison.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_real_pair_ceiling_tests_each_pair_on_an_enhancer_trained_on_the_other_fold(
    folders: tuple[Path, Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    example = _example()
    trained_on: list[list[str]] = []
    original = example.RealPairCrops.__init__

    def recording(self: object, pairs: list[object], *args: object) -> None:
        trained_on.append([pair.name for pair in pairs])  # type: ignore[attr-defined]
        original(self, pairs, *args)

    monkeypatch.setattr(example.RealPairCrops, "__init__", recording)
    out = tmp_path / "out"
    assert example.main([*_two_step_run(folders, out), "--methods", "real-pairs"]) == 0
    # Fold 1 (0.png) is tested on a net trained on fold 2 (1.png), and the other way round; no profile is needed.
    assert trained_on == [["1.png"], ["0.png"]]
    assert not (out / "profiles").exists()
    record = json.loads((out / "results.json").read_text())
    assert set(record["results"]["real-pairs"]["per_pair"]) == {"0.png", "1.png"}


def test_gt_mean_psnr_forgives_a_global_gain_and_psnr_does_not() -> None:
    example = _example()
    high = torch.rand(3, 32, 32, generator=torch.Generator().manual_seed(0)) * 0.5 + 0.25
    pair = example.TestPair("a.png", high * 0.1, high)
    scores = example.pair_scores(high * 0.8, pair)
    assert scores["gt_mean_psnr"] > 100.0 and scores["psnr"] < 25.0, scores
    assert abs(scores["gain"] - 10.0) < 1e-6


def test_the_training_exposures_are_matched_per_image_and_drawn_from_several_references(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    # Two references of different exposures: each image gets one darkening per reference drawn, and a brighter
    # reference gives a brighter darkened image.
    example = _example()
    clean = folders[2]
    images = example.read_clean_images([clean], 32)
    profiles = _reference_profiles(tmp_path, 1, {"dark": 0.05, "less_dark": 0.3})
    exposures = example.ProfileExposures(images, profiles, 2, seed=0)
    low_light = example.profile_low_light(exposures, noise=False)
    clean_image = images[0].float() / 255.0
    means = {exposures.pick(0, seed)[0]: float(low_light(0, clean_image, seed).mean()) for seed in (0, 1)}
    assert set(means) == {0, 1}, means
    assert 3.0 < means[1] / means[0] < 9.0, means


def test_the_even_gain_draw_spreads_the_training_gains_evenly_in_log_over_the_references_range(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    example = _example()
    images = example.read_clean_images([folders[2]], 32)
    profiles = _reference_profiles(tmp_path, 2, {"reference0": 0.04, "reference1": 0.1, "reference2": 0.3})
    exposures = example.ProfileExposures(images, profiles, 3, seed=0, gain_draw="even")
    low, high = exposures.log_gain_range
    assert high - low > 0.5
    clean = images[0].double() / 255.0
    gains = []
    for seed in range(200):
        _, alpha, gamma, _ = exposures.pick(0, seed)
        gains.append(math.log(float(clean.mean() / darksynth.darken(clean, alpha, gamma).mean())))
    assert low - 1e-6 <= min(gains) and max(gains) <= high + 1e-6
    # Even in log: each half of the range holds about half the draws (200 draws: a half's share has std 0.035).
    share = sum(gain < (low + high) / 2 for gain in gains) / len(gains)
    assert abs(share - 0.5) < 0.12


def test_the_pooled_draw_gives_each_image_the_darkenings_matched_on_every_image(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    example = _example()
    images = example.read_clean_images([folders[2]], 32)
    assert len(images) >= 2
    profiles = _reference_profiles(tmp_path, 2, {"reference0": 0.04, "reference1": 0.1, "reference2": 0.3})
    exposures = example.ProfileExposures(images, profiles, 3, seed=0, gain_draw="pooled")
    matched = {(index, alpha, gamma) for row in exposures.choices for index, alpha, gamma, _ in row}
    own = {(index, alpha, gamma) for index, alpha, gamma, _ in exposures.choices[0]}
    drawn = {exposures.pick(0, seed)[:3] for seed in range(200)}
    # Every draw is a darkening matched on some image; most of them on other images than this one.
    assert drawn <= matched and len(drawn - own) > 0 and len(drawn) > len(own)
    assert all(exposures.pick(0, seed)[3] is None for seed in range(10))
    # A sample's draw does not depend on the image it darkens.
    assert [exposures.pick(0, seed) for seed in range(20)] == [exposures.pick(1, seed) for seed in range(20)]


def test_a_low_image_without_its_normal_light_image_is_one_line_and_exit_2(
    folders: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pairs, references, clean = folders
    (pairs / "high" / "1.png").unlink()
    arguments = ["--pairs", str(pairs), "--references", str(references), "--clean", str(clean)]
    assert _example().main([*arguments, "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "1.png" in error and "no normal-light image" in error, error


def test_the_exposure_normalised_enhancer_sees_a_brighter_input_as_the_same_one_but_for_its_level() -> None:
    example = _example()
    model = example.Enhancer(8, seed=0, normalise_exposure=True).eval()
    low = torch.rand(1, 3, 24, 24, generator=torch.Generator().manual_seed(3)) * 0.05
    with torch.no_grad():
        # The level feature is the one input channel of decode2 beyond the features and the skip: zeroed, the
        # output of a 4x brighter input is the same; with it, the net still tells the two exposures apart.
        same_level = example.Enhancer(8, seed=0, normalise_exposure=True).eval()
        same_level.decode2[0].weight[:, 2 * 4 * 8] = 0.0
        assert torch.allclose(same_level(low), same_level(4.0 * low), atol=1e-6)
        assert float((model(low) - model(4.0 * low)).abs().max()) > 1e-4
    plain = example.Enhancer(8, seed=0).eval()
    with torch.no_grad():
        assert float((plain(low) - plain(4.0 * low)).abs().max()) > 1e-5


def test_matched_colour_gives_the_training_inputs_the_references_colour_cast(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    example = _example()
    images = example.read_clean_images([folders[2]], 32)
    profiles = _reference_profiles(tmp_path, 4, {"green": 0.1 * np.array([0.8, 1.2, 0.9])})
    tone = darksynth.load_profile(profiles[0]).tone
    assert tone is not None and tone.colour is not None
    target = np.array(tone.colour)
    cast = example.ProfileExposures(images, profiles, 1, seed=0, match_colour=True)
    plain = example.ProfileExposures(images, profiles, 1, seed=0)
    clean = images[0].float() / 255.0
    shares = {}
    for name, exposures in (("cast", cast), ("plain", plain)):
        low = example.profile_low_light(exposures, noise=False)(0, clean, 0).double()
        means = low.mean(dim=(1, 2)).numpy()
        shares[name] = means / means.mean()
    assert cast.pick(0, 0)[3] is not None and plain.pick(0, 0)[3] is None
    assert np.abs(shares["cast"] - target).max() < 0.03, (shares, target)
    assert np.abs(shares["plain"] - target).max() > 0.1, (shares, target)


def test_the_diagnostic_methods_train_on_albumentations_darkening_with_and_without_darksynth_noise(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    clean = folders[2]
    out = tmp_path / "out"
    arguments = [*_two_step_run(folders, out), "--normalise-exposure", "--methods", "albu-gamma,albu-gamma-darksynth"]
    assert _example().main(arguments) == 0
    record = json.loads((out / "results.json").read_text())
    assert set(record["results"]) == {"low input", "albu-gamma", "albu-gamma-darksynth"}
    assert record["settings"]["normalise_exposure"] is True
    example = _example()
    images = example.read_clean_images([clean], 32)
    exposures = example.ProfileExposures(images, [out / "profiles" / "srgb" / "2.json"], 1, seed=0)
    crop = images[0][:, :32, :32].float() / 255.0
    quiet = example.albumentations_low_light("none")(0, crop, 5)
    noisy = example.albumentations_low_light("darksynth", exposures)(0, crop, 5)
    assert quiet.shape == noisy.shape and not torch.equal(quiet, noisy)
    with pytest.raises(ValueError, match="needs the exposures"):
        example.albumentations_low_light("darksynth")
    with pytest.raises(ValueError, match="noise must be"):
        example.albumentations_low_light("poisson")


def test_the_noise_scale_multiplies_the_noise_about_the_darkened_image() -> None:
    example = _example()
    generator = torch.Generator().manual_seed(0)
    darkened = (torch.full((3, 64, 64), 0.2) * 255.0).round() / 255.0
    noisy = ((darkened + 0.03 * torch.randn(3, 64, 64, generator=generator)).clamp(0.0, 1.0) * 255.0).round() / 255.0
    assert example.scaled_noise(noisy, darkened, 1.0) is noisy
    assert torch.equal(example.scaled_noise(noisy, darkened, 0.0), darkened)
    half = example.scaled_noise(noisy, darkened, 0.5)
    # On 8-bit levels, with half the std (7.65 levels -> 3.8; rounding adds 1/12 level^2 of variance).
    assert torch.equal((half * 255.0).round() / 255.0, half)
    ratio = float((half - darkened).std() / (noisy - darkened).std())
    assert 0.47 < ratio < 0.53, ratio


def test_the_float_paper_range_darkens_within_its_ranges_and_rounds_once() -> None:
    example = _example()
    clean = torch.linspace(0.0, 1.0, 3 * 32 * 32).reshape(3, 32, 32)
    for seed in range(20):
        low = example.float_paper_range_low_light(0, clean, seed)
        assert torch.equal(low, example.float_paper_range_low_light(5, clean, seed))  # the seed alone draws
        assert torch.equal((low * 255.0).round() / 255.0, low)
        # Full white comes out at brightness ** gamma: within 0.05 ** 2.5 and 0.3.
        assert 0.05**2.5 - 1 / 255 <= float(low[2, -1, -1]) <= 0.3 + 1 / 255


def _two_reference_exposures(clean: Path, tmp_path: Path, gain_draw: str) -> Any:
    """The example's exposures of the clean images' 32-px crops, from two references 7.5x apart, with ``gain_draw``."""
    example = _example()
    images = example.read_clean_images([clean], 32)
    profiles = _reference_profiles(tmp_path, 2, {"reference0": 0.04, "reference1": 0.3})
    return example.ProfileExposures(images, profiles, 2, seed=0, gain_draw=gain_draw)


def test_the_profile_draw_gives_every_image_the_darkenings_the_references_were_read_to_have(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    exposures = _two_reference_exposures(folders[2], tmp_path, "profile")
    read = [
        (index, profile.darkening.alpha, profile.darkening.gamma) for index, profile in enumerate(exposures.profiles)
    ]
    drawn = [exposures.pick(0, seed) for seed in range(40)]
    # Each draw is one reference's own darkening, both references are drawn, no colour cast, whatever the image.
    assert {pick[:3] for pick in drawn} == set(read)
    assert all(pick[3] is None for pick in drawn)
    assert drawn == [exposures.pick(1, seed) for seed in range(40)]


def test_the_profile_range_draw_spreads_alpha_and_gamma_between_the_references_readings(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    exposures = _two_reference_exposures(folders[2], tmp_path, "profile-range")
    alphas = [profile.darkening.alpha for profile in exposures.profiles]
    gammas = [profile.darkening.gamma for profile in exposures.profiles]
    drawn = [exposures.pick(0, seed) for seed in range(200)]
    assert all(
        min(alphas) <= alpha <= max(alphas) and min(gammas) <= gamma <= max(gammas) for _, alpha, gamma, _ in drawn
    )
    # Evenly between the two readings: each half of alpha's range holds about half the draws.
    middle = (min(alphas) + max(alphas)) / 2
    assert max(alphas) > min(alphas) and abs(sum(alpha < middle for _, alpha, _, _ in drawn) / 200 - 0.5) < 0.12
    assert drawn == [exposures.pick(1, seed) for seed in range(200)]


def test_the_target_tone_renders_the_targets_and_leaves_the_inputs_as_they_are() -> None:
    example = _example()
    image = (torch.linspace(0.0, 1.0, 3 * 48 * 48).reshape(3, 48, 48) * 255.0).round().to(torch.uint8)
    seen: list[torch.Tensor] = []

    def low_light(_: int, clean: torch.Tensor, __: int) -> torch.Tensor:
        seen.append(clean)
        return 0.1 * clean

    plain = example.LowLightCrops([image], low_light, 16, 2, seed=5)
    flat = example.LowLightCrops([image], low_light, 16, 2, seed=5, target_tone=(0.9, 0.6))
    low, target = plain[1]
    flat_low, flat_target = flat[1]
    assert torch.equal(seen[0], seen[1]) and torch.equal(target, seen[0])
    assert torch.equal(low, flat_low)
    assert torch.allclose(flat_target, 0.9 * target.pow(0.6))
    assert float(flat_target.mean()) > float(target.mean()) + 0.03


@pytest.mark.parametrize("tone", ["0.9", "0.9,x", "0,0.6", "0.9,5"])
def test_a_bad_target_tone_is_refused(tone: str, tmp_path: Path) -> None:
    with pytest.raises(SystemExit):
        _example().parse(["--target-tone", tone, "--out", str(tmp_path)])


def test_a_target_s_tone_is_read_against_average_scenes() -> None:
    from tests.tone_scenes import prior_scene

    example = _example()
    scenes = [prior_scene(seed, size=192) for seed in range(3)]
    assert example.target_tone_of(scenes) == pytest.approx((1.0, 1.0), rel=0.1)
    flattened = [0.8 * scene.pow(0.6) for scene in scenes]
    assert example.target_tone_of(flattened) == pytest.approx((0.8, 0.6), rel=0.1)


def test_the_folds_alternate_in_name_order_and_each_leaves_out_what_it_tests() -> None:
    example = _example()
    pairs = [example.TestPair(name, torch.zeros(3, 8, 8), torch.zeros(3, 8, 8)) for name in "abcde"]
    (other0, tested0), (other1, tested1) = example.folds(pairs)
    assert [pair.name for pair in tested0] == ["a", "c", "e"] and other0 == tested1
    assert [pair.name for pair in tested1] == ["b", "d"] and other1 == tested0


def test_the_folds_target_tone_trains_once_per_fold_and_scores_every_pair(
    folders: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    arguments = [*_two_step_run(folders, out), "--methods", "darkening-only", "--target-tone", "folds"]
    assert _example().main(arguments) == 0
    record = json.loads((out / "results.json").read_text())
    assert record["settings"]["target_tone"] == "folds"
    assert set(record["results"]["darkening-only"]["per_pair"]) == {"0.png", "1.png"}
