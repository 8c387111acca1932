"""The prior over real cameras: its space, its fit with sets weighing the same, its conditionals and its draws."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from darksynth.cameras.bank import BANK_FORMAT, BANK_VERSION, CameraRecord, read_bank, shipped_bank
from darksynth.cameras.prior import (
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
    # The mean log level is halfway between the two sets', not pulled to the big set's.
    expected = 0.5 * (torch.log(torch.tensor(0.01)) + torch.log(torch.tensor(0.04)))
    assert torch.allclose(prior.mean[level], expected.double().expand(24), atol=1e-9)


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
        assert torch.allclose(mean[parts["level_curve"]], torch.log(torch.tensor(level)).double().expand(24))
        coarse = mean[parts["octave_power"]].reshape(OCTAVES, 3)[3:]
        # Twice the log level's gap from the mean (the slope the records were made with), times what the shrinkage
        # leaves of it: the 24 equal knots are one predictor seen 24 times, so by Sherman-Morrison the shrunk
        # regression keeps 24 (1 - s) / (s + 24 (1 - s)) of the slope.
        gap = float(torch.log(torch.tensor(level))) - float(prior.mean[parts["level_curve"]][0])
        relative = coarse - float(prior.mean[parts["octave_power"]].reshape(OCTAVES, 3)[3:].mean())
        kept = 24 * (1 - SHRINKAGE) / (SHRINKAGE + 24 * (1 - SHRINKAGE))
        assert float(relative.mean()) == pytest.approx(2.0 * gap * kept, rel=0.05)
        assert (relative * gap > 0).all()


def test_draws_have_the_prior_moments() -> None:
    records = [_record(f"s{i % 3}", 0.005 * (1 + i % 5), 1 + (i % 7)) for i in range(21)]
    prior = fit_prior(records)
    drawn = prior.draw(torch.Generator().manual_seed(3), count=4000)
    assert drawn.batch_shape == (4000,)
    features = torch.stack([prior.features(drawn.clip(i)) for i in range(4000)])
    assert torch.allclose(features.mean(0), prior.mean, atol=0.05 + 0.05 * prior.covariance.diagonal().sqrt().max())
    variance = features.var(0)
    spread = prior.covariance.diagonal() > 1e-4
    assert torch.allclose(variance[spread], prior.covariance.diagonal()[spread], rtol=0.1)


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
