"""A component declared in the table, and nowhere else, goes end to end.

The test declares a dummy component (uniform dither, a profile-version-7 parameter that no fast path covers)
inside the test, adds it to the table, and runs it through sampling, the profile schema (load, save, version
rules), the composer, ``synthesize`` on float and 8-bit input, the level's closed form, ``apply`` on an image
file and its manifest. Nothing else in darksynth is changed for it: if a consumer kept its own list of
components, this test would fail there. A second one, white Gaussian noise with its variance law declared, is
drawn by every 8-bit route (the fused kernel, the spectral paths) as well as by the composer, again with nothing
but its declaration.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

import darksynth
from darksynth.apply import ApplyOptions, apply
from darksynth.errors import ProfileError
from darksynth.light.darkening import Darkening
from darksynth.noise import components, frame_routes
from darksynth.noise.component_types import ALL_8BIT_PATHS
from darksynth.noise.components import NoiseComponent, Parameter
from darksynth.noise.frame_routes import ClipState, ComposerRoute
from darksynth.noise.level import mean_noise_variance
from darksynth.noise.sampling import random_noise_values
from darksynth.noise.simulate import exposure_gains
from darksynth.noise.spectral_kernel import spectral_kernels
from darksynth.noise.values import NoiseValues
from darksynth.profile import load_profile, profile_schema, save_profile
from darksynth.recipe import ClipParameters, ClipRecipe
from darksynth.synthesize import ClipSynthesizer

DITHER = 0.08


def _draw_dither(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    width = values["dither"][..., 0].reshape(*values["dither"].shape[:-1], *([1] * 4))
    unit = torch.rand(signal.shape, generator=generator, device=signal.device, dtype=signal.dtype)
    return (2.0 * unit - 1.0) * width if signal.dim() >= 4 else (2.0 * unit - 1.0) * width.reshape(())


def _dither_variance(values: Mapping[str, torch.Tensor], channel_means: torch.Tensor) -> torch.Tensor:
    # U(-d, d) has variance d^2 / 3.
    return (values["dither"][:, :1].square() / 3.0).expand_as(channel_means)


DUMMY = NoiseComponent(
    name="dither",
    parameters=(
        Parameter("dither", 1, "half-width d of a uniform U(-d, d) per pixel", 0.5, (0.0, 0.1), since_version=7),
    ),
    structure="pixel",
    draw=_draw_dither,
    variance=_dither_variance,
    reference="a component that exists only in this test",
)


@pytest.fixture
def with_dither(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setattr(components, "NOISE_COMPONENTS", (*components.NOISE_COMPONENTS, DUMMY))
    yield


def _document(version: int, **noise: float) -> dict[str, object]:
    paper = {"shot": 0.0, "read": 0.0, "quantization": 0.0, "banding": 0.0, "temporal_banding": 0.0}
    return {
        "format": "darksynth-profile",
        "version": version,
        "noise": paper | {"periodic": [0.0, 0.0, 0.0]} | noise,
        "darkening": {"alpha": 0.5, "gamma": 1.0},
    }


def _write(path: Path, document: dict[str, object]) -> Path:
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


@pytest.mark.usefixtures("with_dither")
def test_sampling_draws_the_new_parameter_within_its_training_range() -> None:
    values = random_noise_values(batch_shape=(2000,), generator=torch.Generator().manual_seed(0))
    drawn = values["dither"]
    assert drawn.shape == (2000, 1)
    assert float(drawn.min()) >= 0.0 and float(drawn.max()) <= 0.1
    assert float(drawn.max()) - float(drawn.min()) > 0.09
    assert NoiseValues.neutral()["dither"].tolist() == [0.0]


@pytest.mark.usefixtures("with_dither")
def test_profile_schema_and_versions_follow_the_declaration(tmp_path: Path) -> None:
    schema = profile_schema().model_json_schema()
    assert "dither" in json.dumps(schema)
    profile = load_profile(_write(tmp_path / "v7.json", _document(7, dither=DITHER)))
    assert profile.noise.scalar("dither") == DITHER
    save_profile(tmp_path / "copy.json", profile)
    written = json.loads((tmp_path / "copy.json").read_text(encoding="utf-8"))
    assert written["version"] == 7 and written["noise"]["dither"] == DITHER
    assert load_profile(tmp_path / "copy.json") == profile
    # Older documents: read with the new parameter neutral, refused when they carry it.
    older = load_profile(_write(tmp_path / "v4.json", _document(4)))
    assert older.noise.scalar("dither") == 0.0
    with pytest.raises(ProfileError, match=r"noise\.dither needs profile version 7, this document is version 6"):
        load_profile(_write(tmp_path / "bad.json", _document(6, dither=DITHER)))
    with pytest.raises(ProfileError, match=r"noise\.dither must lie in \[0, 0\.5\].*got 0\.7"):
        load_profile(_write(tmp_path / "big.json", _document(7, dither=0.7)))


@pytest.mark.usefixtures("with_dither")
def test_synthesize_draws_it_with_its_law_on_float_and_8bit_input(tmp_path: Path) -> None:
    profile = load_profile(_write(tmp_path / "p.json", _document(7, dither=DITHER)))
    clean = torch.full((3, 128, 128), 0.8)
    result = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(1))
    noise = result.image.double() - 0.4  # darkened: 0.5 * 0.8
    assert float(noise.abs().max()) <= DITHER + 1e-6
    assert abs(float(noise.mean())) < 5 * DITHER / math.sqrt(3 * noise.numel())
    assert abs(float(noise.var()) / (DITHER**2 / 3) - 1.0) < 0.03
    assert result.parameters["noise"]["dither"] == DITHER  # type: ignore[call-overload,index]
    # 8-bit input: no fast path covers the new parameter, so the general composer draws it.
    synthesizer = ClipSynthesizer(ClipParameters(profile.noise, Darkening(0.5, 1.0)), generator=torch.Generator())
    frame = torch.full((3, 96, 96), 204, dtype=torch.uint8)
    levels = synthesizer(frame).double() - 102.0
    assert float(levels.abs().max()) <= DITHER * 255 + 1
    assert abs(float(levels.std()) / (DITHER * 255 / math.sqrt(3)) - 1.0) < 0.05


@pytest.mark.usefixtures("with_dither")
def test_the_level_counts_its_declared_variance() -> None:
    values = NoiseValues.from_values({"dither": DITHER, "read": 0.01}, batch_shape=(1,))
    dark = torch.full((1, 1, 3, 8, 8), 0.3, dtype=torch.float64)
    assert float(mean_noise_variance(values, dark)[0]) == pytest.approx(0.01**2 + DITHER**2 / 3)


@pytest.mark.usefixtures("with_dither")
def test_apply_on_an_image_writes_it_and_records_it_in_the_manifest(tmp_path: Path) -> None:
    source = tmp_path / "clean.png"
    Image.fromarray(np.full((64, 80, 3), 200, dtype=np.uint8)).save(source)
    profile = load_profile(_write(tmp_path / "p.json", _document(7, dither=DITHER)))
    out = tmp_path / "out.png"
    report = apply(source, out, ApplyOptions(recipe=ClipRecipe(profile), seed=3))
    pixels = np.asarray(Image.open(out), dtype=np.float64) - round(0.5 * 200)
    assert np.abs(pixels).max() <= DITHER * 255 + 1
    assert abs(pixels.std() / (DITHER * 255 / math.sqrt(3)) - 1.0) < 0.1
    assert report.manifest is not None
    manifest = json.loads(report.manifest.read_text(encoding="utf-8"))
    assert manifest["profile"]["version"] == 7
    assert manifest["profile"]["noise"]["dither"] == DITHER
    assert manifest["files"][0]["parameters"]["noise"]["dither"] == DITHER


def test_without_the_declaration_the_parameter_is_unknown(tmp_path: Path) -> None:
    """The control: the same document is refused by the table as shipped, so the tests above are not vacuous."""
    with pytest.raises(ProfileError, match=r"noise\.dither is not a noise parameter"):
        load_profile(_write(tmp_path / "v2.json", _document(4, dither=DITHER)))
    with pytest.raises(ProfileError, match=r"unsupported version 7"):
        load_profile(_write(tmp_path / "v7.json", _document(7)))
    assert "dither" not in NoiseValues.neutral()


HUM = 0.03


def _hum_variance(values: Mapping[str, torch.Tensor], signal: torch.Tensor) -> torch.Tensor:
    # Grows with the level as a hum on the sensor's supply would with its gain: (h * (1 + x))^2.
    hum = values["hum"][..., 0].reshape(*values["hum"].shape[:-1], *([1] * 4))
    return (hum * (1.0 + signal)).square() if signal.dim() >= 4 else (hum.reshape(()) * (1.0 + signal)).square()


def _draw_hum(
    signal: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    unit = torch.randn(signal.shape, generator=generator, device=signal.device, dtype=signal.dtype)
    return _hum_variance(values, signal).sqrt() * unit


WHITE_HUM = NoiseComponent(
    name="hum",
    parameters=(
        Parameter(
            "hum",
            1,
            "std h of N(0, (h (1 + x))^2) per pixel",
            0.5,
            (0.0, 0.1),
            since_version=7,
            fast_paths=ALL_8BIT_PATHS,
        ),
    ),
    structure="pixel",
    draw=_draw_hum,
    variance=lambda values, means: (values["hum"][:, :1] * (1.0 + means)).square(),
    white_variance=_hum_variance,
    reference="a white Gaussian component that exists only in this test",
)


def test_a_white_gaussian_component_with_its_law_is_drawn_by_every_8bit_route(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(components, "NOISE_COMPONENTS", (*components.NOISE_COMPONENTS, WHITE_HUM))
    parameters = ClipParameters(NoiseValues.from_values({"hum": HUM, "read": 0.01}), Darkening(0.5, 1.0))
    fused = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(1))
    assert fused.route_name == "fused"
    dark, bright = (torch.full((3, 128, 64), level, dtype=torch.uint8) for level in (40, 240))
    frame = torch.cat([dark, bright], dim=-1)
    fused_frame = fused(frame).double()
    # Float frames take the general composer, which draws the component by its own draw function.
    composer_frame = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(2))(frame.float() / 255.0)
    for columns, level in ((slice(0, 64), 40), (slice(64, 128), 240)):
        signal = 0.5 * level / 255.0
        expected = math.sqrt((HUM * (1.0 + signal)) ** 2 + 0.01**2) * 255.0
        fused_std = float((fused_frame[..., columns] - signal * 255.0).std())
        composer_std = float((composer_frame[..., columns].double() - signal).std()) * 255.0
        # 24k values a side: the std's relative standard error is 0.5%; rounding to 8 bits adds 1/12 level^2.
        assert abs(fused_std / math.sqrt(expected**2 + 1.0 / 12.0) - 1.0) < 0.03, (level, fused_std, expected)
        assert abs(composer_std / expected - 1.0) < 0.03, (level, composer_std, expected)
    # On a spectral profile: the eager spectral path draws the composer's bits, the compiled one its law.
    spectral = ClipParameters(
        NoiseValues.from_values({"hum": HUM, "level_curve": [0.01] * 24, "octave_power": [1.0] * 18}),
        Darkening(0.5, 1.0),
    )
    eager = ClipSynthesizer(spectral, generator=torch.Generator().manual_seed(3))
    state = ClipState(spectral.noise.to("cpu", torch.float32), torch.device("cpu"), torch.Generator().manual_seed(3))
    general = ComposerRoute(state, spectral.darkening)
    assert eager.route_name == "spectral"
    assert torch.equal(eager(frame), general(frame))
    monkeypatch.setattr(frame_routes, "compiled_spectral_kernels", spectral_kernels)
    compiled = ClipSynthesizer(spectral, generator=torch.Generator().manual_seed(4), compile=True)
    compiled_frame = compiled(frame).double()
    assert compiled.route_name == "compiled spectral"
    for columns, level in ((slice(0, 64), 40), (slice(64, 128), 240)):
        signal = 0.5 * level / 255.0
        expected = math.sqrt((HUM * (1.0 + signal)) ** 2 + 0.01**2) * 255.0
        measured = float((compiled_frame[..., columns] - signal * 255.0).std())
        # The spectral unit noise is correlated: its std over one frame varies more than white noise's.
        assert abs(measured / math.sqrt(expected**2 + 1.0 / 12.0) - 1.0) < 0.06, (level, measured, expected)
    # The same component without its law: no 8-bit route can draw it, and the composer does.
    lawless = dataclasses.replace(WHITE_HUM, white_variance=None)
    monkeypatch.setattr(components, "NOISE_COMPONENTS", (*components.NOISE_COMPONENTS[:-1], lawless))
    assert ClipSynthesizer(parameters, generator=torch.Generator()).route_name == "composer"
    assert ClipSynthesizer(spectral, generator=torch.Generator()).route_name == "composer"


class _Dimming:
    """A light component's stream stage declared in the test: every frame's gain is 1 - dim."""

    def __init__(self, dim: float) -> None:
        self.dim = dim

    @property
    def active(self) -> bool:
        return self.dim > 0

    def next(self, generator: torch.Generator | None) -> float:
        return 1.0 - self.dim


def _draw_dimming(
    clean: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    dim = values["dim"][..., 0].reshape(*values["dim"].shape[:-1], *([1] * 4))
    return (1.0 - dim).expand(*clean.shape[:-3], 1, 1, 1)


DIMMING = NoiseComponent(
    name="dimming",
    parameters=(Parameter("dim", 1, "share of the light a filter takes", 0.9, (0.0, 0.5), since_version=7),),
    structure="exposure",
    draw=_draw_dimming,
    stream_stage=lambda values, device: _Dimming(values.scalar("dim")),
    variance=None,
    reference="a light component that exists only in this test",
)


def test_a_light_component_is_run_by_streams_from_its_record(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(components, "NOISE_COMPONENTS", (*components.NOISE_COMPONENTS, DIMMING))
    parameters = ClipParameters(NoiseValues.from_values({"dim": 0.5}), Darkening(0.5, 1.0))
    frame = torch.full((3, 16, 24), 200, dtype=torch.uint8)
    # No noise: the darkened level times the component's gain, 0.5 * 0.5 * 200, in a stream and in a whole clip.
    streamed = torch.stack(ClipSynthesizer(parameters, generator=torch.Generator()).push(frame))
    assert streamed.unique().tolist() == [50]
    # A whole clip: the composer's gains come from the component's draw.
    gains = exposure_gains(frame[None].float() / 255.0, parameters.noise, generator=torch.Generator())
    assert gains is not None and gains.flatten().tolist() == [0.5]


def _freeze_after_frame(
    clean: torch.Tensor,
    finished: torch.Tensor,
    values: NoiseValues,
    generator: torch.Generator | None,
    held: dict[str, torch.Tensor],
) -> torch.Tensor:
    # Every frame after the first is the first finished frame again: a stuck decoder.
    return held.setdefault("freeze", finished)


FREEZE = NoiseComponent(
    name="freeze",
    parameters=(Parameter("freeze", 1, "whether the decoder is stuck", 1.0, (0.0, 1.0), since_version=7),),
    structure="output",
    draw=lambda noisy, values, generator: noisy,
    after_frame=_freeze_after_frame,
    variance=None,
    reference="an output stage across frames that exists only in this test",
)


def test_an_output_stage_across_frames_runs_after_each_finished_frame_from_its_record(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(components, "NOISE_COMPONENTS", (*components.NOISE_COMPONENTS, FREEZE))
    parameters = ClipParameters(NoiseValues.from_values({"freeze": 1.0, "read": 0.05}), Darkening(0.5, 1.0))
    frames = [torch.full((3, 16, 24), level, dtype=torch.uint8) for level in (100, 200, 50)]
    stream = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(0))
    finished = [stream(frame) for frame in frames]
    assert all(torch.equal(frame, finished[0]) for frame in finished[1:])
    # Without it, the frames differ (their noise and their levels).
    plain = ClipParameters(NoiseValues.from_values({"read": 0.05}), Darkening(0.5, 1.0))
    stream = ClipSynthesizer(plain, generator=torch.Generator().manual_seed(0))
    unfrozen = [stream(frame) for frame in frames]
    assert not torch.equal(unfrozen[0], unfrozen[1])
