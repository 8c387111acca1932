"""The noise of a profile, read off a reference: the network's values, the column components decided on the
reference itself, and the noise's spectrum measured on it.

The network's estimate of every crop is a full v; the profile holds their median (robust to crops where content,
clipping or a light source misleads the network) and, as ``ranges``, the 10th to 90th percentile across crops, so
that ``apply`` can reproduce the spread the reference shows. Two things are measured on the reference rather than
taken from the network: whether it shows column patterns at all
(:func:`darksynth.estimation.noise.columns.column_presence`; without them the column components are set absent, since
the network never predicts exactly zero), and, for the network of the sRGB vocabulary, the spectral model's level curve,
octaves and compression (:func:`darksynth.estimation.noise.spectrum.estimate_spectrum`), which replace the network's
heteroscedastic values. Last, how much noise the profile adds on the reference (the "nearly noise-free" warning).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import torch

from darksynth.cameras.prior import CameraPrior, shipped_prior
from darksynth.estimation.findings import Findings
from darksynth.estimation.noise.camera_conditional import CameraPriorUse
from darksynth.estimation.noise.columns import decide_columns
from darksynth.estimation.noise.jpeg_grid import jpeg_grid
from darksynth.estimation.noise.network_reading import run_network
from darksynth.estimation.noise.self_check import check_level
from darksynth.estimation.noise.spectrum import estimate_spectrum
from darksynth.estimation.reference import Reference
from darksynth.models.den import DEN
from darksynth.noise.components import NoiseModel, noise_component, noise_parameter
from darksynth.noise.level import channel_noise_std, mean_noise_variance
from darksynth.noise.spectral import LEVEL_KNOTS
from darksynth.noise.spectral_components import SPECTRUM_REPLACES
from darksynth.noise.values import NoiseValues
from darksynth.profile import Range

NOISE_FREE_STD = 0.5 / 255
"""Below this noise std (half an 8-bit level) on the reference, a profile is nearly noise-free: a pixel on an
8-bit level rounds back to it in 68% of the draws (|n| < 0.5 level, one std)."""

REFINE_MIN_SIDE = 64
"""Smallest side the spectrum is measured on: below it the flat blocks of each level are too few, and the
network's values stay."""

CERTAIN_LEVEL_SIDE = 128
"""Smallest side whose measured level is stated without doubt: under it a reference holds at most 16 blocks of 32 px
and one or two of them decide each channel's level (a 96-px crop read green 1.33x its true level); the measurement
stands, with a warning that it is uncertain."""


@dataclass(frozen=True)
class NoiseEstimateOptions:
    """How the noise is read off a reference: the one record of the choices that reach the measurements
    (``estimate``'s and the command line's; the darkening and the light take none).

    Attributes:
        batch: crops per forward pass of the network.
        device: torch device the network runs on.
        refine: after the sRGB network, measure the noise's spectrum on the reference itself
            (docs/spectral-noise.md); False keeps the network's values (the ablation).
        camera_prior: what the reference cannot show, taken from a prior over real cameras
            (docs/camera-prior.md); None (the default) leaves it out: leave-one-set-out on the real pairs the
            prior's expectation was further from the real than none.
        jpeg_texture: without ``camera_prior``, a single image that shows a camera JPEG's block grid
            (:mod:`~darksynth.estimation.noise.jpeg_grid`) takes its texture dependence from the prior, which it
            otherwise cannot show (on polyu's 100 pairs, leave-one-set-out, it brought the level from 0.82 / 0.86 /
            0.81 to 1.07 / 1.13 / 1.03 of the real); the sets without that grid keep none.
        jpeg_texture_prior: the prior it takes it from; None: the shipped one (an evaluation gives the prior fitted
            without the set it judges).
    """

    batch: int = 16
    device: torch.device | str = "cpu"
    refine: bool = True
    camera_prior: CameraPriorUse | None = None
    jpeg_texture: bool = True
    jpeg_texture_prior: CameraPrior | None = None


@dataclass
class NoiseEstimate:
    """The noise values a profile takes, their ranges, the network's values per crop (N,), what was read (the
    profile's ``meta`` entries of the noise) and the warnings of what could not be."""

    noise: NoiseValues
    ranges: dict[str, tuple[Range, ...]]
    per_crop: NoiseValues
    meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def refines(noise_model: NoiseModel, refine: bool = True) -> bool:
    """Whether ``estimate`` (asked to ``refine``) measures the spectrum after a network of this noise model: the
    sRGB vocabulary's only; the paper model stays the paper's."""
    return refine and noise_model == "srgb"


def estimate_noise(reference: Reference, network: DEN, options: NoiseEstimateOptions) -> NoiseEstimate:
    """The network on the reference's crop grid, the columns decided, and with ``options.refine`` the spectrum
    measured; what was read is the record's ``meta``, what could not be its ``warnings``."""
    frames = reference.frames
    found = run_network(frames, network, batch=options.batch, device=options.device)
    noise = found.noise
    findings = Findings(
        {
            "estimator": f"DEN {network.config.variant} width {network.config.width} depth {network.config.depth}",
            "noise_model": network.noise_model,
            "crops": found.per_crop.batch_shape[0],
            "frames": int(frames.shape[0]),
            "aggregate": "median over crops; ranges are the 10th-90th percentiles",
        }
    )
    noise, columns = decide_columns(frames, reference.measured, noise)
    findings.meta["columns"] = columns
    # A parameter the estimate set itself (a column component found absent, a measured one) loses the network's
    # range: ``apply --jitter`` would otherwise draw the network's values back.
    replaced = list(columns.get("set_absent", []))
    if refines(network.noise_model, options.refine) and not reference.all_uniform:
        camera_prior, grid = _texture_prior(frames, options)
        findings.meta |= grid
        noise, measured_names, spectrum = _measure_spectrum(frames, noise, reference.name, camera_prior)
        findings.include(spectrum)
        replaced += measured_names
    noise_std = profile_noise_std(noise, frames, reference.measured)
    findings.meta["noise_std_8bit"] = round(noise_std * 255, 3)
    if noise_std < NOISE_FREE_STD:
        findings.warnings.append(
            f"{reference.name}: nearly noise-free; the profile adds noise of std {noise_std * 255:.2f} "
            f"8-bit levels on it (below {NOISE_FREE_STD * 255:.1f})"
        )
    if frames.shape[0] == 1:
        findings.meta["note"] = (
            "single image: temporal banding cannot be told from banding; their split is the network's prior "
            "(what it learned from the training table's ranges), not a measurement"
        )
    ranges = {name: spread for name, spread in found.ranges.items() if name not in replaced}
    return NoiseEstimate(noise, ranges, found.per_crop, meta=findings.meta, warnings=findings.warnings)


def _texture_prior(frames: torch.Tensor, options: NoiseEstimateOptions) -> tuple[CameraPriorUse | None, dict[str, Any]]:
    """The camera prior the measurement takes, and the meta entry of the JPEG grid: ``options.camera_prior`` when
    given; else, for one image showing a camera JPEG's grid, the texture dependence alone from
    ``options.jpeg_texture_prior`` (the shipped prior when None). A clip is never gated: a video codec's blocks
    are not a still camera's JPEG."""
    if options.camera_prior is not None or not options.jpeg_texture or frames.shape[0] != 1:
        return options.camera_prior, {}
    grid = jpeg_grid(frames[0])
    note: dict[str, Any] = {"shown": grid.shown, "score": round(grid.score, 3)}
    if not grid.shown:
        return None, {"jpeg_grid": note}
    prior = options.jpeg_texture_prior if options.jpeg_texture_prior is not None else shipped_prior()
    note["texture_from"] = f"the camera prior over {', '.join(prior.sets)}"
    return CameraPriorUse(prior, octaves=False), {"jpeg_grid": note}


def _measure_spectrum(
    reference: torch.Tensor,
    noise: NoiseValues,
    source: str,
    camera_prior: CameraPriorUse | None,
) -> tuple[NoiseValues, tuple[str, ...], Findings]:
    """The network's values with the heteroscedastic part and compression replaced by the measured spectrum, the
    names of the replaced parameters, and the findings (the measurement's record is ``meta["spectrum"]``)."""
    findings = Findings()
    if min(reference.shape[-2:]) < REFINE_MIN_SIDE:
        findings.warnings.append(
            f"{source}: {reference.shape[-1]}x{reference.shape[-2]} is too small to measure the noise's spectrum on "
            f"(needs {REFINE_MIN_SIDE} px a side); the profile keeps the network's values, which are weaker and "
            "greyer than real noise (docs/spectral-noise.md)"
        )
        findings.meta["spectrum"] = {"method": "not measured: reference too small"}
        return noise, (), findings
    if min(reference.shape[-2:]) < CERTAIN_LEVEL_SIDE:
        findings.warnings.append(
            f"{source}: {reference.shape[-1]}x{reference.shape[-2]} holds few blocks to measure the noise on (under "
            f"{CERTAIN_LEVEL_SIDE} px a side): the level it measures per channel is unreliable"
        )
    network_curve = network_level_curve(noise)
    found = estimate_spectrum(reference, name=source, prior_curve=network_curve, camera_prior=camera_prior)
    neutral = {name: noise_parameter(name).neutral for name in SPECTRUM_REPLACES}
    measured = noise.replace(**neutral, **{name: value for name, value in found.values.items()})
    # The measurement checked on its own reference: a level the reference contradicts is not kept.
    check = check_level(reference[0], measured, network_curve, found.meta["denoiser_strength_8bit"], source)
    measured = measured.replace(level_curve=check.curve.flatten().to(measured["level_curve"]))
    replaced = (*SPECTRUM_REPLACES, "compression")
    findings.warnings += found.warnings + check.warnings
    findings.meta["spectrum"] = found.meta | {
        "self_check": check.meta,
        "network_values": {name: [round(float(v), 5) for v in noise[name].tolist()] for name in replaced},
    }
    return measured, replaced, findings


def network_level_curve(noise: NoiseValues) -> torch.Tensor:
    """(3, 8) noise std per channel at the spectral model's level knots that the network's heteroscedastic values
    give (``g_c^2 (shot^2 x + read^2)``): the shape the measured level curve follows where the reference shows no
    unclipped flat block. Only the heteroscedastic component's parameters are passed on, so the column components
    the profile keeps beside the curve are not counted in it."""
    parameters = {p.name: noise[p.name] for p in noise_component("heteroscedastic").parameters}
    return channel_noise_std(parameters, torch.tensor(LEVEL_KNOTS, dtype=torch.float64)).T.contiguous()


def profile_noise_std(noise: NoiseValues, reference: torch.Tensor, frames: Sequence[int] | None = None) -> float:
    """The std of the noise a profile's values add on a reference (T, C, H, W) (on the given ``frames``, default
    all), before clipping and rounding.

    The variance depends on the reference only through its channel means, which are passed on as a 1 x 1
    frame: the whole reference in float64 would be a copy of 800 MB for 16 frames of 1080p.
    """
    chosen = range(reference.shape[0]) if frames is None else frames
    channel_means = torch.stack([reference[i].mean(dim=(1, 2)) for i in chosen]).mean(0)
    channel_means = channel_means.to(torch.float64).reshape(1, -1, 1, 1)
    batched = noise.map(lambda t: t[None].to(torch.float64))
    return float(mean_noise_variance(batched, channel_means).clamp_min(0).sqrt())
