"""The light a profile keeps, read off a reference clip: the shutter's exposure fraction and the flicker
(:func:`darksynth.estimation.light.motion.estimate_motion`), held within the table's bounds, with what was measured and
which prior stands where nothing could be."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from darksynth.estimation.light.motion import SHUTTER_LIMIT, estimate_motion
from darksynth.estimation.reference import Reference
from darksynth.noise.components import noise_parameter
from darksynth.noise.values import NoiseValues


@dataclass(frozen=True)
class LightReading:
    """What :func:`estimate_light` read: the noise values with the light set, ``meta.light`` and the warnings."""

    noise: NoiseValues
    meta: dict[str, Any]
    warnings: list[str]


def estimate_light(reference: Reference, noise: NoiseValues) -> LightReading:
    """``noise`` with the light values read off the reference; ``meta`` says what was measured and which prior
    stands. A clip where they cannot be read warns (a single image cannot show either: its priors are stated in
    ``meta`` only)."""
    motion = estimate_motion(reference.frames, uniform=reference.uniform, cuts=reference.cuts)
    warnings = [f"{reference.name}: {note}" for note in motion.notes] if reference.frames.shape[0] > 1 else []
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
            warnings.append(f"{reference.name}: {key} measured {measured[key]:.3g} is held at its bound {value:g}")
    return LightReading(noise.replace(**bounded), motion.to_meta(), warnings)
