"""The evaluation's methods: names, availability, zero-shot discipline, 8-bit outputs, adaptivity."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from darksynth.evaluation.methods.catalogue import (
    AWGN_SIGMA,
    METHOD_NAMES,
    MethodUnavailableError,
    build_method,
    synthesize_image,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels
from tests.evaluation.test_classical import smooth_scene

ZERO_SHOT_ADAPTIVE = ("awgn-blind", "pg-blind", "den")


def noisy_version(clean: torch.Tensor, sigma: float, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    return to_8bit_levels(clean + sigma * torch.randn(clean.shape, generator=generator, dtype=clean.dtype))


@pytest.fixture(scope="module")
def clean() -> torch.Tensor:
    return to_8bit_levels(smooth_scene(192))


def test_unknown_and_unbuilt_methods_are_unavailable(tmp_path: Path) -> None:
    with pytest.raises(MethodUnavailableError, match="nope: unknown method"):
        build_method("nope")
    with pytest.raises(MethodUnavailableError, match=r"den-v1: .*absent\.safetensors: no v1 weights"):
        build_method("den-v1", weights={"den-v1": tmp_path / "absent.safetensors"})
    with pytest.raises(MethodUnavailableError, match=r"den-v2: no trained weights at .*absent"):
        build_method("den-v2", weights={"den-v2": tmp_path / "absent.safetensors"})
    corrupt = tmp_path / "corrupt.safetensors"
    corrupt.write_bytes(b"not safetensors")
    with pytest.raises(MethodUnavailableError, match=r"den: .*corrupt\.safetensors: not a readable safetensors"):
        build_method("den", weights={"den": corrupt})


@pytest.mark.parametrize("name", ZERO_SHOT_ADAPTIVE)
def test_zero_shot_methods_never_read_the_clean_image(name: str, clean: torch.Tensor) -> None:
    method = build_method(name)
    noisy = noisy_version(clean, 0.03, seed=0)
    fitted = method.fit(noisy, clean)
    other = method.fit(noisy, torch.zeros_like(clean))
    first = method.synthesize(clean, fitted, torch.Generator().manual_seed(5))
    second = method.synthesize(clean, other, torch.Generator().manual_seed(5))
    assert torch.equal(first, second)


@pytest.mark.parametrize("name", [n for n in METHOD_NAMES if n not in ("den-v1", "den-v2", "starlight")])
def test_outputs_are_8bit_images_of_the_clean_size(name: str, clean: torch.Tensor) -> None:
    method = build_method(name)
    noisy = noisy_version(clean, 0.03, seed=1)
    synthetic = method.synthesize(clean, method.fit(noisy, clean), torch.Generator().manual_seed(0))
    assert synthetic.shape == clean.shape
    assert torch.equal(synthetic * 255, (synthetic * 255).round())
    assert float(synthetic.min()) >= 0.0 and float(synthetic.max()) <= 1.0


def test_fixed_awgn_does_not_adapt(clean: torch.Tensor) -> None:
    method = build_method("awgn")
    for sigma in (0.01, 0.06):
        synthetic = method.synthesize(clean, method.fit(noisy_version(clean, sigma, 2), clean), torch.Generator())
        assert float((synthetic - clean).std()) == pytest.approx(AWGN_SIGMA, rel=0.1)


@pytest.mark.parametrize("name", (*ZERO_SHOT_ADAPTIVE, "pg-oracle"))
def test_adaptive_methods_follow_the_reference_noise_level(name: str, clean: torch.Tensor) -> None:
    method = build_method(name)
    stds = []
    for sigma in (0.01, 0.06):
        noisy = noisy_version(clean, sigma, seed=3)
        synthetic = method.synthesize(clean, method.fit(noisy, clean), torch.Generator().manual_seed(0))
        stds.append(float((synthetic - clean).std()))
    assert stds[1] > 2.5 * stds[0]
    if name != "den":  # the classical estimators are built for white Gaussian noise like this
        assert stds == pytest.approx([0.01, 0.06], rel=0.2)


def test_the_default_comparison_is_the_papers_and_every_name_is_known() -> None:
    from darksynth.evaluation.methods.catalogue import DEFAULT_METHODS

    assert DEFAULT_METHODS == (
        "den", "den-paper", "den-v1", "den-v2", "awgn", "awgn-blind", "pg", "pg-blind", "pg-oracle", "starlight",
    )  # fmt: skip
    assert set(DEFAULT_METHODS) < set(METHOD_NAMES)


def test_every_den_method_uses_a_shipped_den_of_its_noise_model_and_variant() -> None:
    from darksynth.evaluation.methods.catalogue import DEN_METHODS
    from darksynth.training.weights import SHIPPED_WEIGHTS

    assert DEN_METHODS == {
        "den": ("srgb", "v3"),
        "den-prior": ("srgb", "v3"),
        "den-prior-octaves": ("srgb", "v3"),
        "den-network": ("srgb", "v3"),
        "den-paper": ("paper", "v3"),
        "den-v2": ("paper", "v2"),
    }
    assert set(DEN_METHODS.values()) <= set(SHIPPED_WEIGHTS)
    for name, (noise_model, variant) in DEN_METHODS.items():
        method = build_method(name)
        assert f"DEN {variant}, {noise_model} noise model" in method.summary
        assert method.details["weights"].endswith(SHIPPED_WEIGHTS[noise_model, variant])


def test_den_measures_the_spectrum_and_den_network_does_not() -> None:
    assert "spectrum measured on it" in build_method("den").summary
    assert "spectrum" not in build_method("den-network").summary
    assert "spectrum" not in build_method("den-paper").summary


@pytest.mark.parametrize("name", ["den-srgb", "srgb-oracle", "pg-corr-oracle"])
def test_the_retired_srgb_methods_are_unknown(name: str) -> None:
    with pytest.raises(MethodUnavailableError, match="unknown method"):
        build_method(name)


def test_the_shipped_v2_ablation_is_a_den_without_decoder() -> None:
    method = build_method("den-v2")
    assert "DEN v2" in method.summary and method.details["weights"].endswith("den_v2.safetensors")


def test_methods_synthesise_through_the_composer(clean: torch.Tensor) -> None:
    values = NoiseValues.from_values({"shot": 0.04, "read": 0.01, "correlation_length": 0.8})
    synthetic = synthesize_image(clean, values, torch.Generator().manual_seed(3))
    composed = to_8bit_levels(add_noise(clean[None], values, generator=torch.Generator().manual_seed(3))[0])
    assert torch.equal(synthetic, composed)


def test_methods_of_the_camera_prior_leave_the_judged_set_and_its_cameras_out() -> None:
    den, prior, plain = build_method("den-prior"), build_method("prior"), build_method("den")
    for method in (den, prior):
        for judged, left_out in (("nam-cc15", {"nam-cc15", "nam-cc60"}), ("polyu", {"polyu"}), ("sidd", {"sidd"})):
            sets = set(method.on_set(judged).details["prior_sets"])
            assert sets and not sets & left_out, (method.name, judged, sets)
    # The plain estimate takes a camera JPEG's texture dependence from the prior fitted without the set judged.
    for method in (den, plain):
        for judged, left_out in (("nam-cc15", {"nam-cc15", "nam-cc60"}), ("polyu", {"polyu"})):
            sets = set(method.on_set(judged).details["jpeg_texture_prior_sets"])
            assert sets and not sets & left_out, (method.name, judged, sets)


def test_prior_draws_differ_between_seeds_and_ignore_the_noisy_image(clean: torch.Tensor) -> None:
    method = build_method("prior").on_set("polyu")
    noisy = noisy_version(clean, 0.03, seed=3)
    first = method.synthesize(clean, method.fit(noisy, clean), torch.Generator().manual_seed(1))
    again = method.synthesize(clean, method.fit(torch.zeros_like(noisy), clean), torch.Generator().manual_seed(1))
    other = method.synthesize(clean, method.fit(noisy, clean), torch.Generator().manual_seed(2))
    assert torch.equal(first, again)
    assert not torch.equal(first, other)
