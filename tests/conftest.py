"""Fixtures for tests in several folders: one torch thread, tiny DENs, profiles, CLI inputs."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from darksynth.light.darkening import Darkening
from darksynth.models.den import DEN, DENConfig
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, default_profile_path, validate_profile


@pytest.fixture
def profile_file(tmp_path: Path) -> Path:
    return default_profile_path()


@pytest.fixture
def write_profile(tmp_path: Path) -> Callable[..., Path]:
    """Write a variant of the default profile: noise values replaced, other fields changed or removed."""

    def write(name: str = "profile.json", noise: dict[str, object] | None = None, **fields: object) -> Path:
        document = json.loads(default_profile_path().read_text())
        document["noise"].update(noise or {})
        for key, value in fields.items():
            if value is None:
                document.pop(key, None)
            else:
                document[key] = value
        path = tmp_path / name
        path.write_text(json.dumps(document))
        return path

    return write


@pytest.fixture
def rgb_image(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    pixels = rng.integers(0, 256, (40, 56, 3), dtype=np.uint8)
    path = tmp_path / "in" / "photo.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path)
    return path


ProfileFactory = Callable[..., Profile]


def build_profile(
    darkening: Darkening | None = None,
    ranges: Mapping[str, Sequence[tuple[float, float]]] | None = None,
    **noise: float | Sequence[float],
) -> Profile:
    """A validated profile whose unnamed noise parameters are neutral (zero, or one for a gain)."""
    profile = Profile(
        noise=NoiseValues.from_values(noise),
        darkening=darkening,
        ranges={name: tuple(pairs) for name, pairs in (ranges or {}).items()},
    )
    return validate_profile(profile)


def measured_profile() -> Profile:
    """A profile as ``estimate`` writes one: a spectral level curve and octaves, JPEG, columns and a temporal
    correlation, with ranges on the darkening."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64)
    curve = torch.stack([0.01 + 0.03 * knots, 0.012 + 0.02 * knots, 0.015 + 0.035 * knots]).reshape(-1)
    power = torch.linspace(0.5, 6.0, OCTAVES * 3, dtype=torch.float64)
    correlation = torch.linspace(-0.2, 0.25, OCTAVES * 3, dtype=torch.float64)
    return build_profile(
        darkening=Darkening(0.2, 0.7),
        ranges={"alpha": [(0.1, 0.3)], "gamma": [(0.5, 0.9)]},
        level_curve=curve.tolist(),
        octave_power=power.tolist(),
        octave_correlation=correlation.tolist(),
        temporal_correlation=[0.3] * OCTAVES,
        compression=0.3,
        banding=0.004,
        periodic=[0.001, 0.002, 0.003],
        quantization=0.004,
    )


@pytest.fixture
def make_profile() -> ProfileFactory:
    return build_profile


TINY = DENConfig(width=4, depth=1)


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread() -> Iterator[None]:
    """Run the tiny networks on one thread: on a busy CPU, two threads make a 4-step run ~30x slower."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def tiny_model() -> Callable[..., DEN]:
    """A freshly initialised, seeded DEN of ``width=4, depth=1`` (or other settings) in eval mode."""

    def make(seed: int = 0, **settings: object) -> DEN:
        torch.manual_seed(seed)
        config = DENConfig(**{**TINY.to_dict(), **settings})  # type: ignore[arg-type]
        return DEN(config).eval()

    return make
