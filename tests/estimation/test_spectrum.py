"""The blind spectral estimate (estimation/noise/spectrum.py): round trips of known spectra on drawn scenes, the
frame-to-frame correlation of clips, and the references that cannot show what is asked (warnings and priors)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from darksynth.estimation.noise.coarse_anchor import anchor_pool
from darksynth.estimation.noise.persistence_fit import VIDEO_PRIOR
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.noise.spectrum import estimate_spectrum
from darksynth.estimation.noise.spectrum_checks import compression_ambiguity
from darksynth.evaluation.measures.structure import band_powers, band_ratios
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.values import NoiseValues


def _scene(size: int = 320, seed: int = 0) -> torch.Tensor:
    """A dark scene (3, H, W) of smooth shading with a few flat-shaded rectangles: flat regions, edges between
    them, no fine texture."""
    generator = torch.Generator().manual_seed(seed)
    y, x = torch.meshgrid(torch.linspace(0, 1, size), torch.linspace(0, 1, size), indexing="ij")
    scene = torch.stack([0.10 + 0.10 * x, 0.08 + 0.12 * y, 0.12 + 0.05 * (x + y)])
    patch = size // 4
    for _ in range(6):
        top, left = (torch.randint(0, size - patch, (2,), generator=generator)).tolist()
        scene[:, top : top + patch, left : left + patch] = 0.05 + 0.2 * torch.rand(3, 1, 1, generator=generator)
    return scene


def _spectral(octave_power: list[float], level: float = 0.03, temporal: float = 0.0) -> NoiseValues:
    return NoiseValues.from_values(
        {
            "level_curve": [level] * 24,
            "octave_power": octave_power,
            "temporal_correlation": [temporal] * OCTAVES,
        },
        dtype=torch.float32,
    )


def _noisy(clean: torch.Tensor, values: NoiseValues, seed: int) -> torch.Tensor:
    """(T, 3, H, W) clean frames with the values' noise, on 8-bit levels."""
    return quantised(add_noise(clean[None], values, generator=torch.Generator().manual_seed(seed))[0])


# Coarse colour blotches over a fine brightness grain, as real sRGB noise has (docs/spectral-noise.md).
MOTTLED = [1.0, 0.3, 0.3] * 2 + [1.0, 1.5, 1.5] * 2 + [0.5, 4.0, 4.0] * 2


def _band_ratio(values: NoiseValues, truth: NoiseValues, clean: torch.Tensor) -> dict[str, np.ndarray]:
    synthetic = _noisy(clean[None], values, 91)[0] - clean
    real = _noisy(clean[None], truth, 92)[0] - clean
    as_array = lambda noise: noise.permute(1, 2, 0).double().numpy()  # noqa: E731
    return band_ratios(band_powers(as_array(synthetic)), band_powers(as_array(real)))


def test_a_mottled_spectrum_on_a_drawn_scene_comes_back_band_by_band() -> None:
    clean = quantised(_scene())
    truth = _spectral(MOTTLED)
    found = estimate_spectrum(_noisy(clean[None], truth, 0), name="mottled.png")
    assert not found.warnings, found.warnings
    ratio = _band_ratio(NoiseValues.from_values(found.values, dtype=torch.float32), truth, clean)
    # The three finer bands (2-16 px) within 25 %, colour's 16-32 px band within a factor of 2. The coarser bands
    # are the open shortfall of the blind route: the denoiser leaves nearly all of them in the scene it returns and
    # the octaves there barely move the statistics. Brightness at 16-32 px reads 0.38-0.42 here since the denoiser
    # compares patches in RGB (0.55-0.85 when it compared them in Lab, which lost the noise of dark references;
    # docs/spectral-noise.md); it and the 32-64 px band are not asserted.
    for component in ("brightness", "colour"):
        assert np.abs(np.log(ratio[component][:3])).max() < math.log(1.25), (component, ratio[component])
    assert abs(math.log(ratio["colour"][3])) < math.log(2.0), ratio["colour"]


# Colour that peaks at 11-22 px and falls at 45-90 px, as the phones' does (issue 39): the octaves the anchor reads
# (22 px) strong, the coarser ones, which a plane-detrended 32-px block barely holds, weak.
PEAKED = [1.0, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0, 4.0, 4.0, 1.0, 4.0, 4.0, 1.0, 1.0, 1.0, 1.0, 0.25, 0.25]


@pytest.mark.xfail(
    strict=True,
    reason="open (issue 39): the 45-90 px colour octaves are not read, they continue the finer octaves' rise; "
    "the colour 32-64 px band comes back 2.5x (16-32 px: 0.81x)",
)
def test_colour_that_falls_off_coarser_than_the_anchor_sees_is_not_carried_there() -> None:
    clean = quantised(_scene())
    truth = _spectral(PEAKED)
    found = estimate_spectrum(_noisy(clean[None], truth, 0), name="peaked.png")
    ratio = _band_ratio(NoiseValues.from_values(found.values, dtype=torch.float32), truth, clean)
    # The bar of issue 39 on the real pairs (at most 1.25) widened to 1.5 for one draw of one scene.
    assert np.abs(np.log(ratio["colour"][3:])).max() < math.log(1.5), ratio["colour"]


def test_octaves_the_reference_cannot_show_continue_the_measured_spectrum() -> None:
    # White noise on a flat-shaded scene: the statistics respond to the fine octaves in proportion; the coarsest,
    # whose band holds mostly the finer octaves' leakage, barely, and its fit would run away (on LOL references
    # it came out 1000x the others). It must continue the last measured octave instead, and say so.
    clean = quantised(_scene(256))
    found = estimate_spectrum(_noisy(clean[None], _spectral([1.0] * 18), 8), name="flat.png")
    response = found.meta["octave_response"]
    assert response[:2] == [1.0, 1.0] and response[2] > 0.35 and response[5] < 0.35, response
    power = found.values["octave_power"].reshape(OCTAVES, 3)
    first = next(k for k in range(2, OCTAVES) if response[k] < 0.35)
    # Brightness is held; colour continues its roll-off (rising at most by the cube root of the last two octaves),
    # scaled by the anchor read about planes (a white reference: near 1).
    assert torch.allclose(power[first:, 0], power[first - 1, 0].expand(OCTAVES - first), rtol=1e-9), power
    scale = torch.tensor(found.meta["coarse_octave_scale"][1:], dtype=torch.float64)
    assert bool(((scale > 0.5) & (scale < 2.0)).all()), scale
    held = power[first - 1, 1:].expand(OCTAVES - first, 2) * scale
    assert bool((power[first:, 1:] >= held * 0.99).all() and (power[first:, 1:] <= held * 1.6).all()), power
    assert "continue the finer octaves" in found.meta["octave_prior"]
    # What was read is stated per component: brightness up to the first octave it cannot show, colour one further
    # where the anchor read that one (up to 22 px; coarser octaves get no anchor).
    colour = first + 1 if anchor_pool(first) is not None else first
    assert found.meta["read_octaves"] == {"brightness": first, "colour": colour}, found.meta["read_octaves"]
    # White noise is measured about white: no octave above 2.5x or below 0.4x the mean (the 16-32 px octave is
    # read on about 20 flat 32-px blocks here, its sampling error alone is some 30 %; a runaway is 100x).
    assert float(power.max()) < 2.5 and float(power.min()) > 0.4, power


def test_a_single_image_gets_the_temporal_prior_and_says_so() -> None:
    clean = quantised(_scene())
    found = estimate_spectrum(_noisy(clean[None], _spectral([1.0] * 18), 1), name="one.png")
    assert torch.equal(found.values["temporal_correlation"], torch.zeros(OCTAVES, dtype=torch.float64))
    assert "prior 0" in found.meta["temporal_prior"]


def test_a_still_clip_gives_its_frame_to_frame_correlation() -> None:
    clean = quantised(_scene(256)).expand(4, 3, 256, 256)
    found = estimate_spectrum(_noisy(clean, _spectral([1.0] * 18, temporal=0.6), 2), name="clip")
    assert not found.warnings, found.warnings
    temporal = found.values["temporal_correlation"]
    # 2-16 px within 0.12; 16-32 px, which the frame differences read with each 32-px block's plane taken out (a
    # change of light), within 0.2.
    assert torch.allclose(temporal[:3], torch.full((3,), 0.6, dtype=torch.float64), atol=0.12), temporal
    assert abs(float(temporal[3]) - 0.6) < 0.2, temporal
    independent = estimate_spectrum(_noisy(clean, _spectral([1.0] * 18), 3), name="clip")
    assert independent.values["temporal_correlation"][:4].abs().max() < 0.1


def test_a_still_clip_whose_brightness_pulses_is_still_read_as_still() -> None:
    # Auto-exposure or flicker moves the whole frame by 3 levels a frame (the starlight video: 7 levels in 4
    # frames); no block moves, and the noise's persistence is read as in a steady clip.
    scene = quantised(_scene(256))
    clip = torch.stack([scene + 3.0 * t / 255 for t in range(4)])
    found = estimate_spectrum(_noisy(clip, _spectral([1.0] * 18, temporal=0.6), 2), name="flicker")
    assert not found.warnings, found.warnings
    temporal = found.values["temporal_correlation"]
    assert torch.allclose(temporal[:2], torch.full((2,), 0.6, dtype=torch.float64), atol=0.12), temporal


def test_a_clip_whose_camera_moves_in_every_frame_gets_the_prior_with_a_warning() -> None:
    # Coarse texture everywhere (a 24-px sinusoid of 25 levels), panned 8 px a frame: no block stays still.
    # (Flat regions would stay "still" under a pan and rightly show the sensor's noise persisting.)
    y, x = torch.meshgrid(torch.arange(320.0), torch.arange(320.0), indexing="ij")
    pattern = 0.15 + 0.05 * torch.sin(2 * math.pi * x / 24) * torch.cos(2 * math.pi * y / 24)
    scene = quantised(pattern.expand(3, 320, 320))
    moving = torch.stack([scene[:, 8 * t : 8 * t + 256, 8 * t : 8 * t + 256] for t in range(4)])
    found = estimate_spectrum(_noisy(moving, _spectral([1.0] * 18, temporal=0.6), 4), name="pan.mp4")
    assert any(w.startswith("pan.mp4: only") and "video prior" in w for w in found.warnings), found.warnings
    assert torch.equal(found.values["temporal_correlation"], torch.tensor(VIDEO_PRIOR, dtype=torch.float64))
    assert found.meta["persistence_prior"].startswith(str(list(VIDEO_PRIOR)))


def test_a_clip_of_two_frames_is_read_on_its_one_pair_and_says_so() -> None:
    clean = quantised(_scene(256)).expand(2, 3, 256, 256)
    found = estimate_spectrum(_noisy(clean, _spectral([1.0] * 18, temporal=0.6), 5), name="two")
    assert any(w.startswith("two: 2 frames") for w in found.warnings), found.warnings
    assert 0.4 < float(found.values["temporal_correlation"][:4].mean()) < 0.8


def test_a_reference_with_no_flat_region_warns_that_texture_may_be_read_as_noise() -> None:
    # A mosaic of 8-px tiles of random brightness (up to 75 levels apart) everywhere, as foliage or a crowd.
    generator = torch.Generator().manual_seed(6)
    tiles = 0.05 + 0.3 * torch.rand(1, 1, 32, 32, generator=generator)
    mosaic = quantised(torch.nn.functional.interpolate(tiles, scale_factor=8, mode="nearest")[0].expand(3, 256, 256))
    found = estimate_spectrum(_noisy(mosaic[None], _spectral([1.0] * 18, level=0.01), 6), name="bark.jpg")
    assert any(w.startswith("bark.jpg: no flat region") for w in found.warnings), found.warnings


def test_a_clean_daylight_photo_gets_next_to_no_noise() -> None:
    # Bright, noise-free apart from its 8-bit rounding (std 0.29 levels): the measured curve stays about one 8-bit
    # level or below (0.6-1.0 here: the rounding of smooth shading is read as noise), invisible on a bright image,
    # where estimate warns besides that the reference is not a low-light one.
    clean = quantised(0.55 + 0.4 * (_scene() - 0.12))
    found = estimate_spectrum(clean[None], name="day.jpg")
    assert float(found.values["level_curve"].max()) < 1.25 / 255, found.values["level_curve"]


@pytest.mark.parametrize("side", [64, 100])
def test_small_references_are_measured_without_error(side: int) -> None:
    clean = quantised(_scene(side))
    found = estimate_spectrum(_noisy(clean[None], _spectral([1.0] * 18), 7), name="small.png")
    curve = found.values["level_curve"]
    assert bool(torch.isfinite(curve).all()) and 0.5 * 0.03 < float(curve.median()) < 2.0 * 0.03


@pytest.mark.parametrize(("height", "width", "threads"), [(384, 384, 2), (97, 130, 2), (61, 64, 3), (200, 90, 1)])
def test_non_local_means_in_bands_of_rows_gives_the_whole_frames_result(height: int, width: int, threads: int) -> None:
    import cv2

    from darksynth.estimation.noise import nonlocal_means

    generator = torch.Generator().manual_seed(height)
    frames = (torch.rand(2, 3, height, width, generator=generator) * 0.4 + 0.3).clamp(0, 1)
    previous = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        banded = nonlocal_means.nlm_denoise(frames, 9.0)
    finally:
        torch.set_num_threads(previous)
    for frame, result in zip(frames, banded, strict=True):
        image = nonlocal_means._to_uint8(frame)
        whole = cv2.fastNlMeansDenoising(image, None, 9.0, nonlocal_means.NLM_TEMPLATE, nonlocal_means.NLM_SEARCH)
        assert torch.equal(result, torch.from_numpy(whole).permute(2, 0, 1).to(torch.float32) / 255.0)


def _white_level_curve(shot: float, read: float) -> list[float]:
    from darksynth.noise.spectral import LEVEL_KNOTS

    return [math.sqrt(shot**2 * x + read**2) for _ in range(3) for x in LEVEL_KNOTS]


def test_a_dark_reference_that_clips_its_noise_keeps_its_level() -> None:
    # Mean level 0.05 under noise of 6-7 levels: a third of the pixels at 0. The denoiser was set from the crushed
    # blocks and the level came back 10x too weak before the measurement left clipped blocks out.
    scene = 0.25 * _scene(seed=3)
    truth_curve = torch.tensor(_white_level_curve(0.072, 0.023)).reshape(3, 8)
    truth = NoiseValues.from_values({"level_curve": truth_curve.flatten()}, dtype=torch.float32)
    noisy = _noisy(scene[None], truth, 5)
    assert float((noisy <= 0.5 / 255).float().mean()) > 0.1
    found = estimate_spectrum(noisy, name="dark", prior_curve=truth_curve * 1.3)
    estimated = NoiseValues.from_values(found.values, dtype=torch.float32)
    real = _noisy(scene[None], truth, 11)[0] - scene
    synthetic = _noisy(scene[None], estimated, 12)[0] - scene
    assert 0.8 < float(synthetic.std() / real.std()) < 1.25


def test_a_crushed_black_reference_with_a_few_lamps_takes_the_network_level_and_says_so() -> None:
    frame = torch.zeros(3, 256, 256)
    frame[:, 100:140, 60:90] = 1.0  # a lamp, saturated
    frame[:, 30:50, 200:230] = 0.9
    prior = torch.full((3, 8), 0.02)
    found = estimate_spectrum(frame[None], name="night.jpg", prior_curve=prior)
    assert any("night.jpg" in w and "could not be measured" in w for w in found.warnings)
    assert torch.allclose(found.values["level_curve"].reshape(3, 8).float(), prior)


def test_a_level_that_disagrees_with_the_network_by_more_than_3x_is_named_in_a_warning() -> None:
    scene = _scene(seed=4)
    noisy = _noisy(scene[None], _spectral([1.0] * 18, level=0.02), 3)
    found = estimate_spectrum(noisy, name="ref.png", prior_curve=torch.full((3, 8), 0.2))
    assert any("ref.png" in w and "differ by" in w for w in found.warnings)
    agreeing = estimate_spectrum(noisy, name="ref.png", prior_curve=torch.full((3, 8), 0.02))
    assert not any("differ by" in w for w in agreeing.warnings)


def test_coarse_colour_the_anchor_cannot_read_takes_the_prior_and_says_so() -> None:
    # A still clip with a tenth of a level of noise: the variance about the blocks' planes is the rounding of the
    # scene, which no coarse noise moves, and the anchor ran one colour component to its upper bound and the other
    # to its lower (a phone clip's crushed letterbox: 100x and 0.1x). Those are numbers the fit ran into, not
    # readings: the finer octaves continue, and a warning says which components. (384 px: on 256 px the probe finds
    # the 22-px octave readable, and 45 px and up are not anchored.)
    clean = (quantised(_scene(384)) * 0.3).expand(4, 3, 384, 384)
    found = estimate_spectrum(_noisy(clean, _spectral([1.0] * 18, level=0.0005), 3), name="dim.mov")
    released = found.meta["coarse_octave_prior"]
    assert released and set(released) <= {"red-green", "blue-yellow"}, released
    scale = dict(zip(["brightness", "red-green", "blue-yellow"], found.meta["coarse_octave_scale"], strict=True))
    assert all(scale[component] == 1.0 for component in released), (scale, released)
    assert any(scale in (0.1, 100.0) for scale in released.values()), released
    # Released, the anchor read nothing: colour is read no further than brightness (and less where the JPEG stage
    # the fit chose rounds the colour away: this reference's noise is a tenth of a level).
    read = found.meta["read_octaves"]
    assert read["colour"] <= read["brightness"] < OCTAVES, read
    assert read["colour"] == read["brightness"] or "colour_prior" in found.meta, found.meta
    assert any("dim.mov: the coarse" in w and "bound" in w for w in found.warnings), found.warnings
    # Held at the bounds, the coarse colour octaves carried 400x the brightness power; continued, they keep about
    # the finer octaves' colour-to-brightness ratio (7x in the finest here: the rounding of a coloured scene).
    power = found.values["octave_power"].reshape(OCTAVES, 3)
    assert float((power[3:, 1:] / power[3:, :1]).max()) < 20.0, power


def test_jpeg_strengths_that_fit_alike_with_different_levels_are_reported_as_an_uncertain_level() -> None:
    # Weak noise under a strong JPEG reads like weaker noise under none: when both fit within 1.5x of the best
    # mismatch and their levels differ by more than 1.5x, the level is uncertain by that much.
    meta = {
        "compression_scores": {"0.0": 0.094, "0.2": 0.088, "0.4": 0.178},
        "level_by_compression_8bit": {"0.0": 1.1, "0.2": 1.4, "0.4": 2.3},
    }
    assert compression_ambiguity(meta) is None  # 0.4 fits twice as badly; 0.0 and 0.2 agree within 1.5x
    meta["compression_scores"]["0.4"] = 0.12
    assert compression_ambiguity(meta) == (["0.0", "0.2", "0.4"], 1.1, 2.3)


@pytest.mark.parametrize(("level", "quality", "readable_octave"), [(0.008, 75, None), (0.03, 80, 2)])
def test_colour_a_jpeg_rounds_away_is_said_not_read(level: float, quality: int, readable_octave: int | None) -> None:
    # White noise of 2 levels under a quality-75 4:2:0 JPEG: through it the colour statistics follow none of the
    # colour octaves, and the estimate says so. At 7.6 levels under quality 80 the 11-px colour octave passes
    # (and the probe sees it) but the 5.7-px one does not: colour is read no further than the 2.8-px octave.
    from darksynth.noise.compression import jpeg_compress

    truth = _spectral([1.0, 1.0, 1.0] * OCTAVES, level=level)
    reference = jpeg_compress(_noisy(_scene(256, seed=3)[None], truth, 5), quality)
    meta = estimate_spectrum(reference, name="drawn.jpg").meta
    assert meta["compression_chosen"] > 0.0, meta["compression_scores"]
    responses = meta["colour_response_through_compression"]
    assert meta["read_octaves"]["colour"] == 1 and "colour_prior" in meta, responses
    assert responses[1] < 0.35, responses
    if readable_octave is None:
        assert max(responses[1:]) < 0.35, responses
    else:
        assert responses[readable_octave] > 0.5, responses


def test_without_a_jpeg_stage_colour_is_not_probed_through_one() -> None:
    meta = estimate_spectrum(_noisy(_scene(256, seed=3)[None], _spectral([1.0] * 3 * OCTAVES, level=0.02), 5)).meta
    assert meta["compression_chosen"] == 0.0
    assert "colour_response_through_compression" not in meta and "colour_prior" not in meta
    assert meta["read_octaves"]["colour"] > 1
