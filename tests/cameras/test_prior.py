"""The prior over real cameras: its space, its fit with sets weighing the same, its conditionals and its draws."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import torch

from darksynth.cameras.bank import BANK_FORMAT, BANK_VERSION, CameraRecord, read_bank, shipped_bank
from darksynth.cameras.prior import (
    LEVEL_RANGE_8BIT,
    SHRINKAGE,
    fit_prior,
    from_features,
    held_out_sets,
    shipped_prior,
    to_features,
)
from darksynth.errors import DarksynthError
from darksynth.noise.spectral import LEVEL_KNOTS, OCTAVES


def _record(set_name: str, level: float, coarse: float, correlation: float = 0.1) -> CameraRecord:
    power = torch.ones(OCTAVES, 3)
    power[3:] *= coarse
    return CameraRecord(
        set=set_name,
        name=f"{set_name}-{level}-{coarse}",
        camera="c",
        iso="",
        values={
            "level_curve": (level,) * (3 * len(LEVEL_KNOTS)),
            "octave_power": tuple(power.reshape(-1).tolist()),
            "octave_correlation": (correlation,) * (3 * OCTAVES),
            "compression": (0.2,),
        },
    )


def test_the_space_inverts_and_snaps_jpeg_to_the_fitted_steps() -> None:
    curve = torch.tensor([0.01, 0.02, 0.04])
    assert torch.allclose(from_features("level_curve", to_features("level_curve", curve)), curve.double())
    correlation = torch.tensor([-0.5, 0.0, 0.7])
    assert torch.allclose(
        from_features("octave_correlation", to_features("octave_correlation", correlation)), correlation.double()
    )
    assert from_features("compression", torch.tensor([0.13, 0.31, -0.2], dtype=torch.float64)).tolist() == [
        0.2,
        0.4,
        0.0,
    ]
    # Powers are a shape: scaling every octave leaves the features unchanged.
    power = torch.rand(OCTAVES * 3, generator=torch.Generator().manual_seed(0)) + 0.1
    assert torch.allclose(to_features("octave_power", power), to_features("octave_power", 7 * power))


def test_each_set_weighs_the_same_whatever_its_size() -> None:
    records = [_record("big", 0.01, 1.0)] * 30 + [_record("small", 0.04, 1.0)]
    prior = fit_prior(records)
    level = prior.slices()["level_curve"]
    # The mean log level is halfway between the two sets', not pulled to the big set's; the curves are flat.
    expected = 0.5 * (math.log(0.01) + math.log(0.04))
    assert float(prior.mean[level][0]) == pytest.approx(float(expected), abs=1e-9)
    assert torch.allclose(prior.mean[level][1:], torch.zeros(24, dtype=torch.float64), atol=1e-9)


def test_the_conditional_mean_follows_the_regression_of_the_shrunk_covariance() -> None:
    # Coarse power rises with the level across cameras: a louder camera has stronger mottle.
    generator = torch.Generator().manual_seed(1)
    records = []
    for index in range(40):
        log_level = float(torch.randn(1, generator=generator)) * 0.5 + float(torch.log(torch.tensor(0.02)))
        level = float(torch.exp(torch.tensor(log_level)))
        coarse = float(
            torch.exp(torch.tensor(2.0 * (log_level + 3.9) + 0.05 * float(torch.randn(1, generator=generator))))
        )
        records.append(_record(f"set{index % 4}", level, coarse))
    prior = fit_prior(records)
    parts = prior.slices()
    for level in (0.01, 0.04):
        known = {"level_curve": torch.full((24,), level)}
        mask = {"level_curve": torch.ones(24, dtype=torch.bool)}
        mean = prior.conditional_mean(known, mask)
        assert float(mean[parts["level_curve"]][0]) == pytest.approx(float(torch.log(torch.tensor(level))))
        coarse = mean[parts["octave_power"]].reshape(OCTAVES, 3)[3:]
        # Twice the log level's gap from the mean (the slope the records were made with), times what the shrinkage
        # leaves of it: the level's one feature that varies predicts with the cross-covariance's off-diagonal share
        # 1 - s over its own full variance.
        gap = float(torch.log(torch.tensor(level))) - float(prior.mean[parts["level_curve"]][0])
        relative = coarse - float(prior.mean[parts["octave_power"]].reshape(OCTAVES, 3)[3:].mean())
        assert float(relative.mean()) == pytest.approx(2.0 * gap * (1 - SHRINKAGE), rel=0.05)
        assert (relative * gap > 0).all()


def test_draws_without_a_reference_span_the_exposure_range_and_follow_the_prior_given_it() -> None:
    records = [_record(f"s{i % 3}", 0.005 * (1 + i % 5), 1 + (i % 7)) for i in range(21)]
    prior = fit_prior(records)
    drawn = prior.draw(torch.Generator().manual_seed(3), count=3000)
    assert drawn.batch_shape == (3000,)
    features = torch.stack([prior.features(drawn.clip(i)) for i in range(3000)])
    # Loudness log-uniform over the range: its quartiles at a quarter, half and three quarters of the log span.
    low, high = (math.log(level / 255.0) for level in LEVEL_RANGE_8BIT)
    scale = features[:, prior.slices()["level_curve"].start]
    quartiles = torch.quantile(scale, torch.tensor([0.25, 0.5, 0.75], dtype=torch.float64))
    expected = torch.tensor([low + q * (high - low) for q in (0.25, 0.5, 0.75)], dtype=torch.float64)
    assert torch.allclose(quartiles, expected, atol=0.04 * (high - low))
    # Everything else: the prior's regression on the loudness, with the uniform's variance passed through it
    # (the law of total variance): mean mu + k (E s - mu_s), variance S_xx - k S_sx + k^2 Var s.
    index = prior.slices()["level_curve"].start
    others = torch.arange(prior.mean.numel()) != index
    gain = prior.covariance[others, index] / prior.covariance[index, index]
    mean = prior.mean[others] + gain * ((low + high) / 2 - prior.mean[index])
    variance = (
        prior.covariance.diagonal()[others] - gain * prior.covariance[others, index] + gain**2 * (high - low) ** 2 / 12
    )
    assert torch.allclose(features[:, others].mean(0), mean, atol=0.1 * float(variance.max().sqrt()) + 1e-6)
    spread = variance > 1e-4
    assert torch.allclose(features[:, others].var(0)[spread], variance[spread], rtol=0.1)


def test_a_conditional_draw_keeps_what_is_given_and_spreads_the_rest() -> None:
    records = [_record(f"s{i % 3}", 0.005 * (1 + i % 5), 1 + (i % 7), 0.1 + 0.05 * (i % 4)) for i in range(21)]
    prior = fit_prior(records)
    known = {"level_curve": torch.full((24,), 0.01)}
    mask = {"level_curve": torch.ones(24, dtype=torch.bool)}
    draws = [prior.draw_given(known, mask, torch.Generator().manual_seed(seed)) for seed in range(30)]
    for values in draws:
        assert torch.allclose(values["level_curve"], torch.full((24,), 0.01, dtype=torch.float64))
    coarse = torch.stack([values["octave_power"][9] for values in draws])
    assert float(coarse.std()) > 0


def test_sets_of_the_same_cameras_are_held_out_together() -> None:
    assert held_out_sets("nam-cc15") == {"nam-cc15", "nam-cc60"}
    assert held_out_sets("nam-cc60") == {"nam-cc15", "nam-cc60"}
    assert held_out_sets("polyu") == {"polyu"}


def test_the_shipped_bank_holds_every_set_and_its_prior_leaves_sets_out() -> None:
    bank = shipped_bank()
    sets = {record.set for record in bank}
    assert {"sidd", "nam-cc15", "nam-cc60", "polyu"} <= sets
    for record in bank:
        assert len(record.values["level_curve"]) == 3 * len(LEVEL_KNOTS)
        assert len(record.values["octave_power"]) == 3 * OCTAVES
    assert "polyu" not in shipped_prior(frozenset({"polyu"})).sets
    assert set(shipped_prior().sets) == sets


def test_a_bad_bank_file_is_named(tmp_path: Path) -> None:
    path = tmp_path / "bank.json"
    path.write_text("{")
    with pytest.raises(DarksynthError, match=r"bank\.json: cannot read"):
        read_bank(path)
    path.write_text(json.dumps({"format": "other"}))
    with pytest.raises(DarksynthError, match="not a camera bank"):
        read_bank(path)
    path.write_text(json.dumps({"format": BANK_FORMAT, "version": BANK_VERSION, "records": [{"set": "a"}]}))
    with pytest.raises(DarksynthError, match="malformed"):
        read_bank(path)
