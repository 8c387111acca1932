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

from darksynth.cameras.prior import shipped_prior
from darksynth.estimation.darkening_reading import estimate_profile_darkening
from darksynth.estimation.light.light_reading import estimate_light
from darksynth.estimation.noise.camera_conditional import CameraPriorUse
from darksynth.estimation.noise.noise_estimate import estimate_noise
from darksynth.estimation.noise.spectrum import TEMPORAL_FRAMES
from darksynth.estimation.reference import MAX_FRAMES, describe_reference, load_reference, reference_warnings
from darksynth.models.den import DEN
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile


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
    camera_prior: bool = False
    """Take what the reference cannot show (the noise's dependence on texture) from the shipped prior over real
    cameras (``--camera-prior``; docs/camera-prior.md): off by default, since leave-one-set-out on the real pairs
    the prior's expectation was further from the real than none."""
    prior_octaves: bool = False
    """With ``camera_prior``, also take the coarse octaves the reference cannot show from the prior
    (``--prior-octaves``), not continue the finer ones
    (:class:`~darksynth.estimation.noise.camera_conditional.CameraPriorUse`)."""


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
        camera_prior=CameraPriorUse(shipped_prior(), octaves=options.prior_octaves) if options.camera_prior else None,
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
    camera_prior: CameraPriorUse | None = None,
) -> Estimate:
    """Estimate a noise profile from reference frames (T, 3, H, W) in [0, 1].

    Args:
        refine: for a network of the sRGB vocabulary, measure the spectral model on the reference
            (:func:`darksynth.estimation.noise.spectrum.estimate_spectrum`): the network's heteroscedastic values and
            compression are replaced by the spectrum's, its column components kept; skipped, with a warning, on a
            reference smaller than :data:`~darksynth.estimation.noise.noise_estimate.REFINE_MIN_SIDE`. The paper's model
            keeps the network's values.
        camera_prior: what the reference cannot show, taken from a prior over real cameras
            (:func:`darksynth.estimation.noise.spectrum.estimate_spectrum`); None (the default) leaves it out.
    """
    record = describe_reference(reference, source)
    # Each measurement returns its record (values, meta, warnings); the profile is their composition.
    found = estimate_noise(record, network, batch=batch, device=device, refine=refine, camera_prior=camera_prior)
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
