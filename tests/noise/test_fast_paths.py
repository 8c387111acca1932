"""Fast paths are declared in the table, chosen by what the values need, and fall back loudly."""

from __future__ import annotations

import logging
import sys

import pytest
import torch

from darksynth.darkening import Darkening
from darksynth.noise import kernel8
from darksynth.noise.kernel8 import FAST_PATH
from darksynth.noise.values import NoiseValues
from darksynth.synthesize import ClipParameters, ClipSynthesizer

PAPER = {"shot": 0.05, "read": 0.01, "quantization": 0.004, "banding": 0.003, "temporal_banding": 0.002}


@pytest.mark.parametrize(
    ("extra", "covered"),
    [
        ({}, True),
        ({"periodic": 0.002}, True),
        ({"channel_gain": [1.3, 1.0]}, False),
        ({"correlation_length": 0.8}, False),
        ({"channel_correlation": [0.3, 0.0, 0.0]}, False),
        ({"compression": 0.3}, False),
    ],
)
def test_the_fused_kernel_covers_what_the_table_declares(extra: dict[str, object], covered: bool) -> None:
    values = NoiseValues.from_values(PAPER | extra)  # type: ignore[arg-type]
    assert values.covered_by(FAST_PATH) is covered
    synthesizer = ClipSynthesizer(ClipParameters(values, None), generator=torch.Generator().manual_seed(0))
    assert synthesizer._fusable is covered


def test_fused_and_general_paths_draw_the_same_law() -> None:
    """8-bit frames take the fused kernel, float frames the general composer: same mean and variance."""
    values = NoiseValues.from_values({"shot": 0.06, "read": 0.012, "quantization": 0.004, "banding": 0.003})
    parameters = ClipParameters(values, Darkening(0.4, 1.0))
    frame8 = torch.full((3, 256, 256), 200, dtype=torch.uint8)
    fused = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(1))
    general = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(1))
    assert fused._fusable
    out8 = torch.stack([fused(frame8) for _ in range(4)]).double() / 255.0
    out_float = torch.stack([general(frame8.float() / 255.0) for _ in range(4)]).double()
    # The general path keeps floats: round it as the 8-bit path does before comparing.
    out_float = (out_float * 255.0).round() / 255.0
    level = 0.4 * 200 / 255
    expected_var = 0.06**2 * level + 0.012**2 + 0.004**2 / 12 + 0.003**2 + 1 / (12 * 255**2)
    for out in (out8, out_float):
        assert abs(float(out.mean()) - (level + 0.002)) < 0.002
        assert abs(float(out.var()) / expected_var - 1.0) < 0.05


def test_a_failing_compiled_kernel_falls_back_once_with_a_log_line(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def broken(*args: object) -> torch.Tensor:
        raise RuntimeError("no working C compiler")

    # darksynth.synthesize is also the name of the package's function: reach the module itself.
    monkeypatch.setattr(sys.modules["darksynth.synthesize"], "compiled_pixel_kernel", lambda: broken)
    parameters = ClipParameters(NoiseValues.from_values({"read": 0.02}), None)
    frame = torch.full((3, 32, 32), 100, dtype=torch.uint8)
    with caplog.at_level(logging.WARNING, logger="darksynth.synthesize"):
        compiled = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2), compile=True)
        frames = [compiled(frame) for _ in range(3)]
    eager = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2))
    assert all(torch.equal(a, eager(frame)) for a in frames)
    warnings = [r for r in caplog.records if "compiled 8-bit kernel failed" in r.getMessage()]
    assert len(warnings) == 1 and "no working C compiler" in warnings[0].getMessage()
    assert kernel8.pixel_kernel_8bit is not broken
