"""The shutter's stage of a stream of torch frames (C, H, W): motion blur along the flow for a clip, camera shake
for a single image. The blur itself runs on the CPU on (H, W, C) arrays (:mod:`darksynth.light.motion_blur`);
frames come back on the stream's device."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import torch

from darksynth.light.motion_blur import MotionBlurStream, shake_blur


class ShutterStage:
    """Clean frames through the shutter, before darkening and noise.

    Args:
        exposure_fraction: ``s`` in [0, 1]; 0 passes a clip's frames straight through.
        shake_length: a single image's shake path as a fraction of its longer side; shake_angle: its direction
            in degrees.
        device: where the frames go back to.
    """

    def __init__(self, exposure_fraction: float, shake_length: float, shake_angle: float, device: torch.device) -> None:
        self.device = device
        self.shake_length = shake_length
        self.shake_angle = shake_angle
        self._blur = MotionBlurStream(exposure_fraction) if exposure_fraction > 0 else None

    def push(self, frame: torch.Tensor) -> list[torch.Tensor]:
        """A clip's next frame in, the frames whose blur is done out (one behind: a frame's blur follows the flow to
        both its neighbours). At most two frames are held."""
        blur = self._blur
        return [frame] if blur is None else self._on_arrays(blur.push, frame)

    def finish(self) -> list[torch.Tensor]:
        """The frame still held at the end of the clip."""
        blur = self._blur
        return [] if blur is None else self._on_arrays(lambda _: blur.finish(), None)

    def image(self, frame: torch.Tensor) -> torch.Tensor:
        """A single image, blurred by the camera shake (unchanged without)."""
        length = self.shake_length * max(frame.shape[-2:])
        if length <= 0:
            return frame
        (shaken,) = self._on_arrays(lambda pixels: [shake_blur(pixels, length, self.shake_angle)], frame)
        return shaken

    def _on_arrays(self, stage: Callable[[Any], list[np.ndarray]], frame: torch.Tensor | None) -> list[torch.Tensor]:
        pixels = None if frame is None else frame.permute(1, 2, 0).contiguous().cpu().numpy()
        return [torch.from_numpy(out).permute(2, 0, 1).to(self.device) for out in stage(pixels)]


def scene_blur(
    clip: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    """The clean clips (*batch, T, C, H, W) as the shutter saw them: a clip of several frames blurred along its
    flow over its exposure fraction, a single frame by its camera shake. Deterministic (``generator`` unused: the
    shake's length and angle are values of their own, drawn within ranges like any other)."""
    flat = clip.reshape(-1, *clip.shape[-4:])
    fractions = values["exposure_fraction"].reshape(-1, 1).expand(flat.shape[0], 1)
    lengths = values["shake_length"].reshape(-1, 1).expand(flat.shape[0], 1)
    angles = values["shake_angle"].reshape(-1, 1).expand(flat.shape[0], 1)
    out = []
    for index, one in enumerate(flat):
        # The stage a stream runs (ClipSynthesizer), here on a whole clip.
        stage = ShutterStage(float(fractions[index, 0]), float(lengths[index, 0]), float(angles[index, 0]), one.device)
        frames = one.float() if one.dtype.is_floating_point else one
        if len(frames) > 1:
            blurred = [shot for frame in frames for shot in stage.push(frame)] + stage.finish()
        else:
            blurred = [stage.image(frames[0])]
        out.append(torch.stack(blurred).to(one.dtype))
    return torch.stack(out).reshape(clip.shape)
