"""The Starlight generator (baselines/starlight_model.py): shapes, the physics laws, weights on disk."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file, save_file

from darksynth.baselines.starlight import (
    MODEL_NAME,
    PHYSICS_NAMES,
    StarlightConfig,
    StarlightGenerator,
    default_starlight_path,
    load_starlight,
    save_starlight,
)
from darksynth.errors import DarksynthError

TINY = StarlightConfig(width=4, depth=1, noise_channels=2)
OFF = 1e-12
"""A scale so small that its term vanishes in float32 next to the others."""


def _generator(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _physics_only(**values: float | list[float]) -> StarlightGenerator:
    """A tiny generator, no rounding, the U-Net's residual zero, every term off except those given."""
    model = StarlightGenerator(StarlightConfig(width=4, depth=1, noise_channels=2, quantize=False))
    model.zero_residual()
    model.set_physics_values({name: OFF for name in PHYSICS_NAMES})
    model.set_physics_values(values)
    return model.eval()


# -- shapes and ranges -------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(2, 3, 17, 23), (1, 3, 1, 1), (2, 3, 3, 40, 9), (1, 1, 3, 64, 64)])
def test_output_keeps_shape_and_lies_in_the_unit_range_at_any_size(shape: tuple[int, ...]) -> None:
    torch.manual_seed(0)
    model = StarlightGenerator(TINY).eval()
    # A non-zero residual, so that the U-Net's padding and cropping are exercised too.
    torch.nn.init.normal_(model.net.out.weight, std=1.0)
    model.set_physics_values({"read": 0.2, "row": 0.1})
    clean = torch.rand(shape, generator=_generator(1))
    with torch.no_grad():
        noisy = model(clean, _generator(2))
    assert noisy.shape == clean.shape
    assert float(noisy.min()) >= 0.0 and float(noisy.max()) <= 1.0
    assert torch.equal(noisy, (noisy * 255).round() / 255), "the default output is on 8-bit levels"
    assert float((noisy - clean).abs().mean()) > 0.01


def test_same_generator_seed_gives_the_same_output_and_another_seed_does_not() -> None:
    torch.manual_seed(0)
    model = StarlightGenerator(TINY).eval()
    clean = torch.rand(2, 3, 3, 24, 24, generator=_generator(1)) * 0.3
    with torch.no_grad():
        first, again, other = model(clean, _generator(5)), model(clean, _generator(5)), model(clean, _generator(6))
    assert torch.equal(first, again)
    assert not torch.equal(first, other)


def test_wrong_input_shape_is_refused() -> None:
    model = StarlightGenerator(TINY)
    with pytest.raises(ValueError, match="expected"):
        model(torch.zeros(3, 8, 8))
    with pytest.raises(ValueError, match="expected"):
        model(torch.zeros(1, 4, 8, 8))


def test_the_untrained_residual_is_zero_and_gradients_reach_every_parameter() -> None:
    torch.manual_seed(0)
    model = StarlightGenerator(StarlightConfig(width=4, depth=1, quantize=False))
    clean = torch.rand(2, 2, 3, 16, 16, generator=_generator(1)) * 0.2
    physics = _physics_only(**model.physics_values())  # same scales, no U-Net
    with torch.no_grad():
        assert torch.equal(model(clean, _generator(3)), physics(clean, _generator(3)))
    model(clean, _generator(3)).square().sum().backward()
    for name, parameter in model.named_parameters():
        if name.startswith("log_") or name.startswith("net.out"):
            assert parameter.grad is not None and float(parameter.grad.abs().sum()) > 0, name


# -- the physics laws --------------------------------------------------------------------------------------


def test_physics_variance_grows_linearly_with_the_signal_slope_shot_squared_intercept_read_squared() -> None:
    shot, read = 0.1, 0.03
    model = _physics_only(shot=shot, read=read)
    # Levels at least 3.4 standard deviations from 0 and 1: clipping leaves the variance alone.
    levels = torch.tensor([0.25, 0.35, 0.45, 0.55, 0.65])
    clean = levels.reshape(5, 1, 1, 1).expand(5, 3, 128, 128).contiguous()
    with torch.no_grad():
        noise = model(clean, _generator(4)) - clean
    variance = noise.flatten(1).var(dim=1).double().numpy()
    slope, intercept = np.polyfit(levels.double().numpy(), variance, 1)
    assert slope == pytest.approx(shot**2, rel=0.05)
    assert intercept == pytest.approx(read**2, rel=0.15)


def test_uniform_noise_lies_in_zero_to_q_with_its_mean_and_variance() -> None:
    q = 0.05
    model = _physics_only(uniform=q)
    clean = torch.full((2, 3, 64, 64), 0.5)
    with torch.no_grad():
        noise = model(clean, _generator(1)) - clean
    assert float(noise.min()) >= -1e-6 and float(noise.max()) <= q + 1e-6
    assert float(noise.mean()) == pytest.approx(q / 2, rel=0.02)
    assert float(noise.var()) == pytest.approx(q**2 / 12, rel=0.05)


def test_row_noise_is_constant_down_each_column_varies_along_the_row_and_per_frame() -> None:
    sigma = 0.03
    model = _physics_only(row=sigma)
    clean = torch.full((4, 3, 3, 32, 40), 0.5)
    with torch.no_grad():
        noise = model(clean, _generator(2)) - clean
    # Starlight's "row" pattern: one offset per (frame, channel, column index), the same at every row.
    assert float((noise - noise[..., :1, :]).abs().max()) < 1e-6
    assert float(noise[..., 0, :].std()) == pytest.approx(sigma, rel=0.1)
    assert not torch.allclose(noise[:, 0], noise[:, 1]), "redrawn every frame"
    assert not torch.allclose(noise[:, :, 0], noise[:, :, 1]), "drawn per channel"


def test_temporal_row_noise_is_identical_in_every_frame_of_a_clip_and_differs_between_clips() -> None:
    sigma = 0.03
    model = _physics_only(row_temporal=sigma)
    clean = torch.full((6, 5, 3, 16, 48), 0.5)
    with torch.no_grad():
        noise = model(clean, _generator(3)) - clean
    assert float((noise - noise[:, :1]).abs().max()) < 1e-6, "held over the frames"
    assert float((noise - noise[..., :1, :]).abs().max()) < 1e-6, "constant down the columns"
    assert not torch.allclose(noise[0], noise[1]), "drawn once per clip"
    assert float(noise[:, 0, :, 0, :].std()) == pytest.approx(sigma, rel=0.1)


def test_periodic_noise_has_column_spectrum_peaks_at_zero_quarter_and_three_quarter_width() -> None:
    sigmas = [0.01, 0.02, 0.03]
    model = _physics_only(periodic=sigmas)
    width = 64
    clean = torch.full((64, 2, 3, 8, width), 0.5)
    with torch.no_grad():
        noise = model(clean, _generator(4)) - clean
    assert float((noise - noise[..., :1, :]).abs().max()) < 1e-6
    spectrum = torch.fft.fft(noise[..., 0, :].double(), dim=-1).abs()
    peaks = {0, width // 4, 3 * width // 4}
    others = [k for k in range(width) if k not in peaks]
    assert float(spectrum[..., others].max()) < 1e-6 * float(spectrum.max())
    # Per-pixel strength sqrt(s1^2 + s2^2 + s3^2), whatever the width.
    assert float(noise.std()) == pytest.approx(math.sqrt(sum(s * s for s in sigmas)), rel=0.1)


def test_set_physics_values_refuses_bad_values() -> None:
    model = StarlightGenerator(TINY)
    with pytest.raises(ValueError, match="positive"):
        model.set_physics_values({"shot": 0.0})
    with pytest.raises(KeyError, match="known"):
        model.set_physics_values({"banding": 0.1})
    model.set_physics_values({"periodic": [0.1, 0.2, 0.3]})
    assert model.physics_values()["periodic"] == pytest.approx([0.1, 0.2, 0.3])


# -- weights on disk ---------------------------------------------------------------------------------------


def _trained_looking(seed: int) -> StarlightGenerator:
    torch.manual_seed(seed)
    model = StarlightGenerator(TINY)
    torch.nn.init.normal_(model.net.out.weight, std=0.5)
    model.set_physics_values({"shot": 0.07, "periodic": [0.01, 0.002, 0.003]})
    return model.eval()


def test_save_and_load_round_trip_is_bit_identical(tmp_path: Path) -> None:
    model = _trained_looking(3)
    path = tmp_path / "starlight.safetensors"
    save_starlight(path, model, training={"steps": 5})
    loaded = load_starlight(path)
    assert loaded.config == model.config
    assert not loaded.training
    original, restored = model.state_dict(), loaded.state_dict()
    assert original.keys() == restored.keys()
    assert all(torch.equal(original[k], restored[k]) for k in original)
    clean = torch.rand(2, 3, 3, 20, 28, generator=_generator(1)) * 0.3
    with torch.no_grad():
        assert torch.equal(model(clean, _generator(7)), loaded(clean, _generator(7)))
        assert not torch.equal(_trained_looking(4)(clean, _generator(7)), loaded(clean, _generator(7)))


def _write(path: Path, tensors: dict[str, torch.Tensor], **metadata: str) -> Path:
    save_file(tensors, str(path), metadata=metadata)
    return path


@pytest.mark.parametrize("problem", ["missing", "garbage", "truncated", "other_model", "other_version", "shape"])
def test_an_unusable_weights_file_raises_darksynth_error_naming_it(tmp_path: Path, problem: str) -> None:
    model = _trained_looking(3)
    good = tmp_path / "good.safetensors"
    save_starlight(good, model)
    tensors = load_file(str(good))
    config = json.dumps(model.config.to_dict())
    path = tmp_path / f"{problem}.safetensors"
    if problem == "garbage":
        path.write_bytes(b"not a safetensors file at all")
    elif problem == "truncated":
        path.write_bytes(good.read_bytes()[:200])
    elif problem == "other_model":
        _write(path, tensors, model="darksynth-den", version="1", config=config)
    elif problem == "other_version":
        _write(path, tensors, model=MODEL_NAME, version="99", config=config)
    elif problem == "shape":
        _write(path, tensors, model=MODEL_NAME, version="1", config=json.dumps({**model.config.to_dict(), "width": 6}))
    with pytest.raises(DarksynthError) as caught:
        load_starlight(path)
    message = str(caught.value)
    assert str(path) in message and "\n" not in message


def test_the_shipped_weights_load_and_generate() -> None:
    path = default_starlight_path()
    assert path.name == "starlight.safetensors"
    # The weights are package data: a missing file is a broken package, not a reason to skip.
    assert path.is_file(), f"{path}: the shipped Starlight weights are missing from the package"
    assert path.stat().st_size < 2_000_000
    model = load_starlight()
    clean = torch.rand(1, 3, 3, 33, 47, generator=_generator(1)) * 0.2
    with torch.no_grad():
        noisy = model(clean, _generator(2))
    assert noisy.shape == clean.shape and float(noisy.min()) >= 0 and float(noisy.max()) <= 1
    assert float((noisy - clean).abs().mean()) > 1 / 255, "the shipped generator adds noise"
    assert all(v > 0 for name in PHYSICS_NAMES for v in np.atleast_1d(model.physics_values()[name]))
