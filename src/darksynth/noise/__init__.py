"""The physical noise model f(v): one module per component, pure functions with an explicit generator; the
table that declares them (:mod:`~darksynth.noise.components`), the carrier of their values
(:class:`NoiseValues`) and the one composer (:func:`add_noise`)."""

from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.components import (
    NOISE_COMPONENTS,
    NoiseComponent,
    Parameter,
    model_parameters,
    noise_components,
    noise_parameter_names,
    noise_parameters,
    vector_size,
)
from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_std
from darksynth.noise.periodic import periodic_basis, periodic_noise
from darksynth.noise.quantization import quantization_noise
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues

__all__ = [
    "NOISE_COMPONENTS",
    "NoiseComponent",
    "NoiseValues",
    "Parameter",
    "add_noise",
    "banding_noise",
    "heteroscedastic_noise",
    "heteroscedastic_std",
    "model_parameters",
    "noise_components",
    "noise_parameter_names",
    "noise_parameters",
    "periodic_basis",
    "periodic_noise",
    "quantization_noise",
    "temporal_banding_noise",
    "vector_size",
]
