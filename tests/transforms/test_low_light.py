"""darksynth.transforms.low_light: the PyTorch transform LowLight, its seeding in DataLoader workers, bad input."""

from __future__ import annotations

import importlib
import math
import pickle
import sys

import numpy as np
import pytest
import torch
import torch.utils.data

import darksynth
from darksynth.light.darkening import Darkening, darken
from darksynth.profile import Profile
from darksynth.transforms import LowLight
from tests.conftest import build_profile

LEVEL = 1.0 / 255.0


def _flat(value: float, shape: tuple[int, ...]) -> torch.Tensor:
    return torch.full(shape, value, dtype=torch.float32)


def _on_8bit_levels(image: torch.Tensor) -> bool:
    scaled = image.double() * 255.0
    return bool((scaled - scaled.round()).abs().max() < 1e-3)


def _everything_profile() -> Profile:
    return build_profile(
        darkening=Darkening(alpha=0.3, gamma=0.7),
        shot=0.05,
        read=0.01,
        quantization=0.004,
        banding=0.004,
        temporal_banding=0.003,
        periodic=[0.002, 0.002, 0.002],
        channel_gain=[1.3, 1.4],
        correlation_length=0.8,
        channel_correlation=[0.5, 0.4, 0.6],
    )


# --- shapes, dtypes, ranges --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("shape", "dtype"),
    [
        ((3, 20, 24), torch.float32),
        ((2, 3, 20, 24), torch.float32),
        ((1, 20, 24), torch.float32),
        ((3, 20, 24), torch.float64),
        ((3, 20, 24), torch.uint8),
        ((2, 3, 20, 24), torch.uint8),
    ],
)
def test_output_keeps_shape_and_dtype_and_lies_in_range(shape: tuple[int, ...], dtype: torch.dtype) -> None:
    clean = torch.rand(shape, generator=torch.Generator().manual_seed(0))
    clean = (clean * 255).round().to(dtype) if dtype == torch.uint8 else clean.to(dtype)
    noisy = LowLight(_everything_profile(), seed=1)(clean)
    assert noisy.shape == clean.shape
    assert noisy.dtype == dtype
    if dtype.is_floating_point:
        assert noisy.min().item() >= 0.0 and noisy.max().item() <= 1.0
        assert _on_8bit_levels(noisy)
    assert not torch.equal(noisy, clean)


def test_float_output_is_continuous_when_rounding_is_off() -> None:
    clean = torch.rand((3, 20, 24), generator=torch.Generator().manual_seed(0))
    noisy = LowLight(_everything_profile(), seed=1, round_to_8bit=False)(clean)
    assert noisy.dtype == torch.float32
    assert not _on_8bit_levels(noisy)
    # Rounding is the only difference between the two modes: the same stream rounded gives the 8-bit output.
    rounded = LowLight(_everything_profile(), seed=1)(clean)
    assert torch.equal(rounded, (noisy.clamp(0, 1) * 255).round() / 255)


def test_darkening_alone_matches_the_darkening_function() -> None:
    clean = torch.rand((3, 16, 16), generator=torch.Generator().manual_seed(3))
    profile = build_profile(darkening=Darkening(alpha=0.2, gamma=0.5))
    noisy = LowLight(profile, seed=0, round_to_8bit=False)(clean)
    torch.testing.assert_close(noisy, darken(clean, 0.2, 0.5), rtol=0, atol=1e-6)
    # darkening= overrides the profile's; None adds noise only (here: nothing at all).
    fixed = LowLight(profile, seed=0, darkening=Darkening(alpha=0.1, gamma=1.0), round_to_8bit=False)(clean)
    torch.testing.assert_close(fixed, 0.1 * clean, rtol=0, atol=1e-6)
    assert torch.equal(LowLight(profile, seed=0, darkening=None, round_to_8bit=False)(clean), clean)


# --- the noise follows the profile ----------------------------------------------------------------------------


@pytest.mark.parametrize("round_to_8bit", [False, True])
def test_flat_image_noise_variance_follows_the_shot_and_read_law(round_to_8bit: bool) -> None:
    x, shot, read = 0.3, 0.05, 0.01
    profile = build_profile(shot=shot, read=read)
    noisy = LowLight(profile, seed=11, darkening=None, round_to_8bit=round_to_8bit)(_flat(x, (3, 96, 96)))
    expected = shot**2 * x + read**2
    if round_to_8bit:
        # Rounding to levels of width 1/255 adds their uniform variance (Sheppard); the std is 7 levels here.
        expected += LEVEL**2 / 12.0
    values = noisy.double().flatten()
    n = values.numel()
    variance = values.var().item()
    # Standard error of a Gaussian sample variance: sigma^2 sqrt(2 / (n - 1)); 4 of them.
    assert abs(variance - expected) < 4.0 * expected * math.sqrt(2.0 / (n - 1))
    assert abs(values.mean().item() - x) < 4.0 * math.sqrt(expected / n)


def test_parameters_are_drawn_within_the_profile_ranges() -> None:
    ranges = {"shot": [(0.02, 0.08)], "read": [(0.001, 0.02)], "alpha": [(0.1, 0.3)], "gamma": [(0.4, 0.9)]}
    transform = LowLight(build_profile(shot=0.05, read=0.01, ranges=ranges), seed=5)
    drawn: dict[str, list[float]] = {"shot": [], "read": [], "alpha": [], "gamma": []}
    for _ in range(40):
        parameters = transform.sample(_flat(0.5, (3, 4, 4))).parameters
        assert isinstance(parameters, dict)
        drawn["shot"].append(parameters["noise"]["shot"])
        drawn["read"].append(parameters["noise"]["read"])
        drawn["alpha"].append(parameters["darkening"]["alpha"])
        drawn["gamma"].append(parameters["darkening"]["gamma"])
    for name, values in drawn.items():
        low, high = ranges[name][0]
        assert all(low <= v <= high for v in values), name
        # Uniform draws: 40 of them cover most of the interval (P(spread < half) is about 1e-10).
        assert max(values) - min(values) > 0.5 * (high - low), name


def test_a_clip_shares_one_draw_and_its_temporal_banding() -> None:
    profile = build_profile(temporal_banding=0.02, ranges={"temporal_banding": [(0.01, 0.03)]})
    for clean in (_flat(0.5, (4, 3, 8, 64)), torch.full((4, 3, 8, 64), 128, dtype=torch.uint8)):
        result = LowLight(profile, seed=2, darkening=None).sample(clean)
        noisy = result.image
        assert isinstance(noisy, torch.Tensor)
        assert isinstance(result.parameters, dict)  # one record: one draw for the whole clip
        for frame in noisy[1:]:
            assert torch.equal(frame, noisy[0])
        # The pattern is real: constant down each column, varying across columns.
        assert torch.equal(noisy, noisy[:, :, :1, :].expand_as(noisy))
        assert noisy[0, :, 0, :].double().std().item() > 2 * LEVEL * (255 if clean.dtype == torch.uint8 else 1)
    # Per-frame banding, by contrast, is redrawn in every frame.
    per_frame = LowLight(build_profile(banding=0.02), seed=2, darkening=None)(_flat(0.5, (2, 3, 8, 64)))
    assert not torch.equal(per_frame[0], per_frame[1])


# --- seeding ---------------------------------------------------------------------------------------------------


def test_calls_differ_and_the_same_seed_repeats_the_stream() -> None:
    clean = _flat(0.5, (3, 16, 16))
    first, second = LowLight(_everything_profile(), seed=7), LowLight(_everything_profile(), seed=7)
    a1, a2 = first(clean), first(clean)
    assert not torch.equal(a1, a2)
    assert torch.equal(second(clean), a1)
    assert torch.equal(second(clean), a2)
    assert not torch.equal(LowLight(_everything_profile(), seed=8)(clean), a1)


def test_per_sample_seed_depends_on_the_sample_seed_and_the_transform_seed_only() -> None:
    clean = _flat(0.5, (3, 16, 16))
    transform = LowLight(_everything_profile(), seed=7)
    first = transform(clean, seed=3)
    transform(clean)  # advancing the stream changes nothing for seeded calls
    assert torch.equal(transform(clean, seed=3), first)
    assert torch.equal(LowLight(_everything_profile(), seed=7)(clean, seed=3), first)
    assert not torch.equal(transform(clean, seed=4), first)
    assert not torch.equal(LowLight(_everything_profile(), seed=9)(clean, seed=3), first)


def test_without_a_seed_torch_manual_seed_fixes_the_stream() -> None:
    clean = _flat(0.5, (3, 16, 16))
    torch.manual_seed(123)
    a = LowLight(_everything_profile())(clean)
    torch.manual_seed(123)
    b = LowLight(_everything_profile())(clean)
    torch.manual_seed(124)
    c = LowLight(_everything_profile())(clean)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)


def test_pickling_drops_the_generator_so_a_spawned_worker_starts_its_own() -> None:
    transform = LowLight(_everything_profile(), seed=7)
    clean = _flat(0.5, (3, 16, 16))
    first = transform(clean)
    copy = pickle.loads(pickle.dumps(transform))
    # The copy restarts from the seed instead of continuing the parent's stream.
    assert torch.equal(copy(clean), first)


class _SameImageDataset(torch.utils.data.Dataset[tuple[torch.Tensor, int, int]]):
    """Eight copies of one flat image; each item is (noisy, worker id, index)."""

    def __init__(self, transform: LowLight, *, per_sample: bool = False) -> None:
        self.transform = transform
        self.per_sample = per_sample
        self.clean = _flat(0.4, (3, 12, 12))

    def __len__(self) -> int:
        return 8

    def __getitem__(self, index: int) -> tuple[torch.Tensor, int, int]:
        worker = torch.utils.data.get_worker_info()
        noisy = self.transform(self.clean, seed=index if self.per_sample else None)
        return noisy, -1 if worker is None else worker.id, index


def _run_loader(dataset: _SameImageDataset, seed: int, epochs: int = 1) -> list[list[tuple[torch.Tensor, int, int]]]:
    torch.manual_seed(seed)
    loader = torch.utils.data.DataLoader(dataset, batch_size=None, num_workers=2)
    return [list(loader) for _ in range(epochs)]


def test_dataloader_workers_add_different_reproducible_noise() -> None:
    transform = LowLight(_everything_profile(), seed=None)
    dataset = _SameImageDataset(transform)
    # A generator made in the main process before the workers fork must not be inherited by them.
    transform(dataset.clean)
    first, second = _run_loader(dataset, seed=0, epochs=2)
    by_worker = {worker: noisy for noisy, worker, index in first if index in (0, 1)}
    assert set(by_worker) == {0, 1}
    assert not torch.equal(by_worker[0], by_worker[1])
    outputs = [noisy for noisy, _, _ in first]
    assert all(not torch.equal(a, b) for i, a in enumerate(outputs) for b in outputs[i + 1 :])
    # A new epoch gets new worker seeds, hence new noise.
    assert not any(torch.equal(a, b) for (a, _, _), (b, _, _) in zip(first, second, strict=True))
    # The same torch seed repeats the run exactly; another one does not.
    (again,) = _run_loader(dataset, seed=0)
    assert all(torch.equal(a, b) for (a, _, _), (b, _, _) in zip(first, again, strict=True))
    (other,) = _run_loader(dataset, seed=1)
    assert not any(torch.equal(a, b) for (a, _, _), (b, _, _) in zip(first, other, strict=True))


def test_dataloader_with_a_user_seed_and_per_sample_seeds() -> None:
    seeded = _SameImageDataset(LowLight(_everything_profile(), seed=3))
    (a,) = _run_loader(seeded, seed=0)
    (b,) = _run_loader(seeded, seed=0)
    assert all(torch.equal(x, y) for (x, _, _), (y, _, _) in zip(a, b, strict=True))
    assert not torch.equal(a[0][0], a[1][0])  # items 0 and 1 come from workers 0 and 1
    # Per-sample seeds: the same noisy item whatever the worker, the epoch or the torch seed.
    per_sample = _SameImageDataset(LowLight(_everything_profile(), seed=3), per_sample=True)
    (c,) = _run_loader(per_sample, seed=5)
    for noisy, _, index in c:
        assert torch.equal(noisy, per_sample[index][0])


# --- bad input ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (torch.rand(16, 16), r"\(C, H, W\) image or a \(T, C, H, W\) clip, got shape \(16, 16\)"),
        (torch.rand(2, 2, 3, 8, 8), r"got shape \(2, 2, 3, 8, 8\)"),
        (torch.rand(2, 8, 8), r"1 \(grey\) or 3 \(RGB\) channels"),
        (torch.rand(4, 8, 8), r"drop an alpha channel"),
        (torch.rand(8, 8, 3), r"permute \(H, W, C\)"),
        (torch.rand(3, 8, 8) * 4 - 2, r"values must lie in \[0, 1\].*before normalising"),
        (torch.rand(3, 8, 8) * 255, r"divide 0-255 floats by 255"),
        (torch.full((3, 8, 8), float("nan")), r"values must lie in \[0, 1\]"),
        (torch.zeros(3, 8, 8, dtype=torch.int16), r"unsupported pixel type torch.int16"),
        (torch.zeros(3, 0, 8), r"empty image"),
        (np.zeros((3, 8, 8), dtype=np.float32), r"takes a torch tensor"),
    ],
)
def test_bad_input_is_refused_with_a_clear_message(image: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        LowLight(_everything_profile(), seed=0)(image)  # type: ignore[arg-type]


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="seed must be an integer"):
        LowLight(_everything_profile(), seed=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="darkening must be"):
        LowLight(_everything_profile(), darkening="bright")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="seed must be an integer"):
        LowLight(_everything_profile())(_flat(0.5, (3, 4, 4)), seed=True)


def test_a_camera_is_drawn_per_sample_and_shown_with_its_values() -> None:
    transform = LowLight(_everything_profile(), seed=3, camera="dslr-jpeg")
    clean = _flat(0.5, (3, 16, 16))
    first, again = transform.sample(clean, seed=1), transform.sample(clean, seed=1)
    assert isinstance(first.image, torch.Tensor) and isinstance(again.image, torch.Tensor)
    assert torch.equal(first.image, again.image)
    assert isinstance(first.parameters, dict) and isinstance(again.parameters, dict)
    assert first.parameters == again.parameters
    assert first.parameters["camera"] == {"source": "dslr-jpeg", "given_profile": False}
    # The camera replaces the profile's shot and read noise; its darkening and columns stay.
    assert first.parameters["noise"]["shot"] == 0.0 and min(first.parameters["noise"]["level_curve"]) > 0.0
    assert first.parameters["noise"]["banding"] == 0.004
    assert first.parameters["darkening"] == {"alpha": 0.3, "gamma": 0.7}
    other = transform.sample(clean, seed=2).parameters
    assert isinstance(other, dict) and other["noise"]["level_curve"] != first.parameters["noise"]["level_curve"]
    with pytest.raises(ValueError, match="camera must be None or one of prior, phone, dslr, dslr-jpeg, got 'sony'"):
        LowLight(_everything_profile(), camera="sony")


def test_slight_resampling_overshoot_is_accepted_and_clipped() -> None:
    clean = torch.tensor([-0.05, 0.5, 1.05]).view(1, 1, 3)
    noisy = LowLight(build_profile(), seed=0, darkening=None)(clean)
    assert torch.equal(noisy, torch.tensor([0.0, 128 / 255, 1.0]).view(1, 1, 3))


def test_importing_the_package_does_not_need_albumentations(monkeypatch: pytest.MonkeyPatch) -> None:
    # A fresh import of darksynth.transforms with albumentations made unimportable (None in sys.modules);
    # monkeypatch puts the original modules back afterwards.
    monkeypatch.setattr(darksynth, "transforms", sys.modules["darksynth.transforms"])
    for name in [name for name in sys.modules if name.split(".")[0] == "albumentations"] + ["albumentations"]:
        monkeypatch.setitem(sys.modules, name, None)
    for name in ("darksynth.transforms", "darksynth.transforms.low_light", "darksynth.transforms._albumentations"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    transforms = importlib.import_module("darksynth.transforms")
    assert transforms.LowLight(_everything_profile(), seed=0)(_flat(0.5, (3, 8, 8))).shape == (3, 8, 8)
    with pytest.raises(ImportError, match=r"needs albumentations 2\.x"):
        transforms.AlbumentationsLowLight  # noqa: B018
