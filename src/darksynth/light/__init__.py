"""Light beyond noise: what happens to the clean scene before it is darkened and noised (motion blur along the
scene's own flow, camera shake) and the per-frame gain on the darkening (flicker).

These are components of the one table (:mod:`darksynth.noise.light_components`), carried with the noise values;
this package holds their pure functions, on frames as images and videos are read (numpy, OpenCV).
"""

from darksynth.light.flicker import FlickerGains
from darksynth.light.motion_blur import MotionBlurStream, blur_frame, shake_blur

__all__ = ["FlickerGains", "MotionBlurStream", "blur_frame", "shake_blur"]
