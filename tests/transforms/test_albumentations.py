"""darksynth.transforms._albumentations: AlbumentationsLowLight in albumentations pipelines, and the package
without albumentations."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import torch
import torch.utils.data

from darksynth.light.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.recipe import ClipParameters, ClipRecipe
from darksynth.transforms.low_light import low_light, mix_seed
from tests.conftest import build_profile
from tests.transforms.test_low_light import _everything_profile

A = pytest.importorskip("albumentations")


def _albumentations_transform(p: float = 1.0, profile: Profile | None = None, **kwargs: object) -> object:
    from darksynth.transforms import AlbumentationsLowLight

    return AlbumentationsLowLight(profile or _everything_profile(), p=p, **kwargs)


def _image(dtype: type, shape: tuple[int, ...] = (20, 24, 3)) -> np.ndarray:
    values = np.random.default_rng(0).random(shape)
    return (values * 255).round().astype(np.uint8) if dtype == np.uint8 else values.astype(dtype)


@pytest.mark.parametrize(
    ("dtype", "shape"),
    [(np.uint8, (20, 24, 3)), (np.float32, (20, 24, 3)), (np.uint8, (20, 24)), (np.float32, (20, 24, 1))],
)
def test_albumentations_compose_with_a_seed_is_reproducible(dtype: type, shape: tuple[int, ...]) -> None:
    image = _image(dtype, shape)
    first = A.Compose([_albumentations_transform()], seed=17)
    second = A.Compose([_albumentations_transform()], seed=17)
    a1, a2 = first(image=image)["image"], first(image=image)["image"]
    assert a1.shape == image.shape and a1.dtype == image.dtype
    assert not np.array_equal(a1, a2)
    assert np.array_equal(second(image=image)["image"], a1)
    assert np.array_equal(second(image=image)["image"], a2)
    assert not np.array_equal(A.Compose([_albumentations_transform()], seed=18)(image=image)["image"], a1)
    if dtype == np.float32:
        assert a1.min() >= 0.0 and a1.max() <= 1.0
        assert np.abs(a1 * 255 - np.round(a1 * 255)).max() < 1e-3


def test_albumentations_transform_is_the_torch_transform_with_the_parameters_it_drew() -> None:
    image = _image(np.float32)
    transform = _albumentations_transform()
    params = transform.get_params_dependent_on_data(params={"seed": 42}, data={"image": image})  # type: ignore[attr-defined]
    parameters = ClipParameters(
        noise=NoiseValues.from_json({**params["noise"], **params["light"]}),
        darkening=Darkening(alpha=params["alpha"], gamma=params["gamma"]),
    )
    expected = low_light(
        torch.from_numpy(image).permute(2, 0, 1),
        ClipRecipe(_everything_profile()),
        generator=torch.Generator().manual_seed(mix_seed("noise", 42)),
        parameters=parameters,
    ).image
    assert isinstance(expected, torch.Tensor)
    assert np.array_equal(transform.apply(image, **params), expected.permute(1, 2, 0).numpy())  # type: ignore[attr-defined]


def test_albumentations_respects_p() -> None:
    image = _image(np.uint8, (4, 4, 3))
    assert np.array_equal(A.Compose([_albumentations_transform(p=0.0)], seed=1)(image=image)["image"], image)
    pipeline = A.Compose([_albumentations_transform(p=0.3, profile=build_profile(read=0.05))], seed=1)
    applied = sum(not np.array_equal(pipeline(image=image)["image"], image) for _ in range(300))
    # Binomial(300, 0.3): mean 90, std 7.9; 4 standard deviations.
    assert abs(applied - 90) < 4 * math.sqrt(300 * 0.3 * 0.7)
    with pytest.raises(ValueError, match="p must be a probability"):
        _albumentations_transform(p=1.5)


def test_albumentations_images_are_one_clip() -> None:
    from darksynth.transforms import AlbumentationsLowLight

    profile = build_profile(temporal_banding=0.02)
    frames = np.full((3, 8, 64, 3), 128, dtype=np.uint8)
    pipeline = A.Compose([AlbumentationsLowLight(profile, darkening=None, p=1.0)], seed=4)
    noisy = pipeline(images=frames)["images"]
    assert noisy.shape == frames.shape and noisy.dtype == np.uint8
    assert np.array_equal(noisy[0], noisy[1]) and np.array_equal(noisy[0], noisy[2])
    assert noisy[0, 0, :, 0].std() > 2.0


def test_albumentations_serialisation_and_replay() -> None:
    image = _image(np.uint8)
    pipeline = A.Compose([_albumentations_transform(darkening=Darkening(alpha=0.2, gamma=0.8))], seed=3)
    rebuilt = A.from_dict(A.to_dict(pipeline))
    rebuilt.set_random_seed(3)
    assert np.array_equal(rebuilt(image=image)["image"], pipeline(image=image)["image"])
    replay = A.ReplayCompose([_albumentations_transform()])
    replay.set_random_seed(2)
    recorded = replay(image=image)
    again = A.ReplayCompose.replay(recorded["replay"], image=image)
    assert np.array_equal(again["image"], recorded["image"])


RANGED = build_profile(
    shot=0.02, read=0.01, ranges={"alpha": [(0.1, 0.3)], "gamma": [(0.5, 0.9)], "read": [(0.005, 0.02)]}
)
"""A profile whose alpha, gamma and read noise are drawn for each call."""


def test_a_replay_shows_the_drawn_parameters_and_applies_exactly_those() -> None:
    image = _image(np.uint8, (32, 40, 3))
    replay = A.ReplayCompose([_albumentations_transform(profile=RANGED)])
    replay.set_random_seed(5)
    recorded = replay(image=image)
    shown = recorded["replay"]["transforms"][0]["params"]
    assert 0.1 <= shown["alpha"] <= 0.3 and 0.5 <= shown["gamma"] <= 0.9
    assert 0.005 <= shown["noise"]["read"] <= 0.02 and shown["noise"]["shot"] == pytest.approx(0.02)
    assert set(shown["light"]) >= {"exposure_fraction", "flicker"}
    assert np.array_equal(A.ReplayCompose.replay(recorded["replay"], image=image)["image"], recorded["image"])
    # The replay applies what it shows: a brighter alpha written into it brightens the output.
    edited = copy.deepcopy(recorded["replay"])
    edited["transforms"][0]["params"]["alpha"] = 1.0
    brighter = A.ReplayCompose.replay(edited, image=image)["image"]
    assert brighter.mean() > 2 * recorded["image"].mean()


def test_a_replay_shows_the_drawn_camera_and_applies_it() -> None:
    image = _image(np.uint8, (32, 40, 3))
    replay = A.ReplayCompose([_albumentations_transform(profile=RANGED, camera="phone")])
    replay.set_random_seed(5)
    recorded, second = replay(image=image), replay(image=image)
    shown = recorded["replay"]["transforms"][0]["params"]
    assert shown["camera"] == {"source": "phone", "given_profile": False}
    assert shown["noise"]["shot"] == 0.0 and min(shown["noise"]["level_curve"]) > 0.0
    assert second["replay"]["transforms"][0]["params"]["noise"]["level_curve"] != shown["noise"]["level_curve"]
    assert np.array_equal(A.ReplayCompose.replay(recorded["replay"], image=image)["image"], recorded["image"])
    # The replay applies the camera it shows: without its level curve no noise is left (the camera replaced the
    # profile's shot and read noise), with twice the curve about twice the noise (less where black clips it: the
    # darkened image has many pixels within a few levels of 0).
    replayed = {}
    for factor in (0, 2):
        edited = copy.deepcopy(recorded["replay"])
        edited["transforms"][0]["params"]["noise"]["level_curve"] = [factor * v for v in shown["noise"]["level_curve"]]
        replayed[factor] = A.ReplayCompose.replay(edited, image=image)["image"].astype(float)
    noise = (recorded["image"] - replayed[0]).std()
    assert noise > 1.0
    assert 1.5 < (replayed[2] - replayed[0]).std() / noise < 2.1
    rebuilt = A.from_dict(A.to_dict(replay))
    assert rebuilt.transforms[0].camera == "phone"
    with pytest.raises(ValueError, match="camera must be None or one of"):
        _albumentations_transform(camera="canon")


def test_the_drawn_parameters_are_uniform_within_the_profiles_ranges() -> None:
    transform = _albumentations_transform(profile=RANGED)
    image = _image(np.uint8, (16, 16, 3))
    draws = [
        transform.get_params_dependent_on_data(params={"seed": seed}, data={"image": image})  # type: ignore[attr-defined]
        for seed in range(400)
    ]
    alphas = np.array([d["alpha"] for d in draws])
    reads = np.array([d["noise"]["read"] for d in draws])
    assert alphas.min() >= 0.1 and alphas.max() <= 0.3 and reads.min() >= 0.005 and reads.max() <= 0.02
    # U(0.1, 0.3) over 400 draws: mean 0.2, standard error 0.2 / sqrt(12 * 400) = 0.0029; 4 of them.
    assert abs(alphas.mean() - 0.2) < 4 * 0.2 / math.sqrt(12 * 400)
    assert np.corrcoef(alphas, reads)[0, 1] ** 2 < 0.05


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.zeros((8, 8, 4), dtype=np.uint8), r"1 \(grey\) or 3 \(RGB\) channels"),
        (np.zeros((8, 8, 3), dtype=np.int32), r"unsupported dtype int32"),
        (np.full((8, 8, 3), 200.0, dtype=np.float32), r"divide 0-255 floats by 255"),
    ],
)
def test_albumentations_bad_input_is_refused(image: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        A.Compose([_albumentations_transform()], seed=0)(image=image)


class _AlbumentationsDataset(torch.utils.data.Dataset[np.ndarray]):
    def __init__(self) -> None:
        self.pipeline = A.Compose([_albumentations_transform()], seed=9)
        self.image = _image(np.uint8, (8, 8, 3))

    def __len__(self) -> int:
        return 4

    def __getitem__(self, index: int) -> np.ndarray:
        return np.asarray(self.pipeline(image=self.image)["image"])


def test_albumentations_in_dataloader_workers_differs_per_worker_and_repeats() -> None:
    def run() -> list[np.ndarray]:
        torch.manual_seed(0)
        loader = torch.utils.data.DataLoader(_AlbumentationsDataset(), batch_size=None, num_workers=2)
        return [np.asarray(item) for item in loader]

    first, again = run(), run()
    # Items 0 and 1 are the first draws of workers 0 and 1, from identical albumentations states.
    assert not np.array_equal(first[0], first[1])
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
