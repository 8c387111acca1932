"""The frame-to-frame correlation fitted on frame differences (estimation/noise/persistence_fit.py): the statistic holds
no still scene, the search takes the first crossing, drawn clips of known AR(1) coefficient come back, a codec's
skipped blocks and frame types are read as the persistence they give, and what cannot be read gets the video
prior, stated."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.estimation.noise import persistence_fit
from darksynth.estimation.noise.persistence_fit import (
    MAX_COEFFICIENT,
    SEARCH_GRID,
    VIDEO_PRIOR,
    difference_powers,
    persistence_statistic,
    skipped_shares,
    solve_coefficients,
)
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.noise.spectrum import estimate_spectrum
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.synthesize import synthesize


def _ar1_frames(rho: float, frames: int = 4, side: int = 128, seed: int = 0) -> torch.Tensor:
    """(T, 3, side, side) white noise of unit variance, AR(1) from frame to frame with coefficient ``rho``."""
    generator = torch.Generator().manual_seed(seed)
    noise = [torch.randn(3, side, side, generator=generator, dtype=torch.float64)]
    for _ in range(frames - 1):
        fresh = torch.randn(3, side, side, generator=generator, dtype=torch.float64)
        noise.append(rho * noise[-1] + math.sqrt(1 - rho**2) * fresh)
    return torch.stack(noise)


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8])
def test_the_statistic_reads_the_coefficient_whatever_still_texture_rides_on_the_noise(rho: float) -> None:
    noise = _ar1_frames(rho)
    generator = torch.Generator().manual_seed(1)
    # Fine texture twice as strong as the noise, the same in every frame: a correlation would read it as 0.8+.
    texture = 2.0 * torch.randn(3, 128, 128, generator=generator, dtype=torch.float64)
    mask = torch.ones(128, 128)
    statistic = persistence_statistic(difference_powers(noise + texture, mask))
    assert torch.allclose(statistic[:3], torch.full((3,), rho, dtype=torch.float64), atol=0.08), statistic


def test_a_change_of_exposure_between_frames_is_not_read_as_persistence() -> None:
    # A gain of the whole frame, its noise included (auto-exposure): 30% over the clip, on shading of 40 levels.
    noise = _ar1_frames(0.3)
    y, x = torch.meshgrid(torch.linspace(0, 1, 128), torch.linspace(0, 1, 128), indexing="ij")
    scene = 20.0 * (x + y).expand(3, -1, -1).double()
    gains = torch.tensor([1.0, 0.9, 0.8, 0.7], dtype=torch.float64)[:, None, None, None]
    statistic = persistence_statistic(difference_powers(gains * (scene + noise), torch.ones(128, 128)))
    assert torch.allclose(statistic[:3], torch.full((3,), 0.3, dtype=torch.float64), atol=0.1), statistic


def test_the_search_takes_the_first_crossing_of_a_statistic_that_turns_back() -> None:
    # Like JPEG's: the statistic rises to 0.5 at 0.8 then falls back to 0.2 at the bound.
    def statistic(temporal: torch.Tensor) -> torch.Tensor:
        return torch.where(temporal <= 0.8, temporal * 0.625, 0.5 - (temporal - 0.8) * 0.3 / 0.19)

    target = torch.tensor([0.0, 0.25, 0.45, 0.9, -0.1, 0.3], dtype=torch.float64)
    curve = torch.stack([statistic(torch.full((OCTAVES,), r, dtype=torch.float64)) for r in SEARCH_GRID])
    coefficient = solve_coefficients(target, curve)
    expected = torch.tensor([0.0, 0.4, 0.72, 0.8, 0.0, 0.48], dtype=torch.float64)
    assert torch.allclose(coefficient, expected, atol=1e-6), coefficient
    assert float(coefficient.max()) <= MAX_COEFFICIENT


def _textured_still_clip(side: int = 256, seed: int = 0) -> torch.Tensor:
    """A dark still scene (4, 3, side, side): smooth shading with fine static texture of about 2 levels."""
    generator = torch.Generator().manual_seed(seed)
    y, x = torch.meshgrid(torch.linspace(0, 1, side), torch.linspace(0, 1, side), indexing="ij")
    scene = torch.stack([0.12 + 0.08 * x, 0.10 + 0.10 * y, 0.14 + 0.04 * (x + y)])
    scene = scene + 2.0 / 255 * torch.randn(3, side, side, generator=generator)
    return quantised(scene).expand(4, 3, side, side)


@pytest.mark.parametrize("rho", [0.3, 0.7])
def test_a_still_textured_clip_gives_back_its_coefficient(rho: float) -> None:
    found = estimate_spectrum(_noisy_still_clip(rho, 0.0), name="clip")
    temporal = found.values["temporal_correlation"]
    assert not [w for w in found.warnings if "frame-to-frame" in w], found.warnings
    assert torch.allclose(temporal[:3], torch.full((3,), rho, dtype=torch.float64), atol=0.12), temporal


def test_under_jpeg_the_coefficient_errs_low_not_high() -> None:
    # JPEG quality 80 on 6 levels, AR 0.6: the lag-one reading leans on a level fit JPEG bends, and the smaller
    # reading is kept (0.28-0.39 here; the harness's JPEG cases err by 0.10-0.17, mostly low).
    temporal = estimate_spectrum(_noisy_still_clip(0.6, 0.2), name="clip").values["temporal_correlation"]
    assert 0.15 < float(temporal[:3].mean()) < 0.72, temporal


def _noisy_still_clip(rho: float, compression: float) -> torch.Tensor:
    values = NoiseValues.from_values(
        {
            "level_curve": [6.0 / 255] * 24,
            "octave_power": [1.0] * 18,
            "temporal_correlation": [rho] * OCTAVES,
            "compression": compression,
        },
        dtype=torch.float32,
    )
    return quantised(add_noise(_textured_still_clip()[None], values, generator=torch.Generator().manual_seed(3))[0])


def _codec_like_clip(copied_share: float, gains: tuple[float, ...], side: int = 256, seed: int = 0) -> torch.Tensor:
    """(4, 3, side, side) a codec's output of a still noisy scene: independent noise of 6 levels in every frame
    before coding; from the second frame on, a share of the 16-px blocks (a macroblock) copied bit-identically from
    the frame before (skipped), the rest coded afresh; then each frame's gain (exposure) and 8-bit rounding."""
    fresh = _noisy_still_clip(0.0, 0.0)
    generator = torch.Generator().manual_seed(seed)
    coded = [fresh[0]]
    for frame in fresh[1:]:
        copied = torch.rand(side // 16, side // 16, generator=generator) < copied_share
        pixels = copied.repeat_interleave(16, 0).repeat_interleave(16, 1)
        coded.append(torch.where(pixels, coded[-1], frame))
    clip = torch.stack(coded)
    return quantised(clip * torch.tensor(gains)[:, None, None, None])


def _pooled_lag_one(clip: torch.Tensor) -> float:
    """The lag-1 correlation of the clip's noise (the clip minus its still scene), pooled over pairs and pixels."""
    noise = (clip - _textured_still_clip()).double()
    before, after = noise[:-1].flatten(), noise[1:].flatten()
    return float(torch.corrcoef(torch.stack([before, after]))[0, 1])


def test_skipped_shares_count_the_cells_a_codec_repeated() -> None:
    clip = _codec_like_clip(0.5, (1.0, 1.0, 1.0, 1.0))
    shares = skipped_shares(clip, torch.ones(256, 256))
    # Each pair repeats about half the 16-px blocks (256 of them, drawn): never by chance under 6 levels of noise.
    assert torch.all((shares > 0.38) & (shares < 0.62)), shares
    assert float(skipped_shares(_noisy_still_clip(0.0, 0.0), torch.ones(256, 256)).max()) == 0.0


def test_a_codec_that_skips_most_still_blocks_is_read_as_persistent_with_a_warning() -> None:
    # A codec at a high quantiser: 90% of the blocks repeated each frame, and an exposure step between frames 1 and 2
    # (3% gain: 1 to 2 levels on this scene) that moves every block. The ratio reads no AR(1) process here; the
    # lag-one reading, the pooled lag-1 correlation, must give the clip's persistence, not independent frames.
    clip = _codec_like_clip(0.9, (1.0, 1.0, 1.03, 1.03))
    # The truth on the same blocks without the gain (the gain's shading is no noise).
    truth = _pooled_lag_one(_codec_like_clip(0.9, (1.0, 1.0, 1.0, 1.0)))
    found = estimate_spectrum(clip, name="codec.mp4")
    temporal = found.values["temporal_correlation"]
    frame_warnings = [w for w in found.warnings if "frame" in w]
    assert any(w.startswith("codec.mp4: ") and "codec skipped" in w for w in frame_warnings), frame_warnings
    assert found.meta["persistence_source"].startswith("read"), found.meta
    assert abs(float(temporal[0]) - truth) < 0.2, (temporal, truth)
    assert float(temporal[:3].min()) > 0.5, temporal


def _synthetic_codec_clip(found_values: dict[str, torch.Tensor], seed: int = 5) -> torch.Tensor:
    """The still scene of the codec clips through the estimate's spectrum, JPEG and codec repeat, as a float clip
    (the whole-clip route of ``synthesize``), 8-bit levels."""
    values = NoiseValues.from_values(
        {
            name: found_values[name].to(torch.float32)
            for name in (
                "level_curve",
                "octave_power",
                "octave_correlation",
                "temporal_correlation",
                "compression",
                "codec_repeat",
            )
        },
        dtype=torch.float32,
    )
    result = synthesize(
        _textured_still_clip(),
        Profile(noise=values),
        darkening=None,
        generator=torch.Generator().manual_seed(seed),
    )
    assert isinstance(result.image, torch.Tensor)
    return quantised(result.image)


def test_a_codec_that_skips_half_the_blocks_is_put_back_with_its_pooled_correlation() -> None:
    # Half the blocks repeated, the rest coded afresh (independent): the pooled lag-1 is about 0.5. The profile
    # repeats that share itself and gives the coded cells' coefficient (about 0), so that its synthetic clip of the
    # same scene has the same pooled lag-1 (not the share counted twice).
    clip = _codec_like_clip(0.5, (1.0, 1.0, 1.0, 1.0))
    truth = _pooled_lag_one(clip)
    found = estimate_spectrum(clip, name="half")
    repeated = float(skipped_shares(clip, torch.ones(256, 256)).mean())
    assert abs(float(found.values["codec_repeat"][0]) - repeated) < 0.1, (found.values["codec_repeat"], repeated)
    assert float(found.values["temporal_correlation"][:3].max()) < 0.2, found.values["temporal_correlation"]
    synthetic = _pooled_lag_one(_synthetic_codec_clip(found.values))
    assert abs(synthetic - truth) < 0.15, (synthetic, truth)


def test_a_clip_whose_persistence_cannot_be_read_gets_the_video_prior_stated_in_meta(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The reference's still blocks change far more from one frame to the next than noise does (ten times the
    # lag-1 difference power of its own noise): neither statistic can read it. Only the reference's measurement is
    # changed; the simulations are the module's own.
    original = persistence_fit.difference_powers
    calls = []

    def changing_more_than_noise(frames: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        powers = original(frames, mask)
        calls.append(1)
        if len(calls) == 1:
            powers[0] = powers[0] * 10.0
        return powers

    monkeypatch.setattr(persistence_fit, "difference_powers", changing_more_than_noise)
    found = estimate_spectrum(_noisy_still_clip(0.3, 0.0), name="unreadable")
    assert torch.equal(found.values["temporal_correlation"], torch.tensor(VIDEO_PRIOR, dtype=torch.float64))
    assert found.meta["persistence_source"] == "video prior"
    assert "shared real night clips" in found.meta["persistence_prior"]
    warning = [w for w in found.warnings if "cannot be read" in w]
    assert len(warning) == 1 and "video prior" in warning[0] and warning[0].startswith("unreadable: "), warning


def test_a_codec_that_repeats_most_still_blocks_is_put_back_with_its_persistence() -> None:
    # 85% of the blocks copied each frame, the rest coded afresh: the profile repeats the share the estimate's own
    # still flat blocks show (rounded to 3 decimals in meta), and its synthetic clip of the same scene persists as
    # the clip does (the shared clip132, 82% repeated, real lag-1 1.00, read 0.68 before the codec repeat).
    clip = _codec_like_clip(0.85, (1.0, 1.0, 1.0, 1.0))
    repeated = float(skipped_shares(clip, torch.ones(256, 256)).mean())
    found = estimate_spectrum(clip, name="codec.mp4")
    assert repeated > 0.75, repeated
    share = sum(found.meta["persistence_skipped_share"]) / len(found.meta["persistence_skipped_share"])
    assert abs(float(found.values["codec_repeat"][0]) - share) < 2e-3, (found.values["codec_repeat"], share)
    assert found.meta["persistence_source"].startswith("read: the lag-one reading alone"), found.meta
    assert any("codec_repeat" in w for w in found.warnings), found.warnings
    synthetic = _pooled_lag_one(_synthetic_codec_clip(found.values))
    assert abs(synthetic - _pooled_lag_one(clip)) < 0.15, (synthetic, _pooled_lag_one(clip))


def test_a_pooled_reading_under_the_share_repeated_keeps_the_share_for_the_coded_cells() -> None:
    # clip132's case: 82% repeated and a pooled reading of 0.57 (fine) and 0.28 (coarser), which independent coded
    # cells cannot give; a reading at the share is independent coded cells (0), one above it their persistence.
    pooled = torch.tensor([0.57, 0.28, 0.82, 0.91, 0.82, 0.82], dtype=torch.float64)
    coded = persistence_fit._coded(pooled, 0.82)
    assert torch.allclose(coded, torch.tensor([0.82, 0.82, 0.0, 0.5, 0.0, 0.0], dtype=torch.float64), atol=1e-9)
    assert torch.equal(persistence_fit._coded(pooled, 0.0), pooled)
