"""What the blind estimate takes from the camera prior: the coarse octaves given the finer ones and the level."""

from __future__ import annotations

import torch

from darksynth.cameras.bank import CameraRecord
from darksynth.cameras.prior import fit_prior
from darksynth.estimation.noise.camera_conditional import prior_first_octave, prior_octaves
from darksynth.estimation.noise.spectral_fit import SpectralParameters
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES, covariance_parameters, octave_covariances


def _record(index: int, mottle: float) -> CameraRecord:
    power = torch.ones(OCTAVES, 3)
    power[:, 1:] = torch.tensor([1.0, 1.0, 1.0, mottle, mottle * 2, mottle * 3])[:, None]
    return CameraRecord(
        set=f"set{index % 3}",
        name=str(index),
        camera="c",
        iso="",
        values={
            "level_curve": (0.01 * (1 + index % 4),) * (3 * len(LEVEL_KNOTS)),
            "octave_power": tuple(power.reshape(-1).tolist()),
            "octave_correlation": (0.0,) * (3 * OCTAVES),
            "compression": (0.0,),
        },
    )


def test_the_coarse_octaves_take_the_prior_and_the_finer_keep_their_measurement() -> None:
    # Every camera of the bank has coarse colour mottle 4-16x the finer octaves' colour power.
    records = [_record(index, 4.0 + (index % 5)) for index in range(30)]
    prior = fit_prior(records)
    measured_power = torch.full((OCTAVES, 3), 2.0, dtype=torch.float64)  # flat spectrum, twice white
    covariances = octave_covariances(measured_power.reshape(-1), torch.zeros(OCTAVES * 3, dtype=torch.float64))
    curve = torch.full((3, len(LEVEL_KNOTS)), 0.02, dtype=torch.float64)
    measured = SpectralParameters(covariances=covariances, curve=curve, temporal=torch.zeros(OCTAVES))
    first = prior_first_octave(3)
    assert first == 3
    completed = prior_octaves(measured, first, prior)
    power, _ = covariance_parameters(completed.covariances)
    power = power.reshape(OCTAVES, 3)
    assert torch.allclose(power[:first], measured_power[:first])
    # Colour at 23-90 px: the bank's mean mottle (6x, 12x, 18x the finer colour) on the measured scale (2).
    expected = 2.0 * torch.tensor([6.0, 12.0, 18.0], dtype=torch.float64)
    ratio = power[first:, 1] / expected
    assert ((ratio > 0.85) & (ratio < 1.15)).all(), power
    assert torch.allclose(power[first:, 0], measured_power[first:, 0], rtol=0.05)
    assert torch.equal(completed.curve, curve)


def test_the_prior_supplies_only_the_octaves_the_reference_cannot_show() -> None:
    assert prior_first_octave(2) == 2
    assert prior_first_octave(OCTAVES) == OCTAVES
