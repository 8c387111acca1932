"""Shared helpers for the core tests: profiles built from keyword arguments."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import pytest

from darksynth.darkening import Darkening
from darksynth.noise.components import NOISE_PARAMETERS
from darksynth.profile import Profile, validate_profile

ProfileFactory = Callable[..., Profile]


def build_profile(
    darkening: Darkening | None = None,
    ranges: Mapping[str, Sequence[tuple[float, float]]] | None = None,
    **noise: float | Sequence[float],
) -> Profile:
    """A validated profile whose unnamed noise parameters are neutral (zero, or one for a gain)."""
    values: dict[str, tuple[float, ...]] = {}
    for parameter in NOISE_PARAMETERS:
        neutral = parameter.neutral
        raw: Any = noise.pop(parameter.name, [neutral] * parameter.size if parameter.size > 1 else neutral)
        values[parameter.name] = tuple(float(v) for v in raw) if parameter.size > 1 else (float(raw),)
    if noise:
        raise TypeError(f"unknown noise parameters {sorted(noise)}")
    profile = Profile(
        noise=values,
        darkening=darkening,
        ranges={name: tuple(pairs) for name, pairs in (ranges or {}).items()},
    )
    return validate_profile(profile)


@pytest.fixture
def make_profile() -> ProfileFactory:
    return build_profile
