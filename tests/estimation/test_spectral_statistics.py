"""estimation/noise/spectral_statistics.py: the statistics of a noise map against their definitions."""

from __future__ import annotations

import torch

from darksynth.estimation.noise.spectral_statistics import (
    band_fields,
    knot_binning,
    knot_variances,
    measure,
    measure_weight,
)
from darksynth.noise.spectral import LEVEL_KNOTS


def _knot_variances_by_hats(noise: torch.Tensor, intensity: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """The definition: each knot's hat weight (1 at the knot, falling linearly to 0 at its neighbours) per pixel."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64)
    x = intensity.to(torch.float64).clamp(0.0, 1.0)[..., None]
    left = torch.cat([knots[:1] - 1.0, knots[:-1]])
    right = torch.cat([knots[1:], knots[-1:] + 1.0])
    hats = torch.minimum((x - left) / (knots - left), (right - x) / (right - knots)).clamp(0.0, 1.0)
    hats = hats * weight[:, None, ..., None]
    centred = noise.double() - noise.double().mean(dim=(0, 2, 3), keepdim=True)
    mass = hats.sum(dim=(0, 2, 3))
    return torch.einsum("tchw,tchwk->ck", centred.square(), hats) / mass


def test_knot_variances_and_band_products_equal_their_definitions() -> None:
    generator = torch.Generator().manual_seed(12)
    noise = torch.randn(2, 3, 48, 40, generator=generator) * 0.02
    # Every knot reached, the knots themselves and the ends included.
    intensity = torch.rand(2, 3, 48, 40, generator=generator).square()
    intensity[0, :, 0, : len(LEVEL_KNOTS)] = torch.tensor(LEVEL_KNOTS)
    intensity[1, 0, 0, :2] = torch.tensor([0.0, 1.0])
    weight = (torch.rand(2, 48, 40, generator=generator) > 0.3).double()
    expected = _knot_variances_by_hats(noise, intensity, weight)
    found = knot_variances(noise, intensity, weight)
    # The top knot holds too little weight here to be read (nan, as the estimators expect); every other is read.
    assert bool(torch.isnan(found[:, -1]).all()) and not bool(torch.isnan(found[:, :-1]).any())
    assert torch.allclose(found[:, :-1], expected[:, :-1], rtol=1e-10)
    fields, share = band_fields(noise)
    products = torch.einsum("tbihw,tbjhw,thw->bij", fields, fields, weight) / weight.sum()
    statistics = measure(noise, intensity, weight)
    assert torch.allclose(statistics.cross_power, products / share.clamp_min(1e-12)[:, None, None], rtol=1e-10)
    # The knots found once for many measurements give the same variances.
    binning = knot_binning(intensity, measure_weight(2, 48, 40, weight, noise.device))
    again = measure(noise, intensity, weight, binning=binning).knot_variance
    assert torch.equal(torch.isnan(again), torch.isnan(statistics.knot_variance))
    assert torch.allclose(again.nan_to_num(), statistics.knot_variance.nan_to_num(), rtol=1e-12)
