"""darksynth: realistic synthetic low-light images and videos from clean ones.

Darkening and a physically based sensor-noise model whose parameters come from a noise profile, estimated
zero-shot from one real low-light reference.

The public names are loaded on first use (PEP 562): ``import darksynth`` alone, as the command line's
``--version`` does, does not import torch.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

from darksynth.version import __version__

if TYPE_CHECKING:
    from darksynth.light.darkening import Darkening, darken
    from darksynth.profile import Profile, load_profile, save_profile
    from darksynth.recipe import ClipParameters, ClipRecipe, draw_clip_parameters
    from darksynth.synthesize import ClipSynthesizer, LowLightResult, synthesize

_PUBLIC: dict[str, str] = {
    "ClipParameters": "darksynth.recipe",
    "ClipRecipe": "darksynth.recipe",
    "ClipSynthesizer": "darksynth.synthesize",
    "Darkening": "darksynth.light.darkening",
    "LowLightResult": "darksynth.synthesize",
    "Profile": "darksynth.profile",
    "darken": "darksynth.light.darkening",
    "draw_clip_parameters": "darksynth.recipe",
    "load_profile": "darksynth.profile",
    "save_profile": "darksynth.profile",
    "synthesize": "darksynth.synthesize",
}

__all__ = [
    "ClipParameters",
    "ClipRecipe",
    "ClipSynthesizer",
    "Darkening",
    "LowLightResult",
    "Profile",
    "__version__",
    "darken",
    "draw_clip_parameters",
    "load_profile",
    "save_profile",
    "synthesize",
]


def _load(name: str) -> Any:
    return getattr(importlib.import_module(_PUBLIC[name]), name)


def __getattr__(name: str) -> Any:
    if name not in _PUBLIC:
        raise AttributeError(f"module 'darksynth' has no attribute {name!r}")
    value = _load(name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))


class _Package(types.ModuleType):
    """``darksynth.synthesize`` is the function, as it was when this file imported it eagerly, although a
    submodule has the same name: the import system sets the package's attribute to the submodule once that is
    imported, which a property with a setter that keeps the function (the submodule stays in sys.modules) undoes."""

    @property
    def synthesize(self) -> Any:
        return _load("synthesize")

    @synthesize.setter
    def synthesize(self, value: Any) -> None:
        del value


sys.modules[__name__].__class__ = _Package
