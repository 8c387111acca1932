"""estimation/noise/self_check.py: the flattest in-range blocks, and the ratio and supported level factor of a profile's
noise put back on a denoised reference."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.estimation.noise.block_check import (
    CHECK_MEAN_RANGE,
    FACTOR_BOUNDS,
    BlockCheck,
    checked_blocks,
    checked_blocks_per_intensity,
    self_consistency,
)
from darksynth.estimation.noise.self_check import check_level
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues


def _scene(height: int = 256, width: int = 320) -> torch.Tensor:
    """(3, H, W): grey steps from dark to mid-grey, one a 32-px block column, a strong grating in the bottom rows."""
    x = torch.linspace(0.05, 0.6, width // 32, dtype=torch.float64).repeat_interleave(32)
    scene = x.expand(3, height, width).clone()
    scene[:, height // 2 :, :] += 0.2 * torch.sin(torch.arange(width, dtype=torch.float64) * 1.3)
    return scene.clamp(0, 1)


def _noisy(scene: torch.Tensor, std: float, seed: int) -> torch.Tensor:
    return scene + std * torch.randn(scene.shape, generator=torch.Generator().manual_seed(seed), dtype=scene.dtype)


def test_checked_blocks_are_the_flattest_tenth_inside_the_mean_range() -> None:
    scene = _scene()
    scene[:, :64, :64] = 0.0  # crushed black: the flattest blocks of all, and outside the range
    chosen = checked_blocks(scene).reshape(8, 10)
    assert not bool(chosen[:2, :2].any())
    assert int(chosen.sum()) == round(0.1 * (80 - 4))
    assert not bool(chosen[4:].any())  # the grating's rows are never the flattest
    assert CHECK_MEAN_RANGE == (8 / 255, 247 / 255)


@pytest.mark.parametrize("factor", [0.5, 1.0, 3.0])
def test_the_ratio_and_the_supported_factor_read_a_scaled_noise_back(factor: float) -> None:
    scene = _scene()
    real = _noisy(scene, 0.01, 0)
    synthetic = _noisy(scene, 0.01 * factor, 1)
    check = self_consistency(real, scene, synthetic)
    assert check.ratio == pytest.approx(factor, rel=0.05)
    assert check.supported == pytest.approx(1 / factor, rel=0.05)
    assert check.consistent == (factor == 1.0)


def test_blocks_per_intensity_cover_every_segment_with_enough_blocks() -> None:
    chosen = checked_blocks_per_intensity(_scene())
    assert len(chosen) >= 3
    for blocks in chosen.values():
        assert int(blocks.sum()) >= 3


def test_a_scene_the_denoiser_kept_rougher_than_the_reference_supports_no_factor() -> None:
    scene = _scene()
    check = self_consistency(scene, _noisy(scene, 0.02, 0), _noisy(scene, 0.03, 1))
    assert math.isnan(check.supported)


@pytest.mark.parametrize(
    ("real", "synthetic", "scene", "up"),
    [
        # dicm 43.jpg's 83-130 levels: the scene's median std (1.62) above the synthetic blocks' (1.54), the
        # synthetic noise too weak (0.73x): no variance left to scale, and a factor that went to 1/16 before.
        (2.12, 1.54, 1.62, True),
        (2.0, 1.2, 0.5, True),  # too weak: up
        (2.0, 3.0, 0.5, False),  # too strong: down
        (2.0, 3.0, 2.9, False),  # too strong, the scene alone nearly as rough as the synthetic blocks: down
        (2.0, 0.0, 0.0, True),  # no synthetic noise at all (round-trip seed 70 after a first step): up, no division
    ],
)
def test_a_correction_moves_the_level_the_way_the_check_asks(
    real: float, synthetic: float, scene: float, up: bool
) -> None:
    check = BlockCheck(3, real / 255, synthetic / 255, (scene / 255) ** 2)
    factor = check.correction()
    assert factor > 1.0 if up else factor < 1.0
    assert FACTOR_BOUNDS[0] <= factor <= FACTOR_BOUNDS[1]


def test_a_consistent_check_corrects_nothing() -> None:
    assert BlockCheck(3, 2.0 / 255, 2.1 / 255, (1.0 / 255) ** 2).correction() == 1.0


def _spectral_values(level: float) -> NoiseValues:
    return NoiseValues.from_values({"level_curve": [level] * 24, "octave_power": [1.0] * 18}, dtype=torch.float32)


def _reference(level: float, seed: int = 7) -> tuple[torch.Tensor, float]:
    """(3, 256, 320) the grey steps with white noise of std ``level`` on 8-bit levels, and the denoiser strength
    the estimate would use (the noise in 8-bit levels). Its seed is not the check's (0): a reference drawn with the
    check's own seed holds the very noise the check draws, which the denoised base keeps a little of and the
    synthetic side then adds twice over (a true level read 1.1x)."""
    scene = _scene().float()
    noisy = quantised(
        add_noise(scene[None, None], _spectral_values(level), generator=torch.Generator().manual_seed(seed))
    )
    return noisy[0, 0], level * 255


def test_a_level_the_reference_supports_is_kept_without_a_word() -> None:
    reference, strength = _reference(0.02)
    found = check_level(reference, _spectral_values(0.02), torch.full((3, 8), 0.02), strength, "ref.png")
    assert found.warnings == [] and found.meta["kept"].startswith("measurement: its check passes")
    assert torch.allclose(found.curve, torch.full((3, 8), 0.02, dtype=torch.float64))
    # 4x the network's: kept, since it passes, with a line that says texture would pass too.
    far = check_level(reference, _spectral_values(0.02), torch.full((3, 8), 0.005), strength, "ref.png")
    assert torch.equal(far.curve, found.curve)
    assert len(far.warnings) == 1 and "4.0x the network's, passes the self-check" in far.warnings[0]


@pytest.mark.parametrize("misread", [0.25, 4.0])
def test_a_level_the_reference_contradicts_is_scaled_to_what_it_supports(misread: float) -> None:
    reference, strength = _reference(0.02)
    found = check_level(reference, _spectral_values(0.02 * misread), torch.full((3, 8), 0.02), strength, "ref.png")
    assert len(found.warnings) == 1 and found.warnings[0].startswith("ref.png: the measured noise put back")
    checked = found.curve[:, 1:5]  # the knots of the intensities the steps show (0.05-0.6)
    # The true level reads 1.00-1.04 here: a correction from below aims at 1 and settles at about the true level
    # (0.97-0.98; at the near edge, 0.85, it settled at 0.81-0.85); from above at the near edge, 1.2-1.25.
    low, high = (0.9, 1.1) if misread < 1 else (1.15, 1.3)
    assert bool(((checked / 0.02 >= low) & (checked / 0.02 <= high)).all()), found.curve
    assert all(0.8 <= row["ratio"] <= 1.25 for row in found.meta["corrected"].values()), found.meta


def test_what_a_weak_denoiser_leaves_of_the_noise_is_not_read_as_the_profiles() -> None:
    """Strong noise under a denoiser set to 0.6 of it (a phone at ISO 3200): the denoised base keeps about a third of
    the noise's variance, which the synthetic side carries under the profile's. A level read 0.6x then shows 0.84x
    the reference's block std, inside the consistent range; counting the leftover, the check reads it weak and raises
    it, and keeps the true level as it is."""
    reference, strength = _reference(0.06)
    weak = check_level(reference, _spectral_values(0.036), torch.full((3, 8), 0.06), 0.6 * strength, "phone.png")
    leftovers = [row["leftover"] for row in weak.meta["measured"].values()]
    assert max(leftovers) > 0.25, weak.meta  # the denoiser left a sizeable share at the steps' intensities
    assert weak.meta["kept"] == "measurement scaled to what the check supports", weak.meta
    assert float((weak.curve[:, 2:5] / 0.06).min()) > 0.72, weak.curve  # raised from 0.6
    true = check_level(reference, _spectral_values(0.06), torch.full((3, 8), 0.06), 0.6 * strength, "phone.png")
    assert true.meta["kept"] == "measurement: its check passes" and true.warnings == [], true.meta


def test_a_level_far_from_the_network_with_no_block_to_check_gives_way_to_the_network() -> None:
    frame = torch.zeros(3, 256, 256)
    frame[:, 100:140, 60:90] = 1.0  # a lamp on crushed black: no block between 8 and 247 levels
    network = torch.full((3, 8), 0.005)
    found = check_level(frame, _spectral_values(0.05), network, 3.0, "night.jpg")
    assert torch.equal(found.curve, network.double())
    assert len(found.warnings) == 1 and "no flat block of 8-247 levels can check it" in found.warnings[0]
    near = check_level(frame, _spectral_values(0.01), network, 3.0, "night.jpg")
    assert near.warnings == [] and near.meta["kept"] == "measurement, unchecked"


def test_fine_texture_the_denoiser_takes_off_does_not_raise_a_true_level() -> None:
    """Grain alike in every channel, as strong as the noise, on every block (fabric, a wall's render): the denoiser
    takes much of it off with the noise, so the reference shows about 0.7x more on its flattest blocks than the true
    level put back. What it took off is alike across channels, unlike the profile's noise: the level is not raised,
    and the warning says so. Without the grain the same noise reads as noise."""
    scene = _scene().float()
    grain = 0.02 * torch.randn(scene.shape[1:], generator=torch.Generator().manual_seed(11))
    textured = quantised(
        add_noise(
            (scene + grain[None]).clamp(0, 1)[None, None],
            _spectral_values(0.02),
            generator=torch.Generator().manual_seed(7),
        )
    )[0, 0]
    found = check_level(textured, _spectral_values(0.02), torch.full((3, 8), 0.02), 0.02 * 255, "fabric.png")
    measured = found.meta["measured"].values()
    assert all(row["ratio"] < 0.8 and row["texture_like"] for row in measured), found.meta  # a raise, before
    assert torch.allclose(found.curve, torch.full((3, 8), 0.02, dtype=torch.float64))
    assert found.meta["kept"] == "measurement: its check passes"
    assert len(found.warnings) == 1 and "alike across channels or smoother than noise" in found.warnings[0]
    reference, strength = _reference(0.02)
    plain = check_level(reference, _spectral_values(0.02), torch.full((3, 8), 0.02), strength, "ref.png")
    assert not any(row["texture_like"] for row in plain.meta["measured"].values()), plain.meta
