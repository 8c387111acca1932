"""noise/spectral_kernel.py: the compiled spectral path draws the eager spectral path's law, and falls back."""

from __future__ import annotations

import logging

import pytest
import scipy.stats
import torch

from darksynth.estimation.noise.spectral_statistics import measure
from darksynth.light.darkening import Darkening
from darksynth.noise import frame_routes
from darksynth.noise.counter_rng import random_key
from darksynth.noise.spectral import OCTAVES, crop_unit, octave_covariances, spectral_tables
from darksynth.noise.spectral_8bit import level_tables
from darksynth.noise.spectral_kernel import (
    spectral_ar_mix_kernel,
    spectral_kernels,
    spectral_mix_kernel,
    spectral_pixel_kernel,
    spectral_white_pixel_kernel,
)
from darksynth.noise.values import NoiseValues
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer

SPECTRAL = {
    "level_curve": [0.01, 0.012, 0.014, 0.016, 0.018, 0.02, 0.022, 0.024] * 3,
    "octave_power": [0.5, 0.3, 0.3] * 3 + [2.0, 20.0, 8.0] * 3,
    "octave_correlation": [0.3, -0.2, 0.1] * OCTAVES,
    "quantization": 0.002,
}


def _eager_kernels(monkeypatch: pytest.MonkeyPatch) -> None:
    """The stream with the kernels run eagerly: the compiled ones' values (tested below), in a test's time."""
    monkeypatch.setattr(frame_routes, "compiled_spectral_kernels", spectral_kernels)


def _field(mixed: torch.Tensor, height: int, width: int) -> torch.Tensor:
    return torch.fft.irfft2(torch.view_as_complex(mixed.view(*mixed.shape[:2], -1, 2)), s=(height, width))


def test_the_kernels_give_the_same_values_eagerly_and_compiled() -> None:
    values = NoiseValues.from_values(SPECTRAL | {"temporal_correlation": [0.6] * OCTAVES})  # type: ignore[arg-type]
    covariances = octave_covariances(values["octave_power"], values["octave_correlation"])
    tables = spectral_tables(covariances, values["temporal_correlation"], 3, 40, 56, device="cpu")
    assert tables.rho is not None and tables.innovation is not None
    generator = torch.Generator().manual_seed(4)
    key = random_key(generator)
    mixed = spectral_mix_kernel(key, tables.factors)
    compiled_mixed = torch.compile(spectral_mix_kernel, dynamic=False)(key, tables.factors)
    assert torch.allclose(mixed, compiled_mixed, rtol=1e-5, atol=1e-3 * mixed.abs().max().item())
    state = torch.randn_like(mixed)
    arguments = (key, tables.factors, tables.rho, tables.innovation, state, torch.tensor(True))
    carried, carried_state = spectral_ar_mix_kernel(*arguments)
    compiled_carried, compiled_state = torch.compile(spectral_ar_mix_kernel, dynamic=False)(*arguments)
    assert torch.allclose(carried_state, compiled_state, rtol=1e-5, atol=1e-5)
    assert torch.allclose(carried, compiled_carried, rtol=1e-5, atol=1e-3 * carried.abs().max().item())
    unit = crop_unit(_field(mixed, tables.grid_height, tables.grid_width), 40, 56)
    signal, std = level_tables(3, Darkening(0.2, 0.6), values["level_curve"], device="cpu")
    frame = torch.randint(0, 256, (3, 40, 56), dtype=torch.uint8, generator=generator)
    pixel_arguments = (
        frame,
        random_key(generator),
        signal,
        std,
        unit,
        torch.tensor(0.002 / 256),
        torch.zeros(3, 1, 56),
    )
    eager_frame = spectral_pixel_kernel(*pixel_arguments)
    compiled_frame = torch.compile(spectral_pixel_kernel, dynamic=False)(*pixel_arguments)
    # Float rounding may differ in the last bit, which moves a value across a .5 boundary once in a while.
    assert (eager_frame.int() - compiled_frame.int()).abs().max() <= 1
    assert (eager_frame != compiled_frame).double().mean() < 1e-3
    white_arguments = (*pixel_arguments[:4], torch.rand(3, 256, generator=generator) * 0.02, *pixel_arguments[4:])
    eager_frame = spectral_white_pixel_kernel(*white_arguments)
    compiled_frame = torch.compile(spectral_white_pixel_kernel, dynamic=False)(*white_arguments)
    assert (eager_frame.int() - compiled_frame.int()).abs().max() <= 1
    assert (eager_frame != compiled_frame).double().mean() < 1e-3


def test_the_unit_noise_is_normal_though_its_frequency_draws_are_triangular() -> None:
    """Even a spectrum whose power sits in the coarse octaves (few frequency bins) on a small grid: the inverse
    FFT's sums are normal (the eager path's law), with unit variance per channel."""
    power = torch.tensor([[0.3, 0.3, 0.3]] * 3 + [[6.0, 20.0, 20.0]] * 3).flatten()
    covariances = octave_covariances(power, torch.zeros(3 * OCTAVES))
    tables = spectral_tables(covariances, torch.zeros(OCTAVES), 3, 96, 128, device="cpu")
    generator = torch.Generator().manual_seed(8)
    units = []
    for _ in range(24):
        mixed = spectral_mix_kernel(random_key(generator), tables.factors)
        units.append(crop_unit(_field(mixed, tables.grid_height, tables.grid_width), 96, 128))
    unit = torch.stack(units).double()
    assert torch.allclose(unit.var(dim=(0, 2, 3)), torch.ones(3, dtype=torch.float64), rtol=0.1)
    values = unit.permute(1, 0, 2, 3).reshape(3, -1).numpy()
    # 24 frames of coarse noise hold few independent values: the kurtosis's sampling error is about 0.03.
    assert abs(scipy.stats.kurtosis(values, axis=1)).max() < 0.12
    assert abs(scipy.stats.skew(values, axis=1)).max() < 0.08


def _frames(synthesizer: ClipSynthesizer, frame: torch.Tensor, count: int) -> torch.Tensor:
    return torch.stack([synthesizer(frame).double() for _ in range(count)])


@pytest.mark.parametrize(
    "extra",
    [
        {},
        {"temporal_correlation": [0.8, 0.7, 0.6, 0.6, 0.5, 0.5]},
        {"banding": 0.004, "compression": 0.3},
        {"shot": 0.04, "read": 0.01},
    ],
    ids=["plain", "temporal", "columns-jpeg", "white"],
)
def test_the_compiled_path_draws_the_eager_paths_law(monkeypatch: pytest.MonkeyPatch, extra: dict[str, object]) -> None:
    """Level, band powers (brightness and colour), channel correlations and frame-to-frame correlation of the
    compiled stream against the eager spectral path's, on a mid-grey 8-bit clip."""
    _eager_kernels(monkeypatch)
    parameters = ClipParameters(NoiseValues.from_values(SPECTRAL | extra), Darkening(0.3, 0.8))  # type: ignore[arg-type]
    frame = torch.full((3, 256, 256), 150, dtype=torch.uint8)
    compiled = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(1), compile=True)
    eager = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2), compile=False)
    assert (compiled.route_name, eager.route_name) == ("compiled spectral", "spectral")
    ours, theirs = _frames(compiled, frame, 12), _frames(eager, frame, 12)
    assert compiled.route_name == "compiled spectral"  # the compiled path drew them, without falling back
    assert not torch.equal(ours[0], ours[1])
    assert torch.allclose(ours.mean(dim=(0, 2, 3)), theirs.mean(dim=(0, 2, 3)), atol=0.3)
    noise = [(f - f.mean(dim=(0, 2, 3), keepdim=True)) / 255.0 for f in (ours, theirs)]
    stds = [n.std(dim=(0, 2, 3)) for n in noise]
    assert torch.allclose(stds[0], stds[1], rtol=0.08)
    measured = [measure(n, torch.full_like(n, 0.5)) for n in noise]
    power = [m.cross_power.diagonal(dim1=-2, dim2=-1) for m in measured]
    # Twelve 256-px frames: over five seeds each path's band powers vary by at most 6% (relative std) in the five
    # finer bands and by up to 14% in the coarsest, which holds few frequencies: its total is compared.
    assert torch.allclose(power[0][:5], power[1][:5], rtol=0.25)
    assert torch.allclose(power[0][5].sum(), power[1][5].sum(), rtol=0.4)
    correlations = [torch.corrcoef(n.permute(1, 0, 2, 3).reshape(3, -1)) for n in noise]
    assert (correlations[0] - correlations[1]).abs().max() < 0.06
    temporal = [m.temporal for m in measured]
    assert temporal[0] is not None and temporal[1] is not None
    assert (temporal[0][:4] - temporal[1][:4]).abs().max() < 0.08


def test_the_compiled_path_is_taken_for_compiled_spectral_streams_only(monkeypatch: pytest.MonkeyPatch) -> None:
    _eager_kernels(monkeypatch)
    spectral = ClipParameters(NoiseValues.from_values(SPECTRAL), None)  # type: ignore[arg-type]
    structured = SPECTRAL | {"shot": 0.02, "channel_gain": [1.2, 0.9]}
    with_structure = ClipParameters(NoiseValues.from_values(structured), None)  # type: ignore[arg-type]
    assert ClipSynthesizer(spectral, compile=True).route_name == "compiled spectral"
    assert ClipSynthesizer(spectral, compile=False).route_name == "spectral"
    assert ClipSynthesizer(with_structure, compile=True).route_name == "composer"
    # A seed fixes the frames.
    frame = torch.full((3, 48, 64), 90, dtype=torch.uint8)
    first, second = (
        _frames(ClipSynthesizer(spectral, generator=torch.Generator().manual_seed(9), compile=True), frame, 2)
        for _ in range(2)
    )
    assert torch.equal(first, second)


def test_failing_compiled_spectral_kernels_fall_back_to_the_eager_path_with_a_log_line(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def broken(*args: object) -> torch.Tensor:
        raise RuntimeError("no working C compiler")

    monkeypatch.setattr(frame_routes, "compiled_spectral_kernels", lambda white=False: (broken,) * 3)
    parameters = ClipParameters(NoiseValues.from_values(SPECTRAL), None)  # type: ignore[arg-type]
    frame = torch.full((3, 48, 64), 90, dtype=torch.uint8)
    with caplog.at_level(logging.WARNING, logger="darksynth.synthesize"):
        synthesizer = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2), compile=True)
        frames = _frames(synthesizer, frame, 3)
    assert synthesizer.route_name == "spectral"
    assert frames.std(dim=(0, 2, 3)).min() > 1.0  # noisy frames, from the eager path
    warnings = [r for r in caplog.records if "compiled spectral kernels failed" in r.getMessage()]
    assert len(warnings) == 1 and "no working C compiler" in warnings[0].getMessage()


@pytest.mark.parametrize("compiled", [False, True])
def test_flicker_moves_the_spectral_paths_frames_by_their_gain(monkeypatch: pytest.MonkeyPatch, compiled: bool) -> None:
    """Flicker redoes the level tables of the spectral paths frame by frame: each frame's mean follows its gain."""
    if compiled:
        _eager_kernels(monkeypatch)
    values = NoiseValues.from_values(SPECTRAL | {"flicker": 0.1})  # type: ignore[arg-type]
    synthesizer = ClipSynthesizer(
        ClipParameters(values, Darkening(0.3, 1.0)), generator=torch.Generator().manual_seed(0), compile=compiled
    )
    assert synthesizer.route_name == ("compiled spectral" if compiled else "spectral")
    grey = torch.full((3, 64, 80), 200, dtype=torch.uint8)
    means = torch.tensor([float(synthesizer(grey).double().mean()) for _ in range(200)])
    gains = means / means.mean()
    assert float(gains.std()) == pytest.approx(0.1, rel=0.15)
    steady = ClipSynthesizer(ClipParameters(NoiseValues.from_values(SPECTRAL), Darkening(0.3, 1.0)), compile=compiled)  # type: ignore[arg-type]
    flat = torch.tensor([float(steady(grey).double().mean()) for _ in range(50)])
    assert float((flat / flat.mean()).std()) < 0.01
