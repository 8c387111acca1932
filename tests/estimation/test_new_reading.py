"""A measured quantity declared once (docs/architecture.md, "How to add an option, a component, a measurement"): a
reading after the spectral fit, declared inside the test and put in ``estimation.noise.readings.AFTER_FIT`` with no
other change to darksynth, sets its parameter in the profile, written and read back, and its record in ``meta``."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import pytest
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.findings import Findings
from darksynth.estimation.noise import readings
from darksynth.estimation.noise.resynthesis import FittedReference, MeasuredValues
from darksynth.models.den import DEN
from darksynth.profile import load_profile, save_profile


def _dark_frame(size: int = 128) -> torch.Tensor:
    """(1, 3, size, size): a dark ramp with noise of 3 8-bit levels, on 8-bit levels."""
    generator = torch.Generator().manual_seed(5)
    ramp = torch.linspace(0.05, 0.25, size).expand(3, size, size)
    noisy = ramp + torch.randn(3, size, size, generator=generator) * (3 / 255)
    return ((noisy.clamp(0, 1) * 255).round() / 255)[None]


def test_a_reading_declared_in_the_test_sets_its_parameter_its_meta_and_its_warning(
    tiny_model: Callable[..., DEN], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    given: dict[str, torch.Tensor] = {}

    def strength_as_texture_scale(reference: FittedReference, values: Mapping[str, torch.Tensor]) -> MeasuredValues:
        # Any quantity of the analysed reference will do: the denoiser's strength, as a detail level on [0, 1].
        given.update(values)
        scale = reference.resynthesis.strength / 255.0
        findings = Findings({"texture_scale_read": round(scale, 6)}, [f"{reference.name}: texture scale read"])
        return MeasuredValues({"texture_scale": torch.tensor([scale], dtype=torch.float64)}, findings)

    before = estimate(_dark_frame(), tiny_model(), source="dark.png")
    monkeypatch.setattr(readings, "AFTER_FIT", (*readings.AFTER_FIT, strength_as_texture_scale))
    found = estimate(_dark_frame(), tiny_model(), source="dark.png")

    # The readings before it ran and handed on their values; what they set is unchanged.
    assert {"level_curve", "compression", "temporal_correlation", "codec_repeat"} <= set(given)
    spectrum = found.profile.meta["spectrum"]
    expected = spectrum["denoiser_strength_8bit"] / 255.0
    assert spectrum["texture_scale_read"] == pytest.approx(expected, rel=1e-3)
    assert "dark.png: texture scale read" in found.warnings
    path = tmp_path / "profile.json"
    save_profile(path, found.profile)
    written = load_profile(path).noise
    assert float(written["texture_scale"].reshape(-1)[0]) == pytest.approx(expected, rel=1e-3)
    # Without the reading the profile keeps another scale, and every other value is the same.
    unread = before.profile.noise["texture_scale"]
    assert float(unread.reshape(-1)[0]) != pytest.approx(expected, rel=0.1)
    assert found.profile.noise.replace(texture_scale=unread) == before.profile.noise
