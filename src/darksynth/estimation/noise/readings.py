"""The readings the blind measurement makes once the spectrum is fitted: one line each in :data:`AFTER_FIT`.

A reading is a function of the analysed reference with its fit (:class:`~darksynth.estimation.noise.resynthesis.
FittedReference`) and the table's values found so far; it returns the parameters it sets, by name, and its findings
(:class:`~darksynth.estimation.noise.resynthesis.MeasuredValues`). The measurement runs them in order and the profile
takes their values by name, so a new measured parameter is its reading's module, its line here and, for a parameter
the table does not have yet, its ``Parameter`` in its component's module (docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import torch

from darksynth.estimation.noise.camera_conditional import expected_texture
from darksynth.estimation.noise.persistence_fit import read_persistence
from darksynth.estimation.noise.resynthesis import FittedReference, MeasuredValues

Reading = Callable[[FittedReference, Mapping[str, torch.Tensor]], MeasuredValues]


def prior_texture(reference: FittedReference, values: Mapping[str, torch.Tensor]) -> MeasuredValues:
    """The noise's dependence on texture (``texture_gain``, ``texture_scale``), which no reference shows, as the
    camera prior expects it given what was measured (:func:`~darksynth.estimation.noise.camera_conditional.
    expected_texture`); nothing without a camera prior."""
    if reference.camera_prior is None:
        return MeasuredValues()
    return MeasuredValues(expected_texture(values, reference.camera_prior.prior))


AFTER_FIT: tuple[Reading, ...] = (read_persistence, prior_texture)
"""The readings after the fit, in the order they run (each is given the values of those before it)."""


def read_after_fit(reference: FittedReference) -> MeasuredValues:
    """The table's values of the fit (its spectrum and the JPEG strength it chose) with those every reading of
    :data:`AFTER_FIT` sets, and the readings' findings."""
    compression = torch.tensor([reference.compression], dtype=torch.float64)
    found = MeasuredValues(reference.fitted.as_values() | {"compression": compression})
    for reading in AFTER_FIT:
        measured = reading(reference, found.values)
        found.values |= measured.values
        found.findings.include(measured.findings)
    return found
