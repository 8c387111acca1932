"""Clean image, clip or stream -> darkened and noisy low-light version, with the exact parameters used.

Three lines for a researcher::

    profile = darksynth.load_profile("night.json")
    result = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(0))
    result.image, result.parameters

The command line streams frames through :class:`ClipSynthesizer`, the same code that ``synthesize`` runs on
8-bit input, so the library and the tool give the same output for the same seed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Unpack

import numpy as np
import torch

from darksynth.io.arrays import clips_from_numpy, clips_to_numpy
from darksynth.light.darkening import Darkening, darken
from darksynth.noise.components import noise_parameter
from darksynth.noise.frame_routes import ClipState, ComposerRoute, SpectralRoute, eight_bit_route
from darksynth.noise.simulate import (
    LightStream,
    add_noise,
    exposure_gains,
    finish_clip,
    finish_frame,
    frames_finished_across,
    scene_stage,
)
from darksynth.profile import Profile
from darksynth.recipe import ClipParameters, RecipeChoices, augmenting_recipe
from darksynth.tensors import CLIP_DIMS, eight_bit_levels, scale_channels, to_8bit_levels, to_dtype, unit_float

logger = logging.getLogger(__name__)


class ClipSynthesizer:
    """Darkening + f(v) for the frames of one clip, one frame at a time (memory does not grow with length).

    The light stage comes first (the shutter's blur and shake, the frame's flicker gain on the darkening); then the
    frame's route through f(v), chosen once for the clip's 8-bit frames by
    :data:`darksynth.noise.frame_routes.ROUTES` (the fused white kernel, the spectral tables, their compiled
    kernels, or the general composer, which every other dtype takes); then a codec's repeats of still cells
    (:mod:`darksynth.noise.codec_repeat`). Components a clip keeps fixed (temporal banding) and the spectrum's
    frame-to-frame state are held from the first frame on.

    Args:
        parameters: the clip's parameters (see :func:`draw_clip_parameters`).
        generator: source of randomness, consumed frame after frame.
        device: where the work runs (``"cpu"``, ``"cuda"``); frames are moved there and results returned there.
        compile: fuse the 8-bit kernels with ``torch.compile``; worth it for a long stream of same-sized frames.
        name: what the clip is called in log messages (its file or folder).
    """

    def __init__(
        self,
        parameters: ClipParameters,
        *,
        generator: torch.Generator | None = None,
        device: torch.device | str = "cpu",
        compile: bool = False,
        name: str = "",
    ) -> None:
        self.parameters = parameters
        self.name = name
        self.generator = generator
        self.device = torch.device(device)
        values = parameters.noise.to(self.device, torch.float32)
        self._state = ClipState(values, self.device, generator)
        # Each route holds the frame's darkening (the clip's, times the flicker gain once flicker draws one).
        self._route = eight_bit_route(self._state, parameters.darkening, compile=compile)
        self._composer = ComposerRoute(self._state, parameters.darkening)
        self._frame_shape: torch.Size | None = None
        self._frames_done = 0
        # Light, as the table's light components build their stream stages: the shutter (motion blur, shake), the
        # frame's darkening times its flicker gain.
        self._light = LightStream(values, self.device)
        self._finished_across = frames_finished_across(values)

    @property
    def route_name(self) -> str:
        """The route the clip's 8-bit frames take now: ``fused``, ``compiled spectral``, ``spectral`` or
        ``composer`` (:data:`darksynth.noise.frame_routes.ROUTES`)."""
        return self._route.name

    @property
    def held(self) -> dict[str, Any]:
        """The clip's state held from frame to frame (temporal banding's pattern, the spectrum's state, the codec's
        previous frame), by component."""
        return self._state.held

    def push(self, frame: torch.Tensor) -> list[torch.Tensor]:
        """The next frame (C, H, W) of a clip in, the low-light frames finished so far out, in order. With motion
        blur (``exposure_fraction`` > 0) a frame is finished when the next one arrives: call :meth:`finish` after
        the last frame (:class:`darksynth.light.shutter.ShutterStage`)."""
        return [self(clean) for clean in self._light.push(frame)]

    def finish(self) -> list[torch.Tensor]:
        """The clip's frames still held for their blur (none without motion blur)."""
        return [self(clean) for clean in self._light.finish()]

    def image(self, frame: torch.Tensor) -> torch.Tensor:
        """A single image (C, H, W): its camera shake, if any, and no flicker (it needs a sequence)."""
        return self._frame(self._light.image(frame), flicker=False)

    def __call__(self, frame: torch.Tensor) -> torch.Tensor:
        """Low-light version of one frame (C, H, W) of a clip whose light stage is done (as :meth:`push` gives
        it): uint8 in, uint8 out; uint16 and float likewise. Flicker, if any, is drawn here, and after the frame
        the codec's repeats of still cells from the previous one (:mod:`darksynth.noise.codec_repeat`)."""
        finished = self._frame(frame, flicker=True)
        if not self._finished_across:
            return finished
        clean = unit_float(frame.to(self.device))
        return finish_frame(clean, finished, self._state.values, generator=self.generator, held=self.held)

    def float_image_on_levels(self, image: torch.Tensor) -> torch.Tensor | None:
        """A float image (C, H, W) in [0, 1] whose values are 8-bit levels (``ToTensor`` of a PNG or JPEG) through
        the spectral tables, unrounded: the 8-bit route's draws, so the same result; None when the clip's route is
        not the spectral model's or the image is not on levels."""
        if not isinstance(self._route, SpectralRoute):
            return None
        levels = eight_bit_levels(image)
        if levels is None:
            return None
        return to_dtype(self._route.noisy(levels.to(self.device), rounded=False), image.dtype)

    def _set_gain(self, gain: float) -> None:
        """This frame's darkening: the clip's times the flicker gain (the routes' tables are redone)."""
        base = self.parameters.darkening or Darkening(alpha=1.0, gamma=1.0)
        darkening = Darkening(alpha=base.alpha * gain, gamma=base.gamma)
        self._route.set_darkening(darkening)
        self._composer.set_darkening(darkening)

    def _frame(self, frame: torch.Tensor, *, flicker: bool) -> torch.Tensor:
        if frame.dim() != 3:
            raise ValueError(f"expected a frame shaped (C, H, W), got shape {tuple(frame.shape)}")
        frame = frame.to(self.device)
        if self._frame_shape is not None and frame.shape != self._frame_shape:
            self._restart_for_new_size(frame.shape)
        self._frame_shape = frame.shape
        self._frames_done += 1
        if self.parameters.colour_scale is not None:
            frame = scale_channels(frame, self.parameters.colour_scale)
        if flicker and self._light.flickers:
            # The gain is drawn before the frame's noise, from the same generator.
            self._set_gain(self._light.gain(self.generator))
        route = self._route if frame.dtype == torch.uint8 else self._composer
        return route(frame)

    def _restart_for_new_size(self, shape: torch.Size) -> None:
        # A stream whose frames change size (a video that switches resolution, a folder of mixed sizes): the
        # held patterns (temporal banding) are tied to the width, and the compiled kernels to the shape, which
        # would recompile for seconds at every change. The clip's patterns are redrawn for the new size and its
        # frames go on through the general composer, which has the same law for any size.
        logger.warning(
            "%sframe size changed within a clip from %s to %s at frame %d: its held patterns are redrawn and its "
            "frames take the general composer",
            f"{self.name}: " if self.name else "",
            "x".join(map(str, self._frame_shape or ())),
            "x".join(map(str, shape)),
            self._frames_done,
        )
        self._state.held.clear()
        self._route = self._composer


@dataclass(frozen=True)
class LowLightResult:
    """A synthesized low-light image or clip and the parameters drawn for it.

    Attributes:
        image: the result, in the layout and dtype of the input.
        parameters: per clip (a list for batched input), a JSON-ready record of noise and darkening values.
    """

    image: torch.Tensor | np.ndarray
    parameters: dict[str, Any] | list[dict[str, Any]]


def synthesize(
    clean: torch.Tensor | np.ndarray,
    profile: Profile,
    *,
    generator: torch.Generator | None = None,
    device: torch.device | str | None = None,
    parameters: ClipParameters | None = None,
    **choices: Unpack[RecipeChoices],
) -> LowLightResult:
    """Make a low-light version of a clean image or clip with a noise profile.

    Args:
        clean: a torch tensor (C, H, W) image or (*batch, T, C, H, W) clips, uint8, uint16 or float in [0, 1];
            or a numpy array (H, W) grey, (H, W, C) image or (T, H, W, C) clip. Parameters are drawn once per
            clip. 8-bit clips run frame by frame through the fused kernel, as the command line does; float clips
            run through the vectorised composer.
        profile: the noise profile (see :func:`darksynth.profile.load_profile`).
        generator: source of randomness; pass a seeded one for reproducible output.
        device: where to compute; the input's device by default.
        parameters: the parameters every clip takes, chosen before (a transform's replay); None chooses each clip's
            by the recipe (:meth:`darksynth.recipe.ClipRecipe.choose`).
        choices: how each clip's parameters are chosen (:class:`darksynth.recipe.RecipeChoices`): ``darkening``,
            ``jitter``, ``blur``, ``flicker``, ``match_colour``, ``camera``, with the meaning and default of
            :class:`~darksynth.recipe.ClipRecipe`'s fields, but ``jitter`` :data:`~darksynth.recipe.AUGMENTING`
            (this makes training data). ``camera`` draws each clip's camera from real ones (``"prior"`` or a
            preset): given the profile's measured level, JPEG and finer octaves when it has them, whole otherwise.

    Returns:
        The low-light result in the input's layout and dtype, with the parameters used.

    Raises:
        DarksynthError: ``camera`` names no camera.
        TypeError: a keyword that is no choice of the recipe.
    """
    recipe = augmenting_recipe(profile, choices)
    if isinstance(clean, np.ndarray):
        clips, layout = clips_from_numpy(clean)
    else:
        clips, layout = (clean.unsqueeze(0), "image") if clean.dim() == 3 else (clean, "clips")
    if clips.dim() < CLIP_DIMS:
        raise ValueError(f"expected (C, H, W) or (..., T, C, H, W), got shape {tuple(clean.shape)}")
    target = torch.device(device) if device is not None else clips.device
    clips = clips.to(target)
    batch_shape = tuple(clips.shape[: clips.dim() - CLIP_DIMS])
    flat = clips.reshape(-1, *clips.shape[-CLIP_DIMS:])
    outputs = []
    records = []
    for clip in flat:
        chosen = parameters if parameters is not None else recipe.choose(generator, clip[0])
        records.append(chosen.to_json())
        if clip.dtype == torch.uint8:
            synthesizer = ClipSynthesizer(chosen, generator=generator, device=target)
            if clip.shape[0] == 1:
                outputs.append(synthesizer.image(clip[0])[None])
            else:
                frames = [low for frame in clip for low in synthesizer.push(frame)] + synthesizer.finish()
                outputs.append(torch.stack(frames))
        else:
            outputs.append(_synthesize_clip(clip, chosen, generator))
    result = torch.stack(outputs).reshape(clips.shape)
    record: dict[str, Any] | list[dict[str, Any]] = records[0] if not batch_shape else records
    if isinstance(clean, np.ndarray):
        return LowLightResult(image=clips_to_numpy(result, layout), parameters=record)
    return LowLightResult(image=result[0] if layout == "image" else result, parameters=record)


def _synthesize_clip(clip: torch.Tensor, parameters: ClipParameters, generator: torch.Generator | None) -> torch.Tensor:
    values = parameters.noise
    if parameters.colour_scale is not None:
        clip = _colour_cast(clip, parameters.colour_scale)
    if clip.shape[0] == 1 and clip.dtype.is_floating_point and values.is_neutral(noise_parameter("shake_length")):
        # A float image of 8-bit levels (``ToTensor`` of a PNG or JPEG, as training loops pass them) has the
        # 8-bit path's tables: the composer's draws in the composer's order, so the same result.
        synthesizer = ClipSynthesizer(parameters, generator=generator, device=clip.device)
        on_levels = synthesizer.float_image_on_levels(clip[0])
        if on_levels is not None:
            return on_levels[None]
    clean = scene_stage(unit_float(clip), values, generator=generator)
    darkening = parameters.darkening
    signal = clean if darkening is None else darken(clean, darkening.alpha, darkening.gamma)
    gains = exposure_gains(signal, values, generator=generator)
    if gains is not None:
        signal = signal * gains
    noisy = finish_clip(clean, add_noise(signal, values, generator=generator), values, generator=generator)
    return to_dtype(noisy, clip.dtype)


def _colour_cast(clip: torch.Tensor, colour_scale: tuple[float, ...]) -> torch.Tensor:
    """The clip (T, C, H, W) with the reference's colour cast, as :class:`ClipSynthesizer` gives each 8-bit frame:
    a float clip of 8-bit levels stays on levels (rounded, clipped), so it keeps the 8-bit route's result."""
    scaled = torch.stack([scale_channels(frame, colour_scale) for frame in clip])
    on_levels = clip.dtype.is_floating_point and eight_bit_levels(clip) is not None
    return to_8bit_levels(scaled).to(clip.dtype) if on_levels else scaled


__all__ = [
    "ClipSynthesizer",
    "LowLightResult",
    "synthesize",
]
