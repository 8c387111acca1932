"""Reference -> crops or clips -> DEN -> robust aggregate -> noise profile.

The estimate of every crop is a full v; the profile holds their median (robust to crops where content,
clipping or a light source misleads the network) and, as ``ranges``, the 10th to 90th percentile across crops,
so that ``apply`` can reproduce the spread the reference shows. The darkening (alpha, gamma) is read from the
reference's tone distribution (:mod:`darksynth.estimation.darkening`); for a clip, its ``ranges`` are the 10th
to 90th percentile of the per-frame estimates.

Two things are measured on the reference itself rather than taken from the network: whether it shows column
patterns at all (:func:`darksynth.estimation.columns.column_presence`; without them the column components are
set absent, since the network never predicts exactly zero), and how much noise the profile would add on it (the
"nearly noise-free" warning).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from darksynth.estimation.columns import decide_columns
from darksynth.estimation.darkening import estimate_profile_darkening
from darksynth.estimation.motion import SHUTTER_LIMIT, estimate_motion
from darksynth.estimation.network import run_network
from darksynth.estimation.reference import (
    FLAT_STD,
    MAX_FRAMES,
    load_reference,
    scene_cuts,
    spread_frames,
    uniform_frames,
)
from darksynth.estimation.spectrum import TEMPORAL_FRAMES, estimate_spectrum
from darksynth.models.den import DEN
from darksynth.noise.components import NoiseModel, noise_component, noise_parameter
from darksynth.noise.level import channel_noise_std, mean_noise_variance
from darksynth.noise.spectral import LEVEL_KNOTS
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile

BRIGHT_MEAN = 0.35
"""A reference whose mean level is above this is not low-light; its estimate is less reliable."""

MEASURED_FRAMES = 4
"""Frames (evenly spread) on which the column presence and the profile's noise level are measured."""

NOISE_FREE_STD = 0.5 / 255
"""Below this noise std (half an 8-bit level) on the reference, a profile is nearly noise-free: a pixel on an
8-bit level rounds back to it in 68% of the draws (|n| < 0.5 level, one std)."""


@dataclass(frozen=True)
class EstimateOptions:
    """How ``estimate`` reads and runs on a reference file (the network is chosen by the caller).

    Attributes:
        clip: a folder is the frames of one clip (without it, a folder is refused).
        device: torch device the network runs on.
        max_frames: frames read from a video or frame folder.
        batch: crops per forward pass.
    """

    clip: bool = False
    device: str = "cpu"
    max_frames: int = MAX_FRAMES
    batch: int = 16
    refine: bool = True
    """After the sRGB network, measure the noise's spectrum on the reference itself (docs/spectral-noise.md);
    ``--no-refine`` keeps the network's values (the ablation)."""


def estimate_file(path: Path, network: DEN, options: EstimateOptions) -> Estimate:
    """Read a reference file or frame folder and estimate its profile (the ``estimate`` job)."""
    frames = load_reference(path, clip=options.clip, max_frames=options.max_frames)
    return estimate(
        frames,
        network,
        source=str(path),
        batch=options.batch,
        device=options.device,
        refine=options.refine,
    )


@dataclass
class Estimate:
    """A profile and what was learned on the way: per-crop values and warnings."""

    profile: Profile
    per_crop: NoiseValues
    """The network's estimate for each crop, batched (N,)."""
    warnings: list[str] = field(default_factory=list)


@torch.no_grad()
def estimate(
    reference: torch.Tensor,
    network: DEN,
    *,
    source: str = "",
    batch: int = 16,
    device: torch.device | str = "cpu",
    refine: bool = True,
) -> Estimate:
    """Estimate a noise profile from reference frames (T, 3, H, W) in [0, 1].

    Args:
        refine: for a network of the sRGB model, measure the spectral model on the reference
            (:func:`darksynth.estimation.spectrum.estimate_spectrum`): the network's heteroscedastic values and
            compression are replaced by the spectrum's, its column components kept; skipped, with a warning, on a
            reference smaller than :data:`REFINE_MIN_SIDE`. The paper's model keeps the network's values.
    """
    found = run_network(reference, network, batch=batch, device=device)
    per_crop, noise, ranges = found.per_crop, found.noise, dict(found.ranges)
    noise_model = network.noise_model
    meta: dict[str, Any] = {
        "source": source,
        "estimator": f"DEN {network.config.variant} width {network.config.width} depth {network.config.depth}",
        "noise_model": noise_model,
        "crops": per_crop.batch_shape[0],
        "frames": int(reference.shape[0]),
        "aggregate": "median over crops; ranges are the 10th-90th percentiles",
    }
    # A few frames spread over the clip measure the columns and the level: the whole 1080p clip took 1.5 s more.
    measured = spread_frames(reference.shape[0], MEASURED_FRAMES)
    noise = decide_columns(reference, measured, noise, ranges, meta)
    warnings: list[str] = []
    name = source or "reference"
    uniform = uniform_frames(reference)
    if uniform:
        which = "the reference is" if len(uniform) == reference.shape[0] else f"frames {uniform} are"
        warnings.append(
            f"{name}: {which} uniform (black, saturated or flat: std under {FLAT_STD * 255:.1f} 8-bit level): there "
            "is no noise to measure there, and what the profile holds from them is the network's output on a flat "
            "image, not a measurement"
        )
    cuts = scene_cuts(reference)
    if cuts:
        meta["scene_cuts"] = cuts
        warnings.append(
            f"{name}: scene cut before frame(s) {cuts}: the estimate mixes more than one scene (the spectrum reads "
            f"the first {TEMPORAL_FRAMES} frames, the darkening several spread over the clip); give one shot"
        )
    if refines(noise_model, refine) and len(uniform) < reference.shape[0]:
        noise = _measure_spectrum(reference, noise, ranges, meta, warnings, name)
    level = float(reference.mean())
    if level > BRIGHT_MEAN:
        warnings.append(
            f"{name}: mean level {level:.2f} is bright for a low-light reference; "
            "the estimate may be unreliable (on a clean daylight photo the profile holds what it reads of the "
            "photo's grain, JPEG residue and fine texture as noise, often several 8-bit levels)"
        )
    noise_std = profile_noise_std(noise, reference, measured)
    meta["noise_std_8bit"] = round(noise_std * 255, 3)
    if noise_std < NOISE_FREE_STD:
        warnings.append(
            f"{name}: nearly noise-free; the profile adds noise of std {noise_std * 255:.2f} "
            f"8-bit levels on it (below {NOISE_FREE_STD * 255:.1f})"
        )
    if reference.shape[0] == 1:
        meta["note"] = (
            "single image: temporal banding cannot be told from banding; their split is the network's prior "
            "(what it learned from the training table's ranges), not a measurement"
        )
    darkening, tone = estimate_profile_darkening(reference, name, ranges, meta, warnings)
    noise = _estimate_light(reference, noise, meta, warnings, name, uniform=uniform, cuts=cuts)
    profile = Profile(noise=noise, darkening=darkening, ranges=ranges, meta=meta, tone=tone)
    return Estimate(profile=profile, per_crop=per_crop, warnings=warnings)


def _estimate_light(
    reference: torch.Tensor,
    noise: NoiseValues,
    meta: dict[str, Any],
    warnings: list[str],
    name: str,
    *,
    uniform: list[int],
    cuts: list[int],
) -> NoiseValues:
    """The shutter's exposure fraction and the flicker of a reference clip into the profile's light, what was
    measured and which prior stands into ``meta.light``. A clip where they cannot be read warns (a single image
    cannot show either: its priors are stated in ``meta`` only)."""
    motion = estimate_motion(reference, uniform=uniform, cuts=cuts)
    meta["light"] = motion.to_meta()
    if reference.shape[0] > 1:
        warnings.extend(f"{name}: {note}" for note in motion.notes)
    measured = {
        "exposure_fraction": motion.exposure_fraction,
        "flicker": motion.flicker,
        "flicker_correlation": motion.flicker_correlation,
    }
    # Within the table's bounds: a clip whose exposure ramps by 2x reads as a flicker beyond what a profile holds.
    bounded = {
        key: min(max(value, noise_parameter(key).minimum), noise_parameter(key).maximum)
        for key, value in measured.items()
    }
    for key, value in bounded.items():
        # A blur longer than a shutter gives has its own note (from estimate_motion), which says why.
        explained = key == "exposure_fraction" and motion.exposure_fraction > SHUTTER_LIMIT
        if value != measured[key] and not explained:
            warnings.append(f"{name}: {key} measured {measured[key]:.3g} is held at its bound {value:g}")
    return noise.replace(**bounded)


def refines(noise_model: NoiseModel, refine: bool = True) -> bool:
    """Whether ``estimate`` (asked to ``refine``) measures the spectrum after a network of this noise model: the
    sRGB model's only; the paper model stays the paper's."""
    return refine and noise_model == "srgb"


REFINE_MIN_SIDE = 64
"""Smallest side the spectrum is measured on: below it the flat blocks of each level are too few, and the
network's values stay."""


SPECTRUM_REPLACES = ("shot", "read", "channel_gain", "correlation_length", "channel_correlation", "chroma_length")
"""The network's sRGB values the measured spectrum replaces: its level curve and octaves hold the level and the
structure (and its ``compression`` the JPEG stage); the column components stay the network's."""


def _measure_spectrum(
    reference: torch.Tensor,
    noise: NoiseValues,
    ranges: dict[str, tuple[tuple[float, float], ...]],
    meta: dict[str, Any],
    warnings: list[str],
    source: str,
) -> NoiseValues:
    """The network's values with the heteroscedastic part and compression replaced by the measured spectrum; the
    replaced parameters lose their ranges (``apply --jitter`` would otherwise add the network's noise back)."""
    if min(reference.shape[-2:]) < REFINE_MIN_SIDE:
        warnings.append(
            f"{source}: {reference.shape[-1]}x{reference.shape[-2]} is too small to measure the noise's spectrum on "
            f"(needs {REFINE_MIN_SIDE} px a side); the profile keeps the network's values, which are weaker and "
            "greyer than real noise (docs/spectral-noise.md)"
        )
        meta["spectrum"] = {"method": "not measured: reference too small"}
        return noise
    found = estimate_spectrum(reference, name=source, prior_curve=network_level_curve(noise))
    neutral = {name: noise_parameter(name).neutral for name in SPECTRUM_REPLACES}
    measured = noise.replace(**neutral, **{name: value for name, value in found.values.items()})
    replaced = (*SPECTRUM_REPLACES, "compression")
    for name in replaced:
        ranges.pop(name, None)
    warnings.extend(found.warnings)
    meta["spectrum"] = found.meta | {
        "network_values": {name: [round(float(v), 5) for v in noise[name].tolist()] for name in replaced}
    }
    return measured


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
