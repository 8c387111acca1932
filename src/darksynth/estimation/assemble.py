"""Reference -> one record -> independent measurements (noise, darkening, light) -> noise profile.

The reference is read once into a :class:`~darksynth.estimation.reference.Reference` (its frames, the frames to
measure, the uniform frames, the scene cuts); the noise (:mod:`~darksynth.estimation.noise.noise_estimate`: the network,
the columns, the spectrum), the darkening (:mod:`~darksynth.estimation.darkening_reading`) and the light
(:mod:`~darksynth.estimation.light.light_reading`) are each read off it without looking at the others' results; the
profile assembles them, with everything each measurement found in ``meta`` and everything it could not read in the
warnings.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from darksynth.estimation.darkening_reading import estimate_profile_darkening
from darksynth.estimation.light.light_reading import estimate_light
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions, estimate_noise
from darksynth.estimation.noise.spectrum import TEMPORAL_FRAMES
from darksynth.estimation.reference import MAX_FRAMES, describe_reference, load_reference, reference_warnings
from darksynth.models.den import DEN
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile


@dataclass(frozen=True)
class EstimateOptions:
    """How ``estimate`` reads a reference file and runs on it (the network is chosen by the caller).

    Attributes:
        clip: a folder is the frames of one clip (without it, a folder is refused).
        max_frames: frames read from a video or frame folder.
        noise: how the noise is read off the reference (the only measurement that takes options).
    """

    clip: bool = False
    max_frames: int = MAX_FRAMES
    noise: NoiseEstimateOptions = field(default_factory=NoiseEstimateOptions)


def estimate_file(path: Path, network: DEN, options: EstimateOptions) -> Estimate:
    """Read a reference file or frame folder and estimate its profile (the ``estimate`` job)."""
    frames = load_reference(path, clip=options.clip, max_frames=options.max_frames)
    return estimate(frames, network, source=str(path), options=options.noise)


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
    options: NoiseEstimateOptions | None = None,
) -> Estimate:
    """Estimate a noise profile from reference frames (T, 3, H, W) in [0, 1].

    Args:
        source: the reference's name, for ``meta`` and the warnings.
        options: how the noise is read (:class:`~darksynth.estimation.noise.noise_estimate.NoiseEstimateOptions`;
            None: its defaults).
            With ``refine`` and a network of the sRGB vocabulary, the spectral model is measured on the reference
            (:func:`darksynth.estimation.noise.spectrum.estimate_spectrum`): the network's heteroscedastic values
            and compression are replaced by the spectrum's, its column components kept; skipped, with a warning,
            on a reference smaller than :data:`~darksynth.estimation.noise.noise_estimate.REFINE_MIN_SIDE`. The
            paper's model keeps the network's values.
    """
    record = describe_reference(reference, source)
    # Each measurement returns its record (values, meta, warnings); the profile is their composition.
    found = estimate_noise(record, network, options or NoiseEstimateOptions())
    darkening = estimate_profile_darkening(record)
    light = estimate_light(record, found.noise)
    meta: dict[str, Any] = {"source": source, **({"scene_cuts": record.cuts} if record.cuts else {})}
    meta |= found.meta | {"darkening": darkening.meta, "light": light.meta}
    warnings = [
        *reference_warnings(record, spectrum_frames=TEMPORAL_FRAMES),
        *found.warnings,
        *darkening.warnings,
        *light.warnings,
    ]
    ranges = found.ranges | darkening.ranges
    profile = Profile(noise=light.noise, darkening=darkening.darkening, ranges=ranges, meta=meta, tone=darkening.tone)
    return Estimate(profile=profile, per_crop=found.per_crop, warnings=warnings)
