"""The downstream check: denoiser shape, learning on a known Gaussian law, determinism, unavailable methods."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from PIL import Image

from darksynth.errors import DarksynthError
from darksynth.evaluation.measures import downstream
from darksynth.evaluation.measures.denoiser import (
    DownstreamSettings,
    ResidualDenoiser,
    train_denoiser,
    train_on_real_pairs,
)
from darksynth.evaluation.measures.downstream import (
    LPIPS_STATUS,
    NOISY_INPUT,
    REAL_PAIRS,
    camera_folds,
    fit_reference_parameters,
    run_downstream,
)
from darksynth.evaluation.methods.catalogue import build_method
from darksynth.evaluation.methods.classical import PoissonGaussian, add_poisson_gaussian
from darksynth.evaluation.methods.method import NoiseMethod
from darksynth.evaluation.pairs import Pair, list_pair_set, load_pair
from tests.evaluation.conftest import MakeSet, smooth_clean

SIGMA = 20.0
"""Noise of the synthetic pairs and of the known method, in 8-bit units: strong enough to learn in a few steps."""

TINY = DownstreamSettings(steps=4, batch=2, crop=16, width=4, depth=3)


@pytest.fixture(autouse=True)
def one_thread() -> None:
    torch.set_num_threads(1)


def gaussian_method(sigma: float = SIGMA) -> NoiseMethod:
    law = PoissonGaussian(a=(0.0, 0.0, 0.0), b=((sigma / 255.0) ** 2,) * 3)
    return NoiseMethod(
        name=f"gauss{sigma:g}",
        summary="known Gaussian law",
        fit=lambda noisy, clean: law,
        synthesize=lambda clean, fitted, generator: add_poisson_gaussian(clean, fitted, generator),
    )


def clean_images(count: int = 4) -> list[np.ndarray]:
    return [smooth_clean(80, 96, 11 * index + 3) for index in range(count)]


def test_denoiser_keeps_any_image_size_and_starts_near_the_identity() -> None:
    model = ResidualDenoiser(width=6, depth=4)
    image = torch.rand(2, 3, 17, 29)
    with torch.no_grad():
        output = model(image)
    assert output.shape == image.shape
    assert float((output - image).abs().max()) < 0.5
    assert len([m for m in model.modules() if isinstance(m, torch.nn.Conv2d)]) == 4


def test_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="depth"):
        DownstreamSettings(depth=1)
    with pytest.raises(ValueError, match="loss"):
        DownstreamSettings(loss="huber")  # type: ignore[arg-type]


def test_training_on_the_known_law_beats_the_noisy_input(make_pair_set: MakeSet) -> None:
    root = make_pair_set("gauss", count=2, sigma=SIGMA, size=64)
    pairs = [load_pair(pair) for pair in list_pair_set(root).pairs]
    method = gaussian_method()
    parameters = fit_reference_parameters(method, pairs)
    settings = DownstreamSettings(steps=100, batch=4, crop=32, width=8, depth=3, learning_rate=3e-3)
    model = train_denoiser(method, parameters, clean_images(), settings)
    losses = model.training_losses
    assert len(losses) == len(model.input_losses) == settings.steps
    assert np.mean(losses[-10:]) < 0.8 * np.mean(model.input_losses[-10:])
    assert np.mean(losses[-10:]) < 0.8 * np.mean(losses[:10])
    scores = downstream.test_denoiser(model, pairs)
    assert scores["pairs"] == 2 and scores[NOISY_INPUT]["pairs"] == 2
    assert scores["psnr"] > scores[NOISY_INPUT]["psnr"] + 1.5
    assert scores["ssim"] > scores[NOISY_INPUT]["ssim"]


def test_same_seed_same_weights_other_seed_other_weights() -> None:
    method = gaussian_method()
    law = method.fit(torch.zeros(1), torch.zeros(1))
    first = train_denoiser(method, [law], clean_images(2), TINY)
    second = train_denoiser(method, [law], clean_images(2), TINY)
    other = train_denoiser(method, [law], clean_images(2), replace(TINY, seed=1))
    for name, tensor in first.state_dict().items():
        assert torch.equal(tensor, second.state_dict()[name])
    assert first.training_losses == second.training_losses
    assert not torch.equal(first.state_dict()["body.0.weight"], other.state_dict()["body.0.weight"])


def test_every_method_sees_the_same_clean_crops() -> None:
    seen: dict[str, list[torch.Tensor]] = {"weak": [], "strong": []}

    def recording(name: str, sigma: float) -> NoiseMethod:
        inner = gaussian_method(sigma)

        def synthesize(clean: torch.Tensor, fitted: Any, generator: torch.Generator) -> torch.Tensor:
            seen[name].append(clean.clone())
            return inner.synthesize(clean, fitted, generator)

        return NoiseMethod(name=name, summary="", fit=inner.fit, synthesize=synthesize)

    for name, sigma in (("weak", 2.0), ("strong", 30.0)):
        method = recording(name, sigma)
        law = method.fit(torch.zeros(1), torch.zeros(1))
        train_denoiser(method, [law, law], clean_images(3), TINY)
    assert len(seen["weak"]) == TINY.steps * TINY.batch
    assert all(torch.equal(a, b) for a, b in zip(seen["weak"], seen["strong"], strict=True))


def test_failed_fits_are_recorded_or_raised(make_pair_set: MakeSet) -> None:
    pairs = [load_pair(pair) for pair in list_pair_set(make_pair_set(count=2, size=64)).pairs]

    def refuse(noisy: torch.Tensor, clean: torch.Tensor) -> None:
        raise DarksynthError("cannot fit")

    method = NoiseMethod(name="refuses", summary="", fit=refuse, synthesize=gaussian_method().synthesize)
    problems: list[str] = []
    assert fit_reference_parameters(method, pairs, problems) == []
    assert len(problems) == 2 and "refuses: cannot fit" in problems[0]
    with pytest.raises(DarksynthError, match="cannot fit"):
        fit_reference_parameters(method, pairs)
    with pytest.raises(DarksynthError, match="no fitted parameters"):
        train_denoiser(method, [], clean_images(1), TINY)
    zero_shot = build_method("awgn-blind")
    assert len(fit_reference_parameters(zero_shot, pairs)) == 2


def write_clean_folder(folder: Path, count: int = 3) -> Path:
    folder.mkdir()
    for index, image in enumerate(clean_images(count)):
        Image.fromarray(image).save(folder / f"clean_{index}.png")
    return folder


def test_run_reports_every_set_and_skips_unavailable_methods(make_pair_set: MakeSet, tmp_path: Path) -> None:
    first = make_pair_set("first", count=2, size=48, sigma=6.0)
    second = make_pair_set("second", count=1, size=48, sigma=6.0, seed=1)
    clean_root = write_clean_folder(tmp_path / "clean")
    messages: list[str] = []
    results = run_downstream(
        [first, second, tmp_path / "absent"],
        ["awgn", "nope", "den-v2", "pg-oracle"],
        [clean_root],
        TINY,
        weights={"den-v2": tmp_path / "missing.safetensors"},
        progress=messages.append,
    )
    assert results["lpips"] == LPIPS_STATUS and LPIPS_STATUS.startswith("not computed: ")
    assert results["settings"]["steps"] == TINY.steps
    assert results["clean_images"]["count"] == 3
    assert set(results["methods"]) == {"awgn", "pg-oracle"}
    problems = " | ".join(results["problems"])
    assert "nope: unknown method" in problems and "den-v2: no trained weights" in problems and "absent" in problems
    # A set of two pairs gets the real-pair ceiling, trained on one pair and tested on the other; a set of one
    # cannot.
    assert list(results["first"]) == [NOISY_INPUT, "awgn", "pg-oracle", REAL_PAIRS]
    assert list(results["second"]) == [NOISY_INPUT, "awgn", "pg-oracle"]
    assert results["first"][REAL_PAIRS]["folds"] == 2
    for name, pairs in (("first", 2), ("second", 1)):
        for method, row in results[name].items():
            assert row["pairs"] == pairs
            assert np.isfinite(row["psnr"]) and 0.0 < row["ssim"] <= 1.0
            assert method in (NOISY_INPUT, REAL_PAIRS) or row["training"]["input_loss"] > 0.0
    # The fixed awgn law is the same on every set: its denoiser is trained once and reused.
    assert any("second: awgn: same fixed parameters" in message for message in messages)
    assert results["first"]["awgn"]["psnr"] != results["second"]["awgn"]["psnr"]


def test_run_without_any_available_method_fails(make_pair_set: MakeSet, tmp_path: Path) -> None:
    with pytest.raises(DarksynthError, match="no method can run"):
        run_downstream([make_pair_set(count=1, size=48)], ["nope"], [tmp_path], TINY)


def test_folds_alternate_within_each_camera_and_none_is_empty() -> None:
    pairs = [
        Pair(name=f"{camera}{index}.png", noisy_path=Path("n"), clean_path=Path("c"), camera=camera)
        for camera, count in (("a", 3), ("b", 2), ("c", 1))
        for index in range(count)
    ]
    folds = camera_folds(pairs, 2)
    by_camera = {
        camera: [fold for pair, fold in zip(pairs, folds, strict=True) if pair.camera == camera] for camera in "abc"
    }
    assert sorted(by_camera["a"]) == [0, 0, 1] and sorted(by_camera["b"]) == [0, 1], by_camera
    assert sorted(folds) == [0, 0, 0, 1, 1, 1]


def test_the_denoiser_trained_on_real_pairs_beats_their_noisy_input(make_pair_set: MakeSet) -> None:
    root = make_pair_set("real", count=2, sigma=SIGMA, size=64)
    pairs = [load_pair(pair) for pair in list_pair_set(root).pairs]
    settings = DownstreamSettings(steps=150, batch=4, crop=32, width=8, depth=3)
    model = train_on_real_pairs(pairs[:1], settings)
    scores = downstream.test_denoiser(model, pairs[1:])
    assert scores["psnr"] > scores[NOISY_INPUT]["psnr"] + 1.0, scores
