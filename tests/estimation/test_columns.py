"""Column components are measured on the reference: estimated absent when it shows no column pattern.

The shipped DEN never predicts exactly zero banding, which draws faint vertical stripes; ``column_presence``
compares the reference's high-passed column means with its high-passed row means and ``estimate`` sets the
column components to 0 (and drops their ranges) when the columns are not at least ``COLUMN_RATIO`` times
stronger.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.columns import COLUMN_RATIO, column_presence
from darksynth.estimation.reference import load_reference
from darksynth.light.darkening import darken
from darksynth.models.den import DEN
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.profile import validate_profile
from darksynth.training.weights import default_weights_path, load_weights
from tests.estimation.test_roundtrip import _clean_scene

COLUMN_NAMES = ("banding", "temporal_banding", "periodic")
STARLIGHT = Path(__file__).resolve().parents[3] / "shared" / "data" / "real-lowlight" / "videos"


def _reference(noise: dict[str, float], *, frames: int = 1, seed: int = 0) -> torch.Tensor:
    """A drawn scene, darkened, with the given noise added through the composer and rounded to 8 bits."""
    clean = _clean_scene(seed).float() / 255.0
    signal = darken(clean, 0.3, 0.8).expand(frames, -1, -1, -1)
    values = NoiseValues.from_values(noise, dtype=torch.float32)
    noisy = add_noise(signal, values, generator=torch.Generator().manual_seed(seed))
    return (noisy * 255).round() / 255


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_reference_without_column_components_measures_no_column_pattern(seed: int) -> None:
    presence = column_presence(_reference({"shot": 0.05, "read": 0.01}, seed=seed))
    # Without a column pattern the columns vary like the rows: a ratio near 1, well below the threshold.
    assert 0.6 < presence.ratio < 1.5 < COLUMN_RATIO, presence
    assert not presence.present


@pytest.mark.parametrize(("name", "value"), [("banding", 0.01), ("temporal_banding", 0.01), ("periodic", 0.006)])
def test_each_visible_column_component_is_measured_present(name: str, value: float) -> None:
    presence = column_presence(_reference({"read": 0.01, name: value}, frames=2))
    assert presence.present and presence.ratio > 4 * COLUMN_RATIO, presence


def test_temporal_banding_shows_in_the_part_shared_by_the_frames() -> None:
    held = column_presence(_reference({"read": 0.01, "temporal_banding": 0.01}, frames=4))
    per_frame = column_presence(_reference({"read": 0.01, "banding": 0.01}, frames=4))
    assert held.shared_ratio is not None and per_frame.shared_ratio is not None
    # Banding drawn anew in each frame is halved in the mean over 4 frames; the held pattern is not.
    assert held.shared_ratio > 1.5 * per_frame.shared_ratio, (held, per_frame)
    assert column_presence(_reference({"read": 0.01})).shared_ratio is None


def test_a_few_vertical_edges_of_the_scene_do_not_count_as_banding() -> None:
    reference = _reference({"read": 0.01})
    reference[..., ::97] = 0.9  # five bright vertical lines down the whole frame
    assert not column_presence(reference).present


def test_a_black_reference_has_no_column_pattern() -> None:
    presence = column_presence(torch.zeros(1, 3, 64, 64))
    assert presence.ratio == 0.0 and not presence.present


@pytest.fixture(scope="module")
def srgb_model() -> DEN:
    return load_weights(default_weights_path("v3", "srgb"))


def test_estimate_sets_column_components_absent_without_stripes(srgb_model: DEN) -> None:
    result = estimate(_reference({"shot": 0.05, "read": 0.01}), srgb_model, source="plain.png")
    noise = result.profile.noise
    # The network alone gives them small non-zero values; the measurement overrides that.
    assert all(float(result.per_crop[name].median()) > 0 for name in COLUMN_NAMES)
    for name in COLUMN_NAMES:
        assert float(noise[name].abs().max()) == 0.0, name
        assert name not in result.profile.ranges
    columns = result.profile.meta["columns"]
    assert columns["decision"] == "absent"
    assert columns["set_absent"] == list(COLUMN_NAMES)
    assert columns["ratio"] < COLUMN_RATIO
    # What the network said is kept in the meta, next to the decision that overrode it.
    assert columns["network_values"]["banding"][0] == pytest.approx(
        float(result.per_crop["banding"].median()), abs=1e-5
    )
    validate_profile(result.profile)


def test_estimate_keeps_visible_banding_within_a_factor_of_its_truth(srgb_model: DEN) -> None:
    truth = 0.01
    result = estimate(_reference({"read": 0.01, "banding": truth}, frames=4, seed=5), srgb_model)
    noise = result.profile.noise
    columns = result.profile.meta["columns"]
    assert columns["decision"] == "present" and "set_absent" not in columns
    assert "banding" in result.profile.ranges
    # The shipped sRGB DEN splits the pattern over banding, temporal banding and periodic and gets about a third
    # of its strength (docs/den.md); the column std the profile draws is compared, within a factor of 4.
    drawn = float(sum(noise[name].square().sum() for name in COLUMN_NAMES).sqrt())
    assert noise.scalar("banding") > 0
    assert truth / 4 < drawn < 4 * truth, noise
    # The measurement itself gets the strength to within 20%.
    assert columns["excess_std_8bit"] / 255 == pytest.approx(truth, rel=0.2)


def test_a_clean_profile_adds_no_stripes_on_apply(srgb_model: DEN) -> None:
    # What the decision is for: without column components the profile's noise has no column structure left.
    reference = _reference({"shot": 0.05, "read": 0.01})
    noise = estimate(reference, srgb_model).profile.noise.to(dtype=torch.float32)
    clean = darken(_clean_scene(9).float() / 255.0, 0.3, 0.8)[None]
    output = add_noise(clean, noise, generator=torch.Generator().manual_seed(3))
    assert not column_presence((output * 255).round() / 255).present


@pytest.mark.skipif(not STARLIGHT.is_dir(), reason="../shared/data/real-lowlight is absent")
@pytest.mark.xfail(
    strict=True,
    reason="its first 16 frames show no column pattern above the rows' (ratio 0.96, shared 0.96, also at 2-16 px "
    "scales and in the frame-to-frame part): the measurement does not support 'visible column banding'",
)
def test_the_starlight_video_keeps_its_banding(srgb_model: DEN) -> None:
    reference = load_reference(STARLIGHT / "starlight_submillilux.mov")
    result = estimate(reference, srgb_model, source="starlight")
    assert result.profile.meta["columns"]["decision"] == "present"
    assert result.profile.noise.scalar("banding") > 0


@pytest.mark.skipif(not STARLIGHT.is_dir(), reason="../shared/data/real-lowlight is absent")
def test_the_starlight_video_column_ratio_is_the_measured_one() -> None:
    presence = column_presence(load_reference(STARLIGHT / "starlight_submillilux.mov"))
    assert presence.ratio == pytest.approx(0.96, abs=0.05)
    assert presence.shared_ratio == pytest.approx(0.96, abs=0.05)
    assert np.isfinite(presence.null_std) and presence.null_std > 0
