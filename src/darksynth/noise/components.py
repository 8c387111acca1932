"""The noise components of f(v), declared as data.

Every quantity of the noise model lives in :data:`NOISE_COMPONENTS`: a component's parameters (name, number
of values, unit, valid bound, training range, the profile version it arrived in, the estimator statistics that
reveal it, the fast paths that can draw it) and the pure functions that draw it and give its term of the mean
noise variance. The profile schema, the carrier of values (:mod:`darksynth.noise.values`), the estimation
network's vector and statistics, the samplers, the composer and the fused kernel's choice all read this table
through the functions below (never a copy of it), so a new component is declared next to its functions in the
module of its noise model (:mod:`~darksynth.noise.paper_components`,
:mod:`~darksynth.noise.heteroscedastic_components`, :mod:`~darksynth.noise.spectral_components`,
:mod:`~darksynth.noise.compression`, with the records of :mod:`~darksynth.noise.component_types`), listed
here, and nowhere else; ``tests/noise/test_new_component.py`` declares one inside a test and runs it end to end.

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from darksynth.noise.codec_repeat import CODEC_REPEAT
from darksynth.noise.component_types import (
    LIGHT_STRUCTURES,
    DrawFunction,
    FastPath,
    NoiseComponent,
    NoiseModel,
    Parameter,
    Role,
    StreamDrawFunction,
    Structure,
    VarianceFunction,
    shapes_neutral,
)
from darksynth.noise.compression import COMPRESSION
from darksynth.noise.heteroscedastic_components import HETEROSCEDASTIC
from darksynth.noise.light_components import FLICKER, SCENE
from darksynth.noise.paper_components import BANDING, PERIODIC, QUANTIZATION, TEMPORAL_BANDING
from darksynth.noise.spectral_components import SPECTRAL

__all__ = [
    "LIGHT_STRUCTURES",
    "NOISE_COMPONENTS",
    "NOISE_MODELS",
    "DrawFunction",
    "FastPath",
    "NoiseComponent",
    "NoiseModel",
    "Parameter",
    "Role",
    "StreamDrawFunction",
    "Structure",
    "VarianceFunction",
    "light_parameters",
    "model_parameters",
    "noise_components",
    "noise_parameter",
    "noise_parameter_names",
    "noise_parameters",
    "profile_section",
    "profile_version",
    "shapes_neutral",
    "vector_size",
]

# The training ranges cover real sRGB low-light noise: at mid-grey (x = 0.5) shot 0.2 alone gives a std of
# 0.14 of full scale, and read noise adds up to 0.1 at black.
NOISE_COMPONENTS: tuple[NoiseComponent, ...] = (
    HETEROSCEDASTIC,
    SPECTRAL,
    QUANTIZATION,
    BANDING,
    TEMPORAL_BANDING,
    PERIODIC,
    COMPRESSION,
    SCENE,
    FLICKER,
    CODEC_REPEAT,
)
"""The table. Read it through the functions below, which look it up at each call, so that a component
listed here (or, in a test, added to it) is seen everywhere."""

NOISE_MODELS: tuple[NoiseModel, ...] = ("paper", "srgb", "spectral")


def noise_components() -> tuple[NoiseComponent, ...]:
    """Every component, in table order."""
    return NOISE_COMPONENTS


def noise_parameters() -> tuple[Parameter, ...]:
    """Every parameter, in table order: the full v of the ``spectral`` model."""
    return tuple(p for c in NOISE_COMPONENTS for p in c.parameters)


def noise_parameter_names() -> tuple[str, ...]:
    return tuple(p.name for p in noise_parameters())


def model_parameters(noise_model: NoiseModel = "srgb", version: int | None = None) -> tuple[Parameter, ...]:
    """The noise parameters of one noise model (light's are no model's), in table order: ``paper`` is shot, read,
    quantization, banding, temporal_banding, periodic (3), the paper's v of 8 values; ``srgb`` is every parameter.

    ``version``: only the parameters that had arrived by that table (profile) version, as an estimator trained
    then predicts them (None: the table as it is now)."""
    if noise_model not in NOISE_MODELS:
        raise ValueError(f"unknown noise model {noise_model!r}; known: {', '.join(NOISE_MODELS)}")
    last = NOISE_MODELS.index(noise_model)
    return tuple(
        p
        for c in NOISE_COMPONENTS
        if c.structure not in LIGHT_STRUCTURES
        for p in c.parameters
        if NOISE_MODELS.index(p.noise_model) <= last and (version is None or p.since_version <= version)
    )


def vector_size(noise_model: NoiseModel = "srgb", version: int | None = None) -> int:
    """Length of the flat v of one noise model (8 for ``paper``), at a table version (None: now)."""
    return sum(p.size for p in model_parameters(noise_model, version))


def noise_component(name: str) -> NoiseComponent:
    """The component called ``name``; raises KeyError naming the known ones."""
    for component in NOISE_COMPONENTS:
        if component.name == name:
            return component
    raise KeyError(f"unknown noise component {name!r}; known: {', '.join(c.name for c in NOISE_COMPONENTS)}")


def noise_parameter(name: str) -> Parameter:
    """The parameter called ``name``; raises KeyError naming the known ones."""
    for parameter in noise_parameters():
        if parameter.name == name:
            return parameter
    raise KeyError(f"unknown noise parameter {name!r}; known: {', '.join(noise_parameter_names())}")


def light_parameters() -> tuple[Parameter, ...]:
    """The parameters of light (motion blur, shake, flicker): the profile's ``light`` section."""
    return tuple(p for c in NOISE_COMPONENTS if c.structure in LIGHT_STRUCTURES for p in c.parameters)


def profile_section(parameter: Parameter) -> str:
    """Where a parameter is written in a profile or a manifest record: ``noise`` or ``light``."""
    return "light" if parameter in light_parameters() else "noise"


def profile_version() -> int:
    """The version profiles are written with: the newest a parameter of the table arrived in."""
    return max(p.since_version for p in noise_parameters())
