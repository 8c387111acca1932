"""Shared helpers for the core tests: profiles built from keyword arguments."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import pytest

from darksynth.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, validate_profile

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


@pytest.fixture
def make_profile() -> ProfileFactory:
    return build_profile
