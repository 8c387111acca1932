"""estimation/noise/spectral_fit.py: the spectral model's parameters fitted by re-synthesis, and the priors for what a
reference cannot show."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.estimation.noise.spectral_fit import fit_by_resynthesis, oracle_spectral_fit, quantised
from darksynth.estimation.noise.spectral_statistics import SpectralStatistics, measure
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.values import NoiseValues


@pytest.mark.parametrize("seed", [0, 1])
def test_round_trip_of_a_random_spectrum_through_the_clean_aided_fit(seed: int) -> None:
    generator = torch.Generator().manual_seed(100 + seed)
    truth = {
        "level_curve": (0.01 + 0.04 * torch.rand(24, generator=generator)).tolist(),
        "octave_power": (torch.rand(OCTAVES * 3, generator=generator) * 4 - 1.5).exp().tolist(),
        "octave_correlation": (torch.rand(OCTAVES * 3, generator=generator) * 0.8 - 0.4).tolist(),
    }
    clean = (torch.rand(1, 3, 1, 1, generator=generator) * 0.4 + 0.1).expand(1, 3, 256, 256)
    gradient = torch.linspace(0.0, 0.5, 256).reshape(1, 1, 1, 256)
    clean = quantised(clean + gradient)
    truth_values = NoiseValues.from_values(truth, dtype=torch.float32)  # type: ignore[arg-type]
    noisy = quantised(add_noise(clean[None], truth_values, generator=torch.Generator().manual_seed(7))[0])
    fitted = NoiseValues.from_values(oracle_spectral_fit(noisy[0], clean[0], compressions=(0.0,)))
    check = quantised(
        add_noise(clean[None], fitted.to(dtype=torch.float32), generator=torch.Generator().manual_seed(99))[0]
    )
    real, synthetic = measure(noisy - clean, clean), measure(check - clean, clean)
    ratio = synthetic.cross_power.diagonal(dim1=-2, dim2=-1) / real.cross_power.diagonal(dim1=-2, dim2=-1)
    # Every octave's power of every component within 10 % in the median, within 35 % at worst, from another draw
    # (the coarse bands of a 256-px image hold a few hundred frequencies: their own sampling error is ~10 %).
    assert float(ratio[:5].log().abs().median()) < math.log(1.1)
    assert float(ratio[:5].log().abs().max()) < math.log(1.35)


def test_the_fit_converges_on_its_own_simulator() -> None:
    """fit_by_resynthesis moves a wrong start onto the target when the simulator is exact (common draws)."""
    target_parameters = torch.diag_embed(torch.tensor([[2.0, 0.5, 0.5]] * OCTAVES, dtype=torch.float64))

    def simulate(parameters: object, draw: int) -> SpectralStatistics:
        covariances = parameters.covariances  # type: ignore[attr-defined]
        curve = parameters.curve  # type: ignore[attr-defined]
        return SpectralStatistics(covariances * 1.3, curve.square() * 0.8, None)

    target = SpectralStatistics(target_parameters * 1.3, torch.full((3, 8), 0.01 * 0.8, dtype=torch.float64), None)
    fitted, left = fit_by_resynthesis(target, simulate, iterations=3, draws=1)
    assert torch.allclose(fitted.covariances, target_parameters, rtol=1e-6)
    assert torch.allclose(fitted.curve, torch.full((3, 8), 0.1, dtype=torch.float64), rtol=1e-6)
    assert left >= 0.0


def test_unmeasured_octaves_continue_the_colour_roll_off_of_a_gaussian_low_pass() -> None:
    from darksynth.estimation.noise.spectral_fit import SpectralParameters, continue_octaves
    from darksynth.noise.spectral import OCTAVE_FREQUENCIES

    # Octaves 0-2 measured: white noise through a Gaussian low-pass of f0 = 0.1 cycles/px in colour 1, a falling
    # colour 2, a rising brightness; octaves 3-5 unmeasured (garbage that must be replaced).
    frequency = torch.tensor(OCTAVE_FREQUENCIES, dtype=torch.float64)
    low_pass = 5.0 * torch.exp(-((frequency / 0.1) ** 2))
    power = torch.stack([torch.linspace(1.0, 3.0, OCTAVES), low_pass, torch.linspace(4.0, 1.0, OCTAVES)], dim=-1)
    correlation = torch.tensor([[1.0, 0.3, -0.2], [0.3, 1.0, 0.1], [-0.2, 0.1, 1.0]], dtype=torch.float64)
    covariances = correlation * power.sqrt()[:, :, None] * power.sqrt()[:, None, :]
    covariances[3:] = 77.0 * torch.eye(3, dtype=torch.float64)
    temporal = torch.tensor([0.1, 0.2, 0.3, 0.9, 0.9, 0.9], dtype=torch.float64)
    parameters = SpectralParameters(covariances, torch.ones(3, 8, dtype=torch.float64), temporal)
    continued = continue_octaves(parameters, 3)
    diagonal = continued.covariances.diagonal(dim1=-2, dim2=-1)
    # The low-pass is recovered exactly from its two last measured octaves; its coarse limit is 5.
    assert torch.allclose(diagonal[3:, 1], low_pass[3:], rtol=1e-9)
    assert bool((diagonal[3:, 1] < 5.0).all()) and bool((diagonal[3:, 1] > power[2, 1]).all())
    # Brightness and a colour falling toward coarse scales are held at the last measured octave.
    assert torch.allclose(diagonal[3:, 0], power[2, 0].expand(3))
    assert torch.allclose(diagonal[3:, 2], power[2, 2].expand(3))
    std = diagonal.sqrt()
    assert torch.allclose(continued.covariances[4] / (std[4][:, None] * std[4][None, :]), correlation)
    assert torch.allclose(continued.temporal[3:], torch.full((3,), 0.3, dtype=torch.float64))
    assert torch.equal(continued.covariances[:3], covariances[:3])


def test_unmeasured_knots_follow_the_prior_curve_through_the_measured_ones() -> None:
    from darksynth.estimation.noise.spectral_fit import fill_knots_along

    prior = torch.linspace(1.0, 8.0, 8, dtype=torch.float64).expand(3, 8).clone()
    curve = 2.0 * prior
    measured = torch.zeros(3, 8, dtype=torch.bool)
    measured[:, 3:6] = True
    curve[:, :3] = 0.01  # what a clipped knot would have read: it must not be kept, nor continued flat
    filled = fill_knots_along(curve, measured, prior)
    assert torch.allclose(filled, 2.0 * prior)
    # Between measured knots the log ratio is interpolated: ratios 2 and 8 give 4 half-way.
    curve = prior.clone()
    curve[:, 2], curve[:, 6] = 2.0 * prior[:, 2], 8.0 * prior[:, 6]
    between = torch.zeros(3, 8, dtype=torch.bool)
    between[:, [2, 6]] = True
    assert torch.allclose(fill_knots_along(curve, between, prior)[:, 4], 4.0 * prior[:, 4])
    # A channel with no measured knot takes the others' median ratio.
    only = measured.clone()
    only[2] = False
    assert torch.allclose(fill_knots_along(2.0 * prior, only, prior)[2], 2.0 * prior[2])


@pytest.mark.parametrize("signal", [-0.05, -0.01, 0.0, 0.02, 0.1, 0.97, 1.01])
def test_the_uncensored_signal_is_the_mean_before_the_clip(signal: float) -> None:
    from darksynth.estimation.noise.spectral_fit import uncensored_signal

    std = 0.03
    clipped = (signal + std * torch.randn(400_000, generator=torch.Generator().manual_seed(1))).clamp(0.0, 1.0)
    found = uncensored_signal(clipped.mean()[None], torch.tensor([std]))
    assert abs(float(found[0]) - signal) < 0.002


def test_uncensored_signal_searches_only_where_the_cut_reaches() -> None:
    """The signal under a clipped mean: far from 0 it is the mean itself, near 0 the table's inversion, as a full
    search of every pixel gives."""
    from darksynth.estimation.noise.spectral_fit import _CENSORED_MEAN, _CENSORED_T, uncensored_signal

    generator = torch.Generator().manual_seed(0)
    observed = torch.rand(3, 40, 40, generator=generator) ** 3
    observed[0, :4] = 0.0
    observed[1, :2] = 1.0
    std = 0.002 + 0.05 * torch.rand(3, 40, 40, generator=generator)

    def searched(mean: torch.Tensor) -> torch.Tensor:
        ratio = (mean / std.clamp_min(1e-6)).to(torch.float64)
        index = torch.searchsorted(_CENSORED_MEAN, ratio.clamp(float(_CENSORED_MEAN[0]), float(_CENSORED_MEAN[-1])))
        index = index.clamp(1, len(_CENSORED_T) - 1)
        low, high = _CENSORED_MEAN[index - 1], _CENSORED_MEAN[index]
        t = _CENSORED_T[index - 1] + ((ratio - low) / (high - low)).clamp(0.0, 1.0) * (
            _CENSORED_T[index] - _CENSORED_T[index - 1]
        )
        t = torch.where(ratio >= float(_CENSORED_MEAN[-1]), ratio, t)
        return (t * std.to(torch.float64)).to(mean.dtype)

    assert torch.equal(uncensored_signal(observed, std), 1.0 - searched(1.0 - searched(observed)))
