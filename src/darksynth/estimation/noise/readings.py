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
from darksynth.noise.texture import texture_modulation

Reading = Callable[[FittedReference, Mapping[str, torch.Tensor]], MeasuredValues]


TEXTURE_RISE_WARNING = 2.0
"""The texture dependence's factor on the noise std over the reference (:func:`texture_rise` of its denoised analysis
window) above which the estimate warns: on 15 of polyu's JPEG photos (every 7th) 1.0-1.6 but for one (3.0, over the
whole image); on the round-trip case of a wholly textured McMaster image with JPEG and no texture dependence
(seed 3099) 2.8, where the level read 2.6x the truth."""


def texture_rise(denoised: torch.Tensor, gain: float, scale: float) -> float:
    """The factor a texture dependence (``gain``, ``scale``) puts on the noise std over a scene ``denoised``
    (T, 3, H, W): the RMS of :func:`~darksynth.noise.texture.texture_modulation` over its pixels."""
    return float(texture_modulation(denoised, gain, scale).square().mean().sqrt())


def prior_texture(reference: FittedReference, values: Mapping[str, torch.Tensor]) -> MeasuredValues:
    """The noise's dependence on texture (``texture_gain``, ``texture_scale``), which no reference shows, as the
    camera prior expects it given what was measured (:func:`~darksynth.estimation.noise.camera_conditional.
    expected_texture`); nothing without a camera prior. Where it would raise the noise over the reference's own
    scene by more than :data:`TEXTURE_RISE_WARNING`, a warning says the level is then uncertain."""
    if reference.camera_prior is None:
        return MeasuredValues()
    texture = expected_texture(values, reference.camera_prior.prior)
    found = MeasuredValues(texture)
    if not texture:
        return found
    gain = float(texture["texture_gain"].reshape(-1)[0])
    scale = float(texture["texture_scale"].reshape(-1)[0])
    if gain > 0.0 and scale > 0.0:
        rise = texture_rise(reference.resynthesis.denoised[:1], gain, scale)
        found.findings.meta["texture_rise"] = round(rise, 3)
        if rise > TEXTURE_RISE_WARNING:
            found.findings.warnings.append(
                f"{reference.name}: the texture dependence taken from the camera prior raises the noise {rise:.1f}x "
                "over this scene (it is mostly texture): the profile's level on it is uncertain by that much"
            )
    return found


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
