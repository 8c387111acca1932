"""The shutter and flicker estimate: round trips through darksynth's own synthesis, and odd input."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import torch
from PIL import Image

import darksynth
from darksynth.estimation.light.cross_spectra import phase_ramp
from darksynth.estimation.light.motion import EXPOSURE_FRACTION_PRIOR, MIN_SPEED, MotionEstimate, estimate_motion
from darksynth.estimation.light.shutter_confidence import (
    AMBIGUOUS_PEAK,
    BLOCKY,
    MIN_CONFIDENCE,
    MIN_CONFIDENCE_COMPRESSED,
    compression_blockiness,
    motion_ambiguity,
    reading_confidence,
    resampled_readings,
)
from darksynth.estimation.reference import load_reference
from darksynth.light.darkening import Darkening, darken
from darksynth.profile import default_profile_path
from tests.script_modules import load_script

CLIPS = Path(__file__).resolve().parents[3] / "shared" / "data" / "real-lowlight" / "clips"

HEIGHT, WIDTH = 256, 384
DARKENING = Darkening(alpha=0.2, gamma=0.6)


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def natural_texture(seed: int, height: int = HEIGHT, width: int = WIDTH) -> np.ndarray:
    """A periodic grey texture (H, W) in sRGB [0, 1] with a natural 1/f amplitude spectrum."""
    rng = np.random.default_rng(seed)
    ky = np.fft.fftfreq(height)[:, None]
    kx = np.fft.fftfreq(width)[None, :]
    radius = np.hypot(ky, kx)
    amplitude = np.where(radius > 0, 1.0 / np.maximum(radius, 1.0 / max(height, width)), 0.0)
    phase = np.exp(2j * np.pi * rng.random((height, width)))
    field = np.fft.ifft2(amplitude * phase).real
    field = (field - field.mean()) / field.std()
    return np.clip(0.5 + 0.17 * field, 0.0, 1.0)


def moving_clip(texture: np.ndarray, velocity: tuple[float, float], exposure: float, frames: int) -> np.ndarray:
    """Frames (T, H, W) of a texture translating by ``velocity`` (dy, dx) px/frame, in sRGB [0, 1].

    Each frame is the mean, in linear light, of 64 copies shifted over the window of ``exposure`` frame intervals
    centred on the frame: the same sum done as one filter in the Fourier domain, where a sub-pixel shift of the
    periodic texture is exact.
    """
    height, width = texture.shape
    spectrum = np.fft.fft2(srgb_to_linear(texture))
    ky = np.fft.fftfreq(height)[:, None]
    kx = np.fft.fftfreq(width)[None, :]
    copies = 64
    offsets = exposure * ((np.arange(copies) + 0.5) / copies - 0.5)
    projection = ky * velocity[0] + kx * velocity[1]
    # The mean of the shifted copies of one frame is the frame's shift times the mean of the offsets' shifts.
    window = np.zeros((height, width), complex)
    for offset in offsets:
        window += np.exp(-2j * np.pi * projection * offset) / copies
    out = []
    for t in range(frames):
        shifted = spectrum * window * np.exp(-2j * np.pi * projection * t)
        out.append(linear_to_srgb(np.fft.ifft2(shifted).real))
    return np.stack(out)


def low_light(frames: np.ndarray, seed: int) -> torch.Tensor:
    """Grey frames (T, H, W) in [0, 1] -> their darkened, noisy version (T, 3, H, W) in [0, 1], 8-bit levels."""
    clean = torch.from_numpy(np.round(frames * 255)).to(torch.uint8)[:, None].expand(-1, 3, -1, -1).contiguous()
    profile = darksynth.load_profile(default_profile_path())
    result = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(seed), darkening=DARKENING)
    return result.image.to(torch.float32) / 255.0


def flickering_still(gains: np.ndarray, seed: int) -> torch.Tensor:
    """A still textured scene whose darkened signal is multiplied by ``gains[t]`` before the noise."""
    texture = torch.from_numpy(natural_texture(seed, 192, 256)).to(torch.float32)
    signal = darken(texture[None, None].expand(len(gains), 3, -1, -1), DARKENING.alpha, DARKENING.gamma)
    signal = signal * torch.from_numpy(gains).to(torch.float32)[:, None, None, None]
    profile = darksynth.load_profile(default_profile_path())
    result = darksynth.synthesize(
        signal.clamp(0, 1), profile, generator=torch.Generator().manual_seed(seed), darkening=None
    )
    return result.image.to(torch.float32)


def ar1_gains(std: float, rho: float, frames: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = np.empty(frames)
    z[0] = rng.standard_normal()
    for t in range(1, frames):
        z[t] = rho * z[t - 1] + math.sqrt(1 - rho**2) * rng.standard_normal()
    return 1.0 + std * z


ROUND_TRIP_CASES = [
    (speed, exposure, diagonal) for speed in (1, 3, 6, 12) for exposure in (0.25, 0.5, 1.0) for diagonal in (False,)
] + [(6, 0.5, True), (3, 1.0, True)]


def round_trip(speed: float, exposure: float, diagonal: bool, seed: int) -> MotionEstimate:
    velocity = (speed / math.sqrt(2), speed / math.sqrt(2)) if diagonal else (0.0, float(speed))
    frames = moving_clip(natural_texture(seed), velocity, exposure, 8)
    return estimate_motion(low_light(frames, seed))


def test_the_exposure_fraction_round_trips() -> None:
    """Median error over speeds 1-12 px/frame (one diagonal case) and shutters 1/4, 1/2 and 1 within 0.15."""
    errors = []
    for seed, (speed, exposure, diagonal) in enumerate(ROUND_TRIP_CASES):
        found = round_trip(speed, exposure, diagonal, seed)
        if speed < MIN_SPEED:
            # Too slow to read a box of a fraction of a pixel: the prior, said so.
            assert not found.exposure_measured and found.exposure_fraction == EXPOSURE_FRACTION_PRIOR
            assert any(str(MIN_SPEED) in note for note in found.notes)
        else:
            assert found.exposure_measured, (speed, exposure, found.notes)
            assert found.displacement == pytest.approx(speed, rel=0.1)
        errors.append(abs(found.exposure_fraction - exposure))
    assert float(np.median(errors)) <= 0.15, errors
    # The fast cases, where the box is several px long, are each within 0.15.
    assert max(e for e, (speed, *_) in zip(errors, ROUND_TRIP_CASES, strict=True) if speed >= 3) <= 0.15, errors


def test_a_long_and_a_short_shutter_are_told_apart() -> None:
    """The control for the round trip: the same motion with s = 0.25 and s = 1 gives estimates far apart."""
    short = round_trip(6, 0.25, False, 20).exposure_fraction
    long = round_trip(6, 1.0, False, 20).exposure_fraction
    assert long - short > 0.5


def test_a_blur_longer_than_a_shutter_gives_is_read_as_it_is_with_a_note() -> None:
    """A camera blending frames over time smears motion beyond a full-interval shutter: the estimate says how far
    (a grid ending at 1 read such clips as exactly 1) and notes that it is beyond a shutter."""
    found = round_trip(6, 1.6, False, 21)
    assert found.exposure_measured
    assert found.exposure_fraction == pytest.approx(1.6, abs=0.2)
    assert any("longer than a shutter open for the whole frame interval" in note for note in found.notes)
    within = round_trip(6, 0.9, False, 22)
    assert within.exposure_fraction < 1.05 and not any("longer than" in note for note in within.notes)


def with_a_pattern_that_stays(reference: torch.Tensor, std: float, seed: int) -> torch.Tensor:
    """``reference`` plus one noise pattern (3-px grain) the same in every frame: what a phone's temporal noise
    reduction or a codec's carried-over prediction leaves."""
    rng = np.random.default_rng(seed)
    grain = torch.from_numpy(rng.normal(0.0, 1.0, reference.shape[1:]).astype(np.float32))
    grain = torch.nn.functional.avg_pool2d(grain[None], 3, 1, 1)[0]
    return (reference + std * grain / grain.std()).clamp(0, 1)


@pytest.mark.parametrize(("speed", "exposure"), [(3.0, 0.5), (6.0, 1.0)])
def test_noise_that_stays_in_place_is_not_read_as_blur(speed: float, exposure: float) -> None:
    """A pattern as strong as the independent noise (half the noise power persists from frame to frame, as the
    shared phone clips measure): it stays still while the blocks follow the scene, and before it was modelled it
    read as a shutter of 1.5 at 3 px/frame and s = 0.5."""
    frames = moving_clip(natural_texture(7), (0.0, speed), exposure, 6)
    found = estimate_motion(with_a_pattern_that_stays(low_light(frames, 7), 0.021, 107))
    assert found.exposure_measured
    assert found.exposure_fraction == pytest.approx(exposure, abs=0.2)
    assert found.displacement == pytest.approx(speed, rel=0.2)


def test_a_still_scene_gives_the_prior_with_a_note() -> None:
    frames = np.repeat(natural_texture(3)[None], 6, axis=0)
    found = estimate_motion(low_light(frames, 3))
    assert not found.exposure_measured
    assert found.exposure_fraction == EXPOSURE_FRACTION_PRIOR
    assert found.moving_share < 0.01
    assert any("no motion" in note and f"prior {EXPOSURE_FRACTION_PRIOR}" in note for note in found.notes)
    assert found.to_meta()["exposure_prior"] == EXPOSURE_FRACTION_PRIOR


def test_one_frame_gives_the_priors() -> None:
    found = estimate_motion(low_light(natural_texture(4)[None], 4))
    assert not found.exposure_measured and not found.flicker_measured
    assert (found.exposure_fraction, found.flicker, found.flicker_correlation) == (EXPOSURE_FRACTION_PRIOR, 0.0, 0.0)
    assert len(found.notes) == 2


@pytest.mark.parametrize(
    "reference",
    [
        torch.zeros(5, 3, 64, 64),
        torch.zeros(1, 3, 40, 40),
        torch.rand(4, 3, 40, 40, generator=torch.Generator().manual_seed(0)),
        torch.full((3, 3, 48, 80), float("nan")),
    ],
    ids=["black", "one-tiny", "tiny-noise", "nan"],
)
def test_odd_input_gives_finite_priors(reference: torch.Tensor) -> None:
    found = estimate_motion(reference)
    meta = found.to_meta()
    assert not found.exposure_measured
    assert found.exposure_fraction == EXPOSURE_FRACTION_PRIOR
    assert all(math.isfinite(v) for v in (found.flicker, found.flicker_correlation, found.displacement))
    assert found.notes and meta["notes"] == list(found.notes)


def test_a_scene_cut_is_not_blurred_across() -> None:
    """Two unrelated moving patterns: no pair spans the cut, and the shutter is still found on both sides."""
    before = moving_clip(natural_texture(5), (0.0, 6.0), 0.5, 4)
    after = moving_clip(natural_texture(6), (0.0, 6.0), 0.5, 4)
    found = estimate_motion(low_light(np.concatenate([before, after]), 5))
    assert found.pairs == 6
    assert found.exposure_measured
    assert abs(found.exposure_fraction - 0.5) <= 0.1


def test_a_black_frame_in_the_middle_is_skipped() -> None:
    frames = moving_clip(natural_texture(7), (0.0, 6.0), 1.0, 6)
    reference = low_light(frames, 7)
    reference[3] = 0
    found = estimate_motion(reference)
    assert found.pairs == 3
    assert abs(found.exposure_fraction - 1.0) <= 0.15


@pytest.mark.parametrize("std, rho", [(0.05, 0.6), (0.05, 0.0)])
def test_the_flicker_round_trips(std: float, rho: float) -> None:
    """Over three seeds of 48 frames: the mean std within 25 % and the mean correlation within 0.25."""
    found = [estimate_motion(flickering_still(ar1_gains(std, rho, 48, seed), seed)) for seed in range(3)]
    assert all(f.flicker_measured and f.flicker_frames == 48 for f in found)
    assert float(np.mean([f.flicker for f in found])) == pytest.approx(std, rel=0.25)
    assert abs(float(np.mean([f.flicker_correlation for f in found])) - rho) <= 0.25


def test_no_flicker_reads_as_none() -> None:
    """Without a gain the noise, including its frame-wide offsets, is not read as flicker."""
    for seed in range(3):
        found = estimate_motion(flickering_still(np.ones(48), seed))
        assert found.flicker_measured
        assert found.flicker < 0.01


def test_the_meta_is_json_ready() -> None:
    found = estimate_motion(flickering_still(ar1_gains(0.05, 0.6, 8, 0), 0))
    meta = json.loads(json.dumps(found.to_meta()))
    assert meta["flicker_measured"] is True and meta["flicker_prior"] is None
    assert meta["exposure_measured"] is False and meta["exposure_prior"] == EXPOSURE_FRACTION_PRIOR


@pytest.mark.skipif(not (CLIPS / "clip474").is_dir(), reason="../shared/data/real-lowlight is absent")
def test_a_reading_its_halves_do_not_share_is_refused() -> None:
    """clip474 (a phone clip at 2.7 px/frame): the alternate halves of its moving blocks read s = 0 and s = 2, so
    no one shutter explains it; the prior stands, with a note that says so. clip1021 (7 px/frame) keeps its
    reading."""
    found = estimate_motion(load_reference(CLIPS / "clip474", clip=True))
    assert not found.exposure_measured and found.exposure_fraction == EXPOSURE_FRACTION_PRIOR
    assert any("two halves of the moving blocks" in note for note in found.notes), found.notes
    kept = estimate_motion(load_reference(CLIPS / "clip1021", clip=True))
    assert kept.exposure_measured and 0.3 < kept.exposure_fraction < 0.7


def test_a_well_textured_clip_reads_its_shutter_with_high_confidence() -> None:
    found = round_trip(6, 0.5, False, 30)
    meta = found.to_meta()
    assert found.exposure_measured
    assert found.exposure_fraction == pytest.approx(0.5, abs=0.15)
    assert meta["exposure_confidence"] >= 0.9
    assert meta["exposure_checks"]["contrast_along_motion"] > 1.0


def test_a_textureless_moving_clip_falls_back_to_the_prior_with_a_note() -> None:
    """A flat grey field whose only texture is far below the noise, panning at 6 px/frame: nothing to read a blur
    from, so the prior, with a note, and no confidence."""
    texture = 0.5 + 0.002 * (natural_texture(31) - 0.5)
    found = estimate_motion(low_light(moving_clip(texture, (0.0, 6.0), 0.5, 6), 31))
    assert not found.exposure_measured
    assert found.exposure_fraction == EXPOSURE_FRACTION_PRIOR
    assert found.to_meta()["exposure_confidence"] < MIN_CONFIDENCE
    exposure_notes = [note for note in found.notes if "exposure fraction" in note]
    assert len(exposure_notes) == 1 and f"prior {EXPOSURE_FRACTION_PRIOR}" in exposure_notes[0]


def test_the_confidence_is_the_share_of_resampled_readings_near_the_reading() -> None:
    """Six blocks that all peak at one s give confidence 1; six that peak at s spread over [0, 2] (their pooled
    reading about 1, its bootstrap spread about 0.35) give a low one."""
    grid = np.linspace(0.0, 2.0, 41)
    agreeing = np.stack([-((grid - 0.5) ** 2)] * 6, axis=1)
    peaks = np.array([0.0, 0.0, 0.4, 1.6, 2.0, 2.0])
    scattered = -((grid[:, None] - peaks[None]) ** 2)
    cells = np.arange(6)
    assert reading_confidence(resampled_readings(agreeing, grid, cells), 0.5) == 1.0
    best = float(grid[int(np.argmax(scattered.sum(axis=1)))])
    assert reading_confidence(resampled_readings(scattered, grid, cells), best) < MIN_CONFIDENCE


def block_pair_product(pattern: np.ndarray, shift: int) -> np.ndarray:
    """The cross spectrum of a 64-px block of ``pattern`` and the block ``shift`` px to its right, aligned."""
    window = np.outer(np.hanning(64), np.hanning(64))
    first, second = pattern[:64, :64], pattern[:64, shift : shift + 64]
    spectra = [np.fft.rfft2((b - b.mean()) * window) for b in (first, second)]
    return (spectra[0] * np.conj(spectra[1]) * phase_ramp(np.array([[0.0, -shift]]), 64)[0])[None]


def test_a_periodic_texture_is_seen_as_ambiguous_and_a_natural_one_is_not() -> None:
    y, x = np.mgrid[0:64, 0:96]
    stripes = np.sin(2 * np.pi * x / 9.0) + 0.5 * np.sin(2 * np.pi * y / 13.0)
    motion = np.array([[0.0, 4.0]])
    assert motion_ambiguity(block_pair_product(stripes, 4), motion)[0] >= AMBIGUOUS_PEAK
    natural = natural_texture(8, 64, 96)
    assert motion_ambiguity(block_pair_product(natural, 4), motion)[0] < AMBIGUOUS_PEAK


HARNESS = Path(__file__).resolve().parents[2] / "scripts" / "light" / "shutter_harness.py"
SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"
HARNESS_SEEDS = range(200, 212)
"""Harness cases of the develop part beyond those the confidence was developed on (seeds 0-159)."""


def shutter_harness() -> Any:
    """scripts/light/shutter_harness.py as a module."""
    return load_script(HARNESS)


def harness_rows(harness: Any, seeds: Iterable[int]) -> list[dict[str, Any]]:
    """The harness's develop cases of these seeds, run."""
    paths = harness.textures(SHARED, "develop")
    sizes = {p: tuple(np.asarray(Image.open(p)).shape[:2]) for p in paths}
    return [harness.run_case(harness.draw_case(seed, SHARED, paths, sizes), SHARED) for seed in seeds]


def test_jpeg_blocks_are_seen_and_a_texture_without_them_is_not() -> None:
    """A dark texture (levels 0-38, where the quantization steps are large against the content) compressed at
    quality 90 reads well above BLOCKY; the same frames uncompressed about 1."""
    frames = 0.15 * np.stack([natural_texture(seed, 192, 256) for seed in (40, 41)])
    plain = compression_blockiness(frames)
    levels = np.round(frames * 255).astype(np.uint8)
    quality = [cv2.IMWRITE_JPEG_QUALITY, 90]
    compressed = np.stack([cv2.imdecode(cv2.imencode(".jpg", f, quality)[1], cv2.IMREAD_UNCHANGED) for f in levels])
    assert plain < BLOCKY < compression_blockiness(compressed.astype(np.float32) / 255.0)


@pytest.mark.skipif(not (SHARED / "clean" / "images" / "kodak24").is_dir(), reason="../shared/data is absent")
def test_a_jpeg_reading_the_blocks_agree_on_less_than_unanimously_falls_back() -> None:
    """Harness case 49 (kodim04, 12.7 px/frame, nearly noise-free, JPEG quality 83): the blocks read s = 0.07 for
    a true 0.78 (JPEG's quantization fills the frequencies the long blur emptied) with confidence 0.97, enough
    without JPEG; with JPEG's blocks seen, the prior stands and the note says why. Case 1 (cbsd68/147091, 19
    px/frame, JPEG quality 71, s = 0.83), whose resampled readings all agree, still reads."""
    missed, kept = harness_rows(shutter_harness(), (49, 1))
    assert not missed["measured"] and missed["read"] == EXPOSURE_FRACTION_PRIOR
    assert missed["checks"]["jpeg_blockiness"] > BLOCKY
    assert any("JPEG's 8-px blocks" in note for note in missed["notes"]), missed["notes"]
    assert kept["measured"] and kept["confidence"] >= MIN_CONFIDENCE_COMPRESSED
    assert kept["read"] == pytest.approx(kept["exposure"], abs=0.15)


@pytest.mark.slow
@pytest.mark.skipif(not (SHARED / "clean" / "images" / "kodak24").is_dir(), reason="../shared/data is absent")
def test_the_shutter_harness_cases_read_within_bounds_or_fall_back() -> None:
    """Twelve fixed cases of scripts/light/shutter_harness.py (real textures, dark, noisy, 2-20 px/frame): none is off
    by more than 0.5 without falling back, and the median error of those read is within 0.15."""
    harness = shutter_harness()
    rows = harness_rows(harness, HARNESS_SEEDS)
    totals = harness.summary(rows)
    assert totals["off_without_fallback"] == 0, rows
    assert totals["median_error"] <= 0.15, totals
    assert totals["read"] >= len(rows) // 2, totals
