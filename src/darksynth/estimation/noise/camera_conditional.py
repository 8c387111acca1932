"""What one reference cannot show, taken from the prior over real cameras (:mod:`darksynth.cameras.prior`): the
coarse octaves and the noise's dependence on texture, given what the blind measurement read (the level curve and
the finer octaves' powers and correlations).

One reference cannot tell a coarse colour blotch of the noise from the scene, nor a noise that in-camera denoising
flattened on flat regions from one that is flat everywhere: the blind estimate reads flat blocks, octave by octave,
and the coarse octaves' statistics hold mostly the scene. The prior's conditional mean replaces them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import torch

from darksynth.cameras.prior import CameraPrior, measured_entries, on_measured_scale
from darksynth.estimation.noise.spectral_fit import SpectralParameters
from darksynth.noise.spectral import OCTAVES, covariance_parameters, octave_covariances

TEXTURE_NAMES = ("texture_gain", "texture_scale")


@dataclass(frozen=True)
class CameraPriorUse:
    """What the blind estimate takes from a camera prior.

    Attributes:
        prior: the prior over real cameras.
        octaves: also the coarse octaves the reference cannot show (its conditional mean given the level curve and
            the finer octaves), in place of the finer octaves' continuation. The texture dependence, which no
            reference shows, is always taken. Neither is on by default: leave-one-set-out on the real pairs the
            conditional put both further from the real than the estimate without them (docs/camera-prior.md).
    """

    prior: CameraPrior
    octaves: bool = False


def prior_first_octave(first_unmeasured: int) -> int:
    """The finest octave the prior supplies: the first the reference's probe found it cannot show
    (:func:`~darksynth.estimation.noise.spectrum.octave_responses`); :data:`~darksynth.noise.spectral.OCTAVES` when it
    shows them all. What a reference shows is read, not replaced: a smooth reference shows its coarse noise (white
    noise there read 22 % too loud when the prior's mottle replaced it), a textured scene does not (on the LOL
    references the probe finds octaves 4-6 unmeasurable)."""
    return min(first_unmeasured, OCTAVES)


def _known(parameters: SpectralParameters, first_prior: int) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
    # The JPEG strength is not given: the fit tries each strength with the same constraint.
    power, correlation = covariance_parameters(parameters.covariances)
    values = {"level_curve": parameters.curve.reshape(-1), "octave_power": power, "octave_correlation": correlation}
    return measured_entries(values, first_prior)


def prior_octaves(parameters: SpectralParameters, first_prior: int, prior: CameraPrior) -> SpectralParameters:
    """``parameters`` with the octaves from ``first_prior`` on (coarser) set to the prior's conditional mean given
    the level curve and the finer octaves. The finer octaves keep their covariances; the coarse ones take the
    predicted power relative to the finer octaves' and the predicted correlations."""
    if first_prior >= OCTAVES:
        return parameters
    known, mask = _known(parameters, first_prior)
    expected = prior.values(prior.conditional_mean(known, mask))
    power, correlation = known["octave_power"].clone(), known["octave_correlation"].clone()
    coarse = slice(first_prior * 3, OCTAVES * 3)
    power[coarse] = on_measured_scale(expected["octave_power"], power, first_prior)[coarse]
    correlation[coarse] = expected["octave_correlation"][coarse]
    covariances = octave_covariances(power, correlation).to(parameters.covariances)
    return SpectralParameters(covariances=covariances, curve=parameters.curve, temporal=parameters.temporal)


def expected_texture(values: Mapping[str, torch.Tensor], prior: CameraPrior) -> dict[str, torch.Tensor]:
    """The texture dependence (``texture_gain``, ``texture_scale``) the prior expects given what a blind estimate
    measures of ``values`` (:func:`~darksynth.cameras.prior.measured_entries`: the level curve, the JPEG strength,
    the finer octaves); empty when the prior holds none."""
    if not all(name in prior.names for name in TEXTURE_NAMES):
        return {}
    known, mask = measured_entries(values)
    expected = prior.values(prior.conditional_mean(known, mask))
    return {name: expected[name].reshape(1) for name in TEXTURE_NAMES}
