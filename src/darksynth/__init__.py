"""darksynth: realistic synthetic low-light images and videos from clean ones.

Darkening and a physically based sensor-noise model whose parameters come from a noise profile, estimated
zero-shot from one real low-light reference.
"""

from darksynth.darkening import Darkening, darken
from darksynth.profile import Profile, load_profile, save_profile
from darksynth.synthesize import ClipParameters, ClipSynthesizer, LowLightResult, draw_clip_parameters, synthesize

__version__ = "0.1.0"

__all__ = [
    "ClipParameters",
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
