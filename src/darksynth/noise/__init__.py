"""The physical noise model f(v): one module per component, pure functions with an explicit generator."""

from darksynth.noise.banding import banding_noise, temporal_banding_noise
from darksynth.noise.components import (
    NOISE_COMPONENTS,
    NOISE_PARAMETER_NAMES,
    NOISE_PARAMETERS,
    NOISE_VECTOR_SIZE,
    NoiseComponent,
    Parameter,
    values_to_vector,
    vector_to_values,
)
from darksynth.noise.heteroscedastic import heteroscedastic_noise, heteroscedastic_std
from darksynth.noise.periodic import periodic_basis, periodic_noise
from darksynth.noise.quantization import quantization_noise

__all__ = [
    "NOISE_COMPONENTS",
    "NOISE_PARAMETERS",
    "NOISE_PARAMETER_NAMES",
    "NOISE_VECTOR_SIZE",
    "NoiseComponent",
    "Parameter",
    "banding_noise",
    "heteroscedastic_noise",
    "heteroscedastic_std",
    "periodic_basis",
    "periodic_noise",
    "quantization_noise",
    "temporal_banding_noise",
    "values_to_vector",
    "vector_to_values",
]
