"""Light: everything between the clean scene and the dark signal the noise is added to.

- the darkening of the paper, x_d = alpha * x ** (1 / gamma) (:mod:`~darksynth.light.darkening`);
- the tone distribution of images (:mod:`~darksynth.light.tones`, from the block statistics of
  :mod:`~darksynth.light.tone_blocks`) and the darkening line fitted between two of them
  (:mod:`~darksynth.light.tone_fit`);
- light beyond the darkening: motion blur along the scene's own flow and camera shake
  (:mod:`~darksynth.light.motion_blur`, in linear light: :mod:`~darksynth.light.linear_light`), the shutter stage of
  a stream and of a clip (:mod:`~darksynth.light.shutter`), and the per-frame gain of flicker
  (:mod:`~darksynth.light.flicker`).

All are pure functions on frames and sit below the noise model. An input's darkening matched to a reference's
exposure simulates the profile's noise on the input, so it is a module above the noise model, not of this package:
:mod:`darksynth.exposure` (``tests/test_layers.py``). Blur and flicker are components of the one table
(:mod:`darksynth.noise.light_components` declares them on the functions here), carried with the noise values. The
estimators of light are in :mod:`darksynth.estimation` (``darkening``, ``motion``, ``flicker``, ``shutter_fit``).
"""

from darksynth.light.flicker import FlickerGains
from darksynth.light.motion_blur import MotionBlurStream, blur_frame, shake_blur

__all__ = ["FlickerGains", "MotionBlurStream", "blur_frame", "shake_blur"]
