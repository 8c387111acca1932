"""Named kinds of camera to draw from: the prior over every real camera in the bank, or one kind's own prior.

Each preset is the prior (:func:`~darksynth.cameras.prior.fit_prior`) fitted on the bank's records of the sets
that show that kind of camera; a clip that names a preset gets a whole camera drawn from it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

from darksynth.cameras.bank import shipped_bank
from darksynth.cameras.prior import CameraPrior, fit_prior, shipped_prior
from darksynth.errors import DarksynthError


@dataclass(frozen=True)
class Preset:
    """A kind of camera: what it is in a few words (for the command line's help), the sets of real pairs it is
    measured on and what they are."""

    name: str
    kind: str
    sets: tuple[str, ...]
    source: str


PRESETS: dict[str, Preset] = {
    preset.name: preset
    for preset in (
        Preset(
            "phone",
            "smartphones (SIDD)",
            ("sidd",),
            "smartphones in low light: 6 SIDD pairs (Abdelhamed et al. 2018), PNG, noise std 8-31 of 255",
        ),
        Preset(
            "dslr",
            "DSLRs at ISO 1600-6400 (Nam et al.)",
            ("nam-cc15", "nam-cc60"),
            "Canon 5D Mark III, Nikon D600 and D800 at ISO 1600-6400: 67 crops of Nam et al. 2016 (CC15, CC60), "
            "each clean image the mean of hundreds of shots of a still scene",
        ),
        Preset(
            "dslr-jpeg",
            "DSLRs' own JPEG at ISO 800-12800 (PolyU)",
            ("polyu",),
            "Canon 5D Mark II, 80D, 600D, Nikon D800 and Sony A7 II at ISO 800-12800, JPEG: 100 PolyU pairs "
            "(Xu et al. 2018)",
        ),
    )
}

CAMERA_CHOICES: tuple[str, ...] = ("prior", *PRESETS)
"""What a clip's camera can be drawn from: ``prior`` (every camera of the bank) or a preset."""

CAMERA_KINDS: dict[str, str] = {"prior": "every real camera of the bank", **{p.name: p.kind for p in PRESETS.values()}}
"""Each of :data:`CAMERA_CHOICES` in a few words."""


@functools.cache
def camera_source(name: str) -> CameraPrior:
    """The prior a camera named ``name`` (one of :data:`CAMERA_CHOICES`) is drawn from.

    Raises:
        DarksynthError: an unknown name.
    """
    if name == "prior":
        return shipped_prior()
    if name not in PRESETS:
        raise DarksynthError(f"unknown camera {name!r}; choose one of {', '.join(CAMERA_CHOICES)}")
    sets = frozenset(PRESETS[name].sets)
    return fit_prior(tuple(record for record in shipped_bank() if record.set in sets))
