"""estimation/noise/texture_fit.py through the clean-aided fit: a known texture_gain and texture_scale applied to clean
photographs is fitted back, and the fitted model's textured-to-flat ratio is the truth's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from darksynth.estimation.noise.spectral_fit import oracle_spectral_fit, quantised
from darksynth.estimation.noise.texture_fit import TEXTURE_GAINS, interpolated_gain
from darksynth.evaluation.measures.texture_ratio import textured_flat_ratio
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues

KODAK = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "clean" / "images" / "kodak24"
SHARED_KODAK = Path("/work/shared/data/clean/images/kodak24")

TRUTH = {
    "level_curve": [0.012 + 0.01 * (k / 7) for _ in range(3) for k in range(8)],
    "octave_power": [1.5, 1.0, 1.0] * 6,
    "octave_correlation": [0.0] * 18,
    "texture_gain": 0.8,
    "texture_scale": 0.008,
}


def _clean_crops() -> list[torch.Tensor]:
    folder = next((f for f in (KODAK, SHARED_KODAK) if f.is_dir()), None)
    if folder is None:
        pytest.skip(f"no clean photographs at {KODAK} or {SHARED_KODAK} (the shared data set is absent)")
    crops = []
    for name in ("kodim03.png", "kodim08.png", "kodim19.png"):
        pixels = np.asarray(Image.open(folder / name).convert("RGB"), dtype=np.float64)[:256, :256] / 255.0
        # A dark scene on 8-bit levels, as the real pairs' clean images are.
        crops.append(quantised(0.45 * torch.from_numpy(pixels).permute(2, 0, 1).float()))
    return crops


def test_interpolated_gain_reads_the_rising_curve_and_holds_its_ends() -> None:
    ratios = [1.0 + 0.5 * gain for gain in TEXTURE_GAINS]
    assert interpolated_gain(1.0 + 0.5 * 0.6, ratios) == pytest.approx(0.6)
    assert interpolated_gain(0.9, ratios) == 0.0
    assert interpolated_gain(10.0, ratios) == TEXTURE_GAINS[-1]


def test_a_known_texture_is_fitted_back_and_its_ratio_reproduced() -> None:
    truth = NoiseValues.from_values(TRUTH, dtype=torch.float32)  # type: ignore[arg-type]
    for index, clean in enumerate(_clean_crops()):
        noisy = quantised(add_noise(clean[None, None], truth, generator=torch.Generator().manual_seed(index))[0, 0])
        fitted = NoiseValues.from_values(oracle_spectral_fit(noisy, clean, iterations=2, compressions=(0.0,)))
        assert fitted.scalar("texture_gain") > 0.2, index
        check = add_noise(
            clean[None, None], fitted.to(dtype=torch.float32), generator=torch.Generator().manual_seed(50 + index)
        )
        real_ratio = textured_flat_ratio(noisy - clean, clean)
        synthetic_ratio = textured_flat_ratio(quantised(check[0, 0]) - clean, clean)
        # The truth's texture is strong: without it the ratio would be near 1.
        assert real_ratio > 1.4, index
        assert synthetic_ratio / real_ratio == pytest.approx(1.0, abs=0.10), (index, real_ratio, synthetic_ratio)
