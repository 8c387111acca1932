"""estimate(): median over crops, percentile ranges, warnings and meta, with tiny untrained or rigged networks."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.light.darkening import darken
from darksynth.light.tones import luminance_quantiles, tone_quantiles
from darksynth.models.den import DEN
from darksynth.noise.components import model_parameters, noise_parameter, vector_size
from darksynth.noise.values import NoiseValues, model_vector
from darksynth.profile import validate_profile


def _reference(
    frames: int, height: int, width: int, *, mean: float = 0.1, seed: int = 0, banding: float = 0.0
) -> torch.Tensor:
    """Dark frames with noise that grows from left to right, so that crops differ, and with ``banding``, a
    column offset of that std (so that the column components are measured present and kept)."""
    generator = torch.Generator().manual_seed(seed)
    strength = torch.linspace(0.005, 0.08, width)
    noise = torch.randn(frames, 3, height, width, generator=generator) * strength
    columns = torch.randn(frames, 3, 1, width, generator=generator) * banding
    return (mean + noise + columns).clamp(0, 1)


def _profile_vector(result_noise: NoiseValues) -> np.ndarray:
    return model_vector(result_noise).numpy()


def test_profile_is_the_median_over_crops_and_ranges_the_10th_to_90th_percentile(
    tiny_model: Callable[..., DEN],
) -> None:
    # 1 frame of 48 x 240: side 48, a 1 x 5 grid, so an odd number of crops and an unambiguous median.
    result = estimate(_reference(1, 48, 240, banding=0.1), tiny_model(head_width=16))
    assert result.profile.meta["columns"]["decision"] == "present"
    per_crop = model_vector(result.per_crop).numpy()
    assert per_crop.shape == (5, vector_size())
    assert result.profile.meta["crops"] == 5
    assert np.ptp(per_crop, axis=0).min() > 0  # the crops really disagree
    np.testing.assert_allclose(_profile_vector(result.profile.noise), np.median(per_crop, axis=0), rtol=1e-6)
    low, high = np.percentile(per_crop, [10, 90], axis=0)
    ranges = np.array([pair for p in model_parameters("srgb") for pair in result.profile.ranges[p.name]])
    np.testing.assert_allclose(ranges[:, 0], low, rtol=1e-5)
    np.testing.assert_allclose(ranges[:, 1], high, rtol=1e-5)
    profile = _profile_vector(result.profile.noise)
    assert (ranges[:, 0] <= profile).all() and (profile <= ranges[:, 1]).all()
    validate_profile(result.profile)


def test_even_number_of_crops_gives_a_value_between_the_middle_two(tiny_model: Callable[..., DEN]) -> None:
    # 8 frames of 48 x 144: two windows of four frames times a 1 x 3 grid.
    result = estimate(_reference(8, 48, 144, banding=0.1), tiny_model())
    assert result.profile.meta["columns"]["decision"] == "present"
    per_crop = np.sort(model_vector(result.per_crop).numpy(), axis=0)
    assert len(per_crop) == 6
    profile = _profile_vector(result.profile.noise)
    assert (profile >= per_crop[2] - 1e-7).all() and (profile <= per_crop[3] + 1e-7).all()
    for name, values in result.profile.noise.items():
        if name not in result.profile.ranges:
            continue  # the spectrum, which the network does not estimate
        for (a, b), value in zip(result.profile.ranges[name], values, strict=True):
            assert a <= value <= b
    darkening = result.profile.darkening
    assert darkening is not None
    for name in ("alpha", "gamma"):
        ((a, b),) = result.profile.ranges[name]
        assert a <= getattr(darkening, name) <= b


def _dark_scene(frames: int, alphas: list[float], gamma: float = 0.5) -> torch.Tensor:
    """A textured scene with a wide spread of tones, darkened frame by frame with the given alphas."""
    generator = torch.Generator().manual_seed(3)
    base = torch.rand(1, 3, 24, 24, generator=generator)
    scene = torch.nn.functional.interpolate(base, size=(96, 96), mode="bilinear", align_corners=False)[0]
    scene = (scene - scene.min()) / (scene.max() - scene.min())
    return torch.stack([darken(scene, alphas[i], gamma) for i in range(frames)])


def test_darkening_is_estimated_and_a_clip_gets_its_per_frame_range(tiny_model: Callable[..., DEN]) -> None:
    alphas = [0.1, 0.12, 0.14, 0.16, 0.18, 0.2]
    result = estimate(_dark_scene(6, alphas), tiny_model(), source="clip")
    darkening = result.profile.darkening
    assert darkening is not None
    ((low, high),) = result.profile.ranges["alpha"]
    assert low < high and low <= darkening.alpha <= high
    # The frames' exposures differ by up to 2x (1.7x between the 10th and 90th percentile); the prior on
    # alpha and gamma pulls the per-frame estimates together, and part of the difference goes into gamma.
    assert 1.15 < high / low < 2.0
    assert result.profile.meta["darkening"]["ranges"] == "10th-90th percentile over frames"
    single = estimate(_dark_scene(1, alphas), tiny_model())
    assert single.profile.darkening is not None and "alpha" not in single.profile.ranges
    validate_profile(result.profile)
    # The reference's tones go into the profile, for apply to match each input's exposure to.
    tone = single.profile.tone
    assert tone is not None and len(tone.quantiles) == 49 and tone.noise >= 0.0
    assert np.allclose(tone.quantiles, tone_quantiles(_dark_scene(1, alphas)))
    # And the luminance a viewer sees of it, which apply fits each output's to.
    assert tone.luminance is not None
    assert np.allclose(tone.luminance, luminance_quantiles(_dark_scene(1, alphas)))
    assert validate_profile(single.profile).tone == tone


def test_black_reference_warns_and_leaves_the_darkening_to_apply(tiny_model: Callable[..., DEN]) -> None:
    result = estimate(torch.zeros(1, 3, 64, 64), tiny_model(), source="black.png")
    assert result.profile.darkening is None and result.profile.tone is None
    assert "alpha" not in result.profile.ranges
    assert any(w.startswith("black.png: too dark") for w in result.warnings)


def _rigged(model: DEN, normalised: torch.Tensor) -> DEN:
    """A network that predicts ``normalised`` for every input (its last layer reduced to a bias)."""
    with torch.no_grad():
        model.head[-1].weight.zero_()
        model.head[-1].bias.copy_(torch.logit(normalised))
    return model


def test_each_network_output_lands_in_its_named_profile_entry(tiny_model: Callable[..., DEN]) -> None:
    fractions = torch.tensor([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8])
    network = _rigged(tiny_model(noise_model="paper", log_levels=False), fractions)
    result = estimate(_reference(1, 64, 64, banding=0.1), network)
    expected = {
        "shot": (0.1 * 0.2,),
        "read": (0.2 * 0.1,),
        "quantization": (0.3 * 0.02,),
        "banding": (0.4 * 0.03,),
        "temporal_banding": (0.5 * 0.03,),
        "periodic": (0.6 * 0.02, 0.7 * 0.02, 0.8 * 0.02),
    }
    for name, values in expected.items():
        assert tuple(result.profile.noise[name].tolist()) == pytest.approx(values, rel=1e-5)
        for (low, high), value in zip(result.profile.ranges[name], values, strict=True):
            assert (low, high) == pytest.approx((value, value), rel=1e-5)
    # The paper's model says nothing of the sRGB structure: white, uncompressed noise, and no ranges for it.
    assert result.profile.noise.to_json()["channel_gain"] == [1.0, 1.0]
    assert result.profile.noise.to_json()["correlation_length"] == 0.0
    assert result.profile.noise.to_json()["compression"] == 0.0
    assert "compression" not in result.profile.ranges
    assert result.profile.meta["noise_model"] == "paper"


def test_srgb_model_outputs_land_in_their_profile_entries(tiny_model: Callable[..., DEN]) -> None:
    # v of the sRGB model: shot, read, gain (2), length, correlations (3), chroma length, quantization,
    # banding, temporal banding, periodic (3), compression.
    fractions = torch.linspace(0.05, 0.95, 16)
    result = estimate(
        _reference(1, 64, 64, banding=0.1),
        _rigged(tiny_model(log_levels=False), fractions),
        options=NoiseEstimateOptions(refine=False),
    )
    noise = result.profile.noise
    assert noise["shot"] == pytest.approx((0.05 * 0.2,), rel=1e-5)
    gain_low, gain_high = noise_parameter("channel_gain").training_range
    assert noise["channel_gain"] == pytest.approx(
        tuple(gain_low + f * (gain_high - gain_low) for f in fractions[2:4].tolist()), rel=1e-5
    )
    assert noise["correlation_length"] == pytest.approx((float(fractions[4]) * 2.0,), rel=1e-5)
    assert noise["channel_correlation"] == pytest.approx(tuple(f * 0.7 for f in fractions[5:8].tolist()), rel=1e-5)
    assert noise["chroma_length"] == pytest.approx((float(fractions[8]) * 3.0,), rel=1e-5)
    assert noise["periodic"] == pytest.approx(tuple(f * 0.02 for f in fractions[12:15].tolist()), rel=1e-5)
    assert noise["compression"] == pytest.approx((float(fractions[15]) * 0.7,), rel=1e-5)
    assert result.profile.meta["noise_model"] == "srgb"
    validate_profile(result.profile)


def test_nearly_noise_free_estimate_warns(tiny_model: Callable[..., DEN]) -> None:
    quiet_network = _rigged(tiny_model(), torch.full((vector_size(),), 0.001))
    quiet = estimate(
        _reference(1, 64, 64), quiet_network, source="quiet.png", options=NoiseEstimateOptions(refine=False)
    )
    assert any(w.startswith("quiet.png: nearly noise-free") for w in quiet.warnings)
    noisy = estimate(
        _reference(1, 64, 64), _rigged(tiny_model(), torch.full((vector_size(),), 0.5)), source="noisy.png"
    )
    assert not any("noise-free" in w for w in noisy.warnings)


def test_the_measured_spectrum_overrules_a_network_that_calls_a_noisy_reference_noise_free(
    tiny_model: Callable[..., DEN],
) -> None:
    # White noise of std 0.03 (7.65 8-bit levels) on a level of 0.2: plainly visible.
    network = _rigged(tiny_model(), torch.full((vector_size(),), 0.001))
    noise = 0.03 * torch.randn(1, 3, 128, 128, generator=torch.Generator().manual_seed(0))
    result = estimate((0.2 + noise).clamp(0, 1), network, source="dim.png")
    assert not any("noise-free" in w for w in result.warnings), result.warnings
    network_only = estimate(
        (0.2 + noise).clamp(0, 1), network, source="dim.png", options=NoiseEstimateOptions(refine=False)
    )
    assert network_only.profile.meta["noise_std_8bit"] < 1.0
    assert "network_values" in result.profile.meta["spectrum"]
    assert 0.8 < result.profile.meta["noise_std_8bit"] / 7.65 < 1.2


def test_a_clean_reference_stays_nearly_noise_free_after_the_measured_spectrum(
    tiny_model: Callable[..., DEN],
) -> None:
    # A smooth clean gradient on 8-bit levels: nothing the measurement could read as noise.
    ramp = torch.linspace(0.05, 0.25, 128)
    clean = (ramp[:, None].expand(128, 128)[None, None].expand(1, 3, 128, 128) * 255).round() / 255
    network = _rigged(tiny_model(), torch.full((vector_size(),), 0.001))
    result = estimate(clean, network, source="clean.png", options=NoiseEstimateOptions(refine=False))
    assert any(w.startswith("clean.png: nearly noise-free") for w in result.warnings), result.warnings
    # The measured spectrum reads the ramp's 8-bit steps, which the denoiser's 8-bit output keeps, as about half
    # a level of noise: invisible, and far below any camera's.
    measured = estimate(clean, network, source="clean.png")
    assert measured.profile.meta["noise_std_8bit"] < 0.75, measured.profile.meta["noise_std_8bit"]


def test_the_measured_spectrum_drops_the_ranges_of_what_it_replaces(tiny_model: Callable[..., DEN]) -> None:
    # apply --jitter draws ranged parameters: a range left on the network's shot or compression would add the
    # network's noise back on top of the measured spectrum.
    from darksynth.noise.spectral_components import SPECTRUM_REPLACES

    network = _rigged(tiny_model(), torch.full((vector_size(),), 0.3))
    profile = estimate(_reference(1, 128, 128), network).profile
    assert not set(profile.ranges) & {*SPECTRUM_REPLACES, "compression"}, profile.ranges
    for name in SPECTRUM_REPLACES:
        assert profile.noise.is_neutral(noise_parameter(name)), name
    assert not profile.noise.is_neutral(noise_parameter("octave_power"))


def test_a_reference_too_small_to_measure_keeps_the_network_values_and_says_so(
    tiny_model: Callable[..., DEN],
) -> None:
    network = _rigged(tiny_model(), torch.full((vector_size(),), 0.3))
    reference = _reference(1, 48, 48)
    refined = estimate(reference, network, source="small.png")
    plain = estimate(reference, network, source="small.png", options=NoiseEstimateOptions(refine=False))
    assert refined.profile.noise == plain.profile.noise
    assert any(w.startswith("small.png: 48x48 is too small to measure") for w in refined.warnings)


def test_a_reference_under_128_px_is_measured_with_a_warning_that_its_level_is_uncertain(
    tiny_model: Callable[..., DEN],
) -> None:
    network = _rigged(tiny_model(), torch.full((vector_size(),), 0.3))
    small = estimate(_reference(1, 96, 96), network, source="crop.png")
    assert small.profile.meta["spectrum"]["method"].startswith("blind spectral")
    assert any(w.startswith("crop.png: 96x96 holds few blocks") for w in small.warnings)
    large = estimate(_reference(1, 128, 128), network, source="crop.png")
    assert not any("holds few blocks" in w for w in large.warnings)


def test_noise_free_warning_reads_the_noise_the_profile_adds_on_this_reference(
    tiny_model: Callable[..., DEN],
) -> None:
    # Paper model: shot, read, quantization, banding, temporal banding, periodic (3), linear in the fractions.
    # Shot 0.002 and read 0.001, which the old rule (shot < 0.005 and read < 0.003) called noise-free, with
    # quantization 0.0198 (std 0.0057, 1.5 levels of 8 bits): visibly noisy.
    fractions = torch.tensor([0.01, 0.01, 0.99, 0.01, 0.01, 0.01, 0.01, 0.01])
    network = _rigged(tiny_model(noise_model="paper", log_levels=False), fractions)
    grainy = estimate(_reference(1, 64, 64), network, source="grainy.png")
    assert not any("noise-free" in w for w in grainy.warnings)
    assert grainy.profile.meta["noise_std_8bit"] == pytest.approx(0.0198 / 12**0.5 * 255, rel=0.05)
    # Shot noise alone (0.2, the top of its range) adds nothing on black and 0.2 * sqrt(0.1) on a level of 0.1.
    shot_only = _rigged(tiny_model(noise_model="paper", log_levels=False), torch.tensor([0.999] + [1e-6] * 7))
    black = estimate(torch.zeros(1, 3, 64, 64), shot_only, source="black.png")
    assert any(w.startswith("black.png: nearly noise-free; the profile adds noise of std 0.0") for w in black.warnings)
    grey = estimate(torch.full((1, 3, 64, 64), 0.1), shot_only, source="grey.png")
    assert not any("noise-free" in w for w in grey.warnings)
    assert grey.profile.meta["noise_std_8bit"] == pytest.approx(0.2 * 0.1**0.5 * 255, rel=0.01)


def test_darkening_meta_says_what_was_fitted_and_what_is_prior(tiny_model: Callable[..., DEN]) -> None:
    result = estimate(_dark_scene(1, [0.15], gamma=0.6), tiny_model(), source="scene.png")
    darkening = result.profile.meta["darkening"]
    for name in ("alpha", "gamma"):
        entry = darkening[name]
        assert entry["value"] == pytest.approx(getattr(result.profile.darkening, name), abs=1e-4)
        assert 0.0 < entry["prior_share"] < 1.0
        expected = "mostly prior" if entry["prior_share"] > 0.5 else "fit to the reference's tones"
        assert entry["source"].startswith(expected)
    assert not any("bound" in w for w in result.warnings)
    black = estimate(torch.zeros(1, 3, 64, 64), tiny_model())
    assert black.profile.meta["darkening"]["gamma"]["source"].startswith("prior: apply draws it from the paper's")


def test_a_fitted_value_on_a_bound_of_its_search_range_warns(tiny_model: Callable[..., DEN]) -> None:
    # x ** (1 / 8): mid-tones far brighter than the search range's gamma of at most 2 allows.
    result = estimate(_dark_scene(1, [0.3], gamma=8.0), tiny_model(), source="flat.png")
    assert result.profile.darkening is not None and result.profile.darkening.gamma == 2.0
    # apply matches the reference's tones instead (the profile's tone): a note in meta, not a warning.
    assert result.profile.tone is not None and not any("bound" in w for w in result.warnings)
    assert any(
        w.startswith("flat.png: the fitted gamma sits on the upper bound 2 of its search range [0.1, 2]")
        for w in result.profile.meta["darkening"]["notes"]
    ), result.profile.meta["darkening"]
    assert result.profile.meta["darkening"]["gamma"]["source"].startswith("fit, clipped to the upper bound")


def test_low_darkening_confidence_warns_and_says_why(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model()
    dark = estimate(_dark_scene(1, [0.05], gamma=0.3), model, source="dark.png")  # confidence 0.02
    # Notes in meta, not warnings: apply matches the reference's tones, not this alpha and gamma.
    assert not any("uncertain" in w for w in dark.warnings)
    assert any(
        w.startswith("dark.png: the darkening estimate is uncertain (confidence 0.02 < 0.1: 7 of 49 tone quantiles")
        for w in dark.profile.meta["darkening"]["notes"]
    ), dark.profile.meta["darkening"]
    # Confidence 0.18 (its gamma hit the upper bound, which notes it by itself): above the threshold of 0.1.
    between = estimate(_dark_scene(1, [0.2], gamma=1.5), model, source="between.png")
    assert 0.1 < between.profile.meta["darkening"]["confidence"] < 0.2
    assert not any("uncertain" in w for w in between.profile.meta["darkening"]["notes"])
    assert any("sits on the upper bound" in w for w in between.profile.meta["darkening"]["notes"])
    clear = estimate(_dark_scene(1, [0.15], gamma=0.6), model, source="clear.png")  # confidence 0.43
    assert "notes" not in clear.profile.meta["darkening"]


def test_bright_reference_warns_and_a_dark_one_does_not(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model()
    bright = estimate(_reference(1, 64, 64, mean=0.8), model, source="bright.png")
    assert any(w.startswith("bright.png: mean level 0.80 is bright") for w in bright.warnings)
    dark = estimate(_reference(1, 64, 64, mean=0.1), model, source="dark.png")
    assert not any("is bright for a low-light reference" in w for w in dark.warnings)


def test_single_frame_adds_a_note_and_clips_do_not(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model()
    single = estimate(_reference(1, 64, 64), model, source="one.png")
    assert "single image" in str(single.profile.meta["note"])
    assert single.profile.meta["frames"] == 1
    assert single.profile.meta["source"] == "one.png"
    clip = estimate(_reference(5, 64, 64), model)
    assert "note" not in clip.profile.meta
    assert clip.profile.meta["frames"] == 5


def test_column_components_are_set_absent_without_a_column_pattern(tiny_model: Callable[..., DEN]) -> None:
    fractions = torch.full((8,), 0.5)
    network = _rigged(tiny_model(noise_model="paper", log_levels=False), fractions)
    plain = estimate(_reference(1, 64, 128), network)
    columns = plain.profile.meta["columns"]
    assert columns["decision"] == "absent" and columns["ratio"] < 2.0
    names = ("banding", "temporal_banding", "periodic")
    assert columns["set_absent"] == list(names)
    for name in names:
        assert float(plain.profile.noise[name].abs().max()) == 0.0 and name not in plain.profile.ranges
    assert plain.profile.noise.scalar("read") == pytest.approx(0.05)  # the rest is the network's
    striped = estimate(_reference(1, 64, 128, banding=0.02), network)
    assert striped.profile.meta["columns"]["decision"] == "present"
    assert striped.profile.noise.scalar("banding") == pytest.approx(0.015)
    assert "banding" in striped.profile.ranges
    validate_profile(plain.profile)


def test_batch_size_does_not_change_the_estimate(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model()
    reference = _reference(1, 48, 240)
    whole = estimate(reference, model, options=NoiseEstimateOptions(batch=16))
    one_by_one = estimate(reference, model, options=NoiseEstimateOptions(batch=1))
    np.testing.assert_allclose(model_vector(one_by_one.per_crop), model_vector(whole.per_crop), rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("level", [0.0, 1.0])
def test_a_uniform_reference_says_there_is_no_noise_to_measure(tiny_model: Callable[..., DEN], level: float) -> None:
    # Black or saturated: no noise survives; the refinement is skipped (nothing to read) and the profile says so.
    result = estimate(torch.full((1, 3, 96, 96), level), tiny_model(), source="flat.png")
    assert any(w.startswith("flat.png: the reference is uniform") for w in result.warnings), result.warnings
    assert "refined" not in result.profile.meta


def test_a_clip_with_a_scene_cut_warns_and_names_the_frame(tiny_model: Callable[..., DEN]) -> None:
    generator = torch.Generator().manual_seed(0)
    dark = 0.1 + 0.02 * torch.randn(3, 3, 96, 96, generator=generator)
    ramp = torch.linspace(0.1, 0.6, 96).expand(3, 96, 96)
    other = ramp + 0.02 * torch.randn(2, 3, 96, 96, generator=generator)
    clip = torch.cat([dark, other]).clamp(0, 1)
    result = estimate(clip, tiny_model(), source="cut.mp4")
    assert result.profile.meta["scene_cuts"] == [3]
    assert any(w.startswith("cut.mp4: scene cut before frame(s) [3]") for w in result.warnings), result.warnings
    # One scene with its noise redrawn every frame has no cut.
    steady = estimate(dark.clamp(0, 1), tiny_model(), source="steady.mp4")
    assert "scene_cuts" not in steady.profile.meta
    assert not any("scene cut before" in w for w in steady.warnings)


def test_a_clean_daylight_photo_warns_that_its_texture_is_read_as_noise() -> None:
    from darksynth.training.weights import default_weights_path, load_weights

    # A bright clean scene on 8-bit levels, with fine texture (a sum of gratings) and no noise.
    y, x = torch.meshgrid(torch.arange(160.0), torch.arange(160.0), indexing="ij")
    texture = 0.08 * torch.sin(x * 0.9) * torch.cos(y * 0.7) + 0.05 * torch.sin((x + y) * 0.35)
    scene = torch.stack([0.55 + texture, 0.5 + 0.8 * texture, 0.45 + texture])[None]
    photo = (scene.clamp(0, 1) * 255).round() / 255
    result = estimate(photo, load_weights(default_weights_path("v3", "srgb")), source="day.jpg")
    bright = [w for w in result.warnings if w.startswith("day.jpg: mean level 0.50 is bright")]
    assert bright and "clean daylight photo" in bright[0], result.warnings


def test_only_the_srgb_model_is_refined_and_only_when_asked() -> None:
    from darksynth.estimation.noise.noise_estimate import refines

    assert refines("srgb") and refines("srgb", True)
    assert not refines("srgb", False) and not refines("paper") and not refines("paper", True)


def test_the_light_goes_into_the_profile_with_its_priors_stated(tiny_model: Callable[..., DEN]) -> None:
    """A single image: the exposure-fraction prior, stated in meta, no warning. A still clip: the prior too, with a
    warning naming it. A clip whose brightness steps frame to frame: flicker measured, written in ``light``."""
    from darksynth.estimation.light.motion import EXPOSURE_FRACTION_PRIOR
    from darksynth.profile import profile_to_dict

    single = estimate(_dark_scene(1, [0.15]), tiny_model(), source="photo.png")
    assert single.profile.noise.scalar("exposure_fraction") == EXPOSURE_FRACTION_PRIOR
    assert single.profile.meta["light"]["exposure_measured"] is False
    assert not any("exposure fraction" in w for w in single.warnings)
    still = estimate(_dark_scene(6, [0.15] * 6), tiny_model(), source="still")
    assert still.profile.noise.scalar("exposure_fraction") == EXPOSURE_FRACTION_PRIOR
    assert any("still: " in w and "exposure fraction is the prior" in w for w in still.warnings)
    pulsing = estimate(_dark_scene(6, [0.15, 0.12, 0.17, 0.13, 0.16, 0.12]), tiny_model(), source="pulse")
    assert pulsing.profile.meta["light"]["flicker_measured"] is True
    assert pulsing.profile.noise.scalar("flicker") > 0.05
    assert profile_to_dict(pulsing.profile)["light"]["flicker"] == pulsing.profile.noise.scalar("flicker")


def test_a_blur_beyond_any_shutter_is_held_at_one_with_one_warning(tiny_model: Callable[..., DEN]) -> None:
    from tests.estimation.test_motion import low_light, moving_clip, natural_texture

    frames = low_light(moving_clip(natural_texture(5), (0.0, 6.0), 1.6, 8), 5)
    result = estimate(frames, tiny_model(), source="blended")
    assert result.profile.noise.scalar("exposure_fraction") == 1.0
    assert result.profile.meta["light"]["exposure_fraction"] > 1.3  # the reading, kept in meta
    said = [w for w in result.warnings if "exposure" in w or "shutter" in w]
    assert len(said) == 1 and "held at 1" in said[0], said
