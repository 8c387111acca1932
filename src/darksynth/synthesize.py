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
from typing import Any

import numpy as np
import torch

from darksynth.io.arrays import clips_from_numpy, clips_to_numpy
from darksynth.light.darkening import Darkening, darken
from darksynth.light.flicker import FlickerGains
from darksynth.light.shutter import ShutterStage
from darksynth.noise.codec_repeat import repeat_in_clip, repeat_in_stream
from darksynth.noise.components import noise_component, noise_parameter
from darksynth.noise.counter_rng import random_key
from darksynth.noise.fused_8bit import (
    FAST_PATH,
    FULL_SCALE,
    PixelKernel,
    compiled_pixel_kernel,
    kernel_scalars,
    pixel_kernel_8bit,
    pixel_kernel_in_pieces,
)
from darksynth.noise.simulate import (
    add_noise,
    apply_output_stages,
    column_components_active,
    column_noise,
    exposure_gains,
    scene_stage,
)
from darksynth.noise.spectral import clip_grid, octave_covariances
from darksynth.noise.spectral_8bit import SPECTRAL_PATH, SpectralPixelPass, level_tables, to_8bit
from darksynth.noise.spectral_kernel import SpectralKernelStream, compiled_spectral_kernels
from darksynth.profile import Profile
from darksynth.recipe import AUGMENTING, ClipParameters, ClipRecipe, DarkeningChoice
from darksynth.tensors import CLIP_DIMS, eight_bit_levels, full_scale, scale_channels, to_dtype

logger = logging.getLogger(__name__)


class ClipSynthesizer:
    """Darkening + f(v) for the frames of one clip, one frame at a time (memory does not grow with length).

    Every frame goes through the composer (:func:`darksynth.noise.simulate.add_noise`), which holds the
    components a clip keeps fixed (temporal banding) from the first frame on. 8-bit frames whose values the
    fused kernel covers (:data:`darksynth.noise.fused_8bit.FAST_PATH` in the table) take it for the per-pixel part.
    8-bit frames of a spectral profile (:data:`darksynth.noise.spectral_8bit.SPECTRAL_PATH`) read their darkened
    level and noise std from tables of the 256 levels and draw the composer's bits.

    Args:
        parameters: the clip's parameters (see :func:`draw_clip_parameters`).
        generator: source of randomness, consumed frame after frame.
        device: where the work runs (``"cpu"``, ``"cuda"``); frames are moved there and results returned there.
        compile: fuse the 8-bit kernel with ``torch.compile``; worth it for a long stream of same-sized frames.
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
        self._values = parameters.noise.to(self.device, torch.float32)
        self._held: dict[str, Any] = {}
        self._kernel: PixelKernel = compiled_pixel_kernel() if compile else pixel_kernel_8bit
        uncovered = self._values.uncovered_by(FAST_PATH)
        self._fusable = not uncovered
        # A profile of the spectral model (its curve set) whose other values the spectral path draws; the paper's
        # white model never takes it, so its frames keep their bits.
        self._spectral = (
            bool(uncovered)
            and self._values.is_active(noise_component("spectral"))
            and self._values.covered_by(SPECTRAL_PATH)
        )
        self._spectral_pass: SpectralPixelPass | None = None
        # Compiled, a spectral stream takes the fused kernels (the same law, counter-based draws); they do not draw
        # the texture factor, which the eager pass does.
        self._textured = not self._values.is_neutral(noise_parameter("texture_gain"))
        self._spectral_compiled = compile and self._spectral and not self._textured
        self._spectral_stream: SpectralKernelStream | None = None
        if uncovered and not self._spectral:
            logger.debug("8-bit frames take the general composer: %s not covered by %s", uncovered, FAST_PATH)
        self._scalars: tuple[torch.Tensor, ...] | None = None
        self._frame_shape: torch.Size | None = None
        self._frames_done = 0
        # Light (darksynth.light): the shutter (motion blur, shake), the frame's darkening times its flicker gain.
        self._darkening = parameters.darkening
        self._flicker = FlickerGains(self._values.scalar("flicker"), self._values.scalar("flicker_correlation"))
        fraction, length, angle = (self._values.scalar(n) for n in ("exposure_fraction", "shake_length", "shake_angle"))
        self._shutter = ShutterStage(fraction, length, angle, self.device)
        self._repeat_share = self._values.scalar("codec_repeat")

    def push(self, frame: torch.Tensor) -> list[torch.Tensor]:
        """The next frame (C, H, W) of a clip in, the low-light frames finished so far out, in order. With motion
        blur (``exposure_fraction`` > 0) a frame is finished when the next one arrives: call :meth:`finish` after
        the last frame (:class:`darksynth.light.shutter.ShutterStage`)."""
        return [self(clean) for clean in self._shutter.push(frame)]

    def finish(self) -> list[torch.Tensor]:
        """The clip's frames still held for their blur (none without motion blur)."""
        return [self(clean) for clean in self._shutter.finish()]

    def image(self, frame: torch.Tensor) -> torch.Tensor:
        """A single image (C, H, W): its camera shake, if any, and no flicker (it needs a sequence)."""
        return self._frame(self._shutter.image(frame), flicker=False)

    def _set_gain(self, gain: float) -> None:
        """This frame's darkening: the clip's times the flicker gain (the tables read from it are redone)."""
        base = self.parameters.darkening or Darkening(alpha=1.0, gamma=1.0)
        self._darkening = Darkening(alpha=base.alpha * gain, gamma=base.gamma)
        self._scalars = None
        curve = self._values["level_curve"]
        for stage in (stage for stage in (self._spectral_pass, self._spectral_stream) if stage is not None):
            channels = len(stage.signal_table)
            stage.signal_table, stage.std_table = level_tables(channels, self._darkening, curve, device=self.device)

    def __call__(self, frame: torch.Tensor) -> torch.Tensor:
        """Low-light version of one frame (C, H, W) of a clip whose light stage is done (as :meth:`push` gives
        it): uint8 in, uint8 out; uint16 and float likewise. Flicker, if any, is drawn here, and after the frame
        the codec's repeats of still cells from the previous one (:mod:`darksynth.noise.codec_repeat`)."""
        finished = self._frame(frame, flicker=True)
        if self._repeat_share <= 0.0:
            return finished
        frame = frame.to(self.device)
        scale = full_scale(frame.dtype)
        clean = frame.to(torch.float32) / scale if scale else frame.to(torch.float32)
        return repeat_in_stream(clean, finished, self._repeat_share, self.generator, self._held)

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
        if flicker and self._flicker.active:
            # The gain is drawn before the frame's noise, from the same generator.
            self._set_gain(self._flicker.next(self.generator))
        if frame.dtype == torch.uint8 and self._fusable:
            return self._fused(frame)
        if frame.dtype == torch.uint8 and self._spectral_compiled:
            compiled = self._spectral_kernels(frame)
            if compiled is not None:
                return compiled
        if frame.dtype == torch.uint8 and self._spectral:
            return self._spectral_8bit(frame)
        scale = full_scale(frame.dtype)
        clean = frame.to(torch.float32) / scale if scale else frame.to(torch.float32)
        darkening = self._darkening
        signal = clean if darkening is None else darken(clean, darkening.alpha, darkening.gamma)
        # A frame is a clip of one frame for the composer.
        noisy = add_noise(signal[None], self._values, generator=self.generator, held=self._held)[0]
        return to_dtype(noisy, frame.dtype)

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
        self._held.clear()
        self._fusable = self._spectral = self._spectral_compiled = False

    def _kernel_scalars(self) -> tuple[torch.Tensor, ...]:
        if self._scalars is None:
            darkening = self._darkening
            self._scalars = kernel_scalars(
                darkening.alpha if darkening else None,
                darkening.gamma if darkening else None,
                # The float64 values, as given: squaring before the cast to float32 keeps the kernel's bits.
                self.parameters.noise,
                device=self.device,
            )
        return self._scalars

    def _columns_8bit(self, frame: torch.Tensor) -> torch.Tensor:
        columns = column_noise(
            (1, *frame.shape), self._values, generator=self.generator, held=self._held, device=self.device
        )[0]
        return columns * FULL_SCALE

    def _fused(self, frame: torch.Tensor) -> torch.Tensor:
        columns_8bit = self._columns_8bit(frame)
        scalars = self._kernel_scalars()
        key = random_key(self.generator).to(self.device)
        if self._kernel is not pixel_kernel_8bit:
            try:
                return self._kernel(frame, key, *scalars, columns_8bit)
            except Exception as error:
                # torch.compile fails in many ways on a platform without a working compiler; the eager kernel
                # gives the same bits, only slower.
                logger.warning("compiled 8-bit kernel failed (%s); using the eager kernel", error)
                self._kernel = pixel_kernel_8bit
        return pixel_kernel_in_pieces(self._kernel, frame, key, scalars, columns_8bit)

    def _spectral_kernels(self, frame: torch.Tensor) -> torch.Tensor | None:
        """The uint8 frame through the compiled spectral kernels and the output stages; None once they have failed
        (the stream then goes on through the eager spectral path, which has the same law)."""
        values = self._values
        columns = self._columns_8bit(frame) if column_components_active(values) else None
        try:
            if self._spectral_stream is None:
                mix, ar_mix, pixel = compiled_spectral_kernels()
                self._spectral_stream = SpectralKernelStream(
                    (frame.shape[0], frame.shape[1], frame.shape[2]),
                    octave_covariances(values["octave_power"], values["octave_correlation"]),
                    values["temporal_correlation"],
                    self._darkening,
                    values["level_curve"],
                    values.scalar("quantization"),
                    mix=mix,
                    ar_mix=ar_mix,
                    pixel=pixel,
                    device=self.device,
                )
            out = self._spectral_stream(frame, self.generator, columns)
        except Exception as error:
            # A platform without a working compiler (as for the other kernels).
            logger.warning("compiled spectral kernels failed (%s); using the eager spectral path", error)
            self._spectral_compiled = False
            return None
        if values.is_neutral(noise_parameter("compression")):
            return out
        compressed = apply_output_stages(out.to(torch.float32)[None] / FULL_SCALE, values, generator=self.generator)
        return to_dtype(compressed[0], frame.dtype)

    def _spectral_8bit(self, frame: torch.Tensor, *, rounded: bool = True) -> torch.Tensor:
        """The uint8 frame through the spectral path: the composer's draws in the composer's order (columns, the
        spectral unit noise, quantization, the output stages), the level and std read from 8-bit tables. Not
        ``rounded``: the float32 result in [0, 1], before the rounding to 8 bits."""
        values = self._values
        columns = None
        if column_components_active(values):
            columns = column_noise(
                (1, *frame.shape), values, generator=self.generator, held=self._held, device=self.device
            )[0]
        if self._spectral_pass is None:
            channels, height, width = frame.shape
            self._spectral_pass = SpectralPixelPass(
                channels,
                height,
                width,
                self._darkening,
                values["level_curve"],
                values.scalar("quantization"),
                device=self.device,
                texture=(values.scalar("texture_gain"), values.scalar("texture_scale")) if self._textured else None,
            )
        grid = clip_grid(
            octave_covariances(values["octave_power"], values["octave_correlation"]),
            values["temporal_correlation"],
            frame.shape,
            device=self.device,
            dtype=torch.float32,
            state=self._held,
        )
        generator = self.generator if self.generator is not None else torch.default_generator
        compressed = not values.is_neutral(noise_parameter("compression"))
        noisy = self._spectral_pass.noisy(
            frame, grid.frame(generator), columns, generator, rounded=rounded and not compressed
        )
        if compressed:
            noisy = apply_output_stages(noisy[None], values, generator=self.generator)[0]
            return to_8bit(noisy) if rounded else noisy
        # Not rounded, the result is the pass's own array, which the next frame overwrites.
        return noisy if rounded else noisy.clone()


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
    darkening: DarkeningChoice = "profile",
    device: torch.device | str | None = None,
    parameters: ClipParameters | None = None,
    camera: str | None = None,
) -> LowLightResult:
    """Make a low-light version of a clean image or clip with a noise profile.

    Args:
        clean: a torch tensor (C, H, W) image or (*batch, T, C, H, W) clips, uint8, uint16 or float in [0, 1];
            or a numpy array (H, W) grey, (H, W, C) image or (T, H, W, C) clip. Parameters are drawn once per
            clip. 8-bit clips run frame by frame through the fused kernel, as the command line does; float clips
            run through the vectorised composer.
        profile: the noise profile (see :func:`darksynth.profile.load_profile`).
        generator: source of randomness; pass a seeded one for reproducible output.
        darkening: see :data:`darksynth.recipe.DarkeningChoice`.
        device: where to compute; the input's device by default.
        parameters: the parameters every clip takes, chosen before (a transform's replay); None chooses each clip's
            by the recipe of ``profile``, ``darkening`` and ``camera`` (:meth:`darksynth.recipe.ClipRecipe.choose`).
        camera: draw each clip's camera from real ones, one of :data:`darksynth.cameras.presets.CAMERA_CHOICES`
            (``"prior"`` or a preset): given the profile's measured level, JPEG and finer octaves when it has them,
            whole otherwise; None keeps the profile's noise. Each record then says where it came from.

    Returns:
        The low-light result in the input's layout and dtype, with the parameters used.

    Raises:
        DarksynthError: ``camera`` names no camera.
    """
    as_numpy = isinstance(clean, np.ndarray)
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
    recipe = ClipRecipe(profile, darkening=darkening, jitter=AUGMENTING, camera=camera)
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
    if as_numpy:
        return LowLightResult(image=clips_to_numpy(result, layout), parameters=record)
    return LowLightResult(image=result[0] if layout == "image" else result, parameters=record)


def _synthesize_clip(clip: torch.Tensor, parameters: ClipParameters, generator: torch.Generator | None) -> torch.Tensor:
    values = parameters.noise
    if clip.shape[0] == 1 and clip.dtype.is_floating_point and values.is_neutral(noise_parameter("shake_length")):
        # A float image of 8-bit levels (``ToTensor`` of a PNG or JPEG, as training loops pass them) has the
        # 8-bit path's tables: the composer's draws in the composer's order, so the same result.
        synthesizer = ClipSynthesizer(parameters, generator=generator, device=clip.device)
        levels = eight_bit_levels(clip[0]) if synthesizer._spectral else None
        if levels is not None:
            return to_dtype(synthesizer._spectral_8bit(levels, rounded=False)[None], clip.dtype)
    scale = full_scale(clip.dtype)
    clean = clip.to(torch.float32) / scale if scale else clip.to(torch.float32)
    clean = scene_stage(clean, values, generator=generator)
    darkening = parameters.darkening
    signal = clean if darkening is None else darken(clean, darkening.alpha, darkening.gamma)
    gains = exposure_gains(signal, values, generator=generator)
    if gains is not None:
        signal = signal * gains
    noisy = add_noise(signal, values, generator=generator)
    share = values.scalar("codec_repeat")
    if share > 0.0 and clip.shape[0] > 1:
        noisy = repeat_in_clip(clean, noisy, share, generator)
    return to_dtype(noisy, clip.dtype)


__all__ = [
    "ClipSynthesizer",
    "LowLightResult",
    "synthesize",
]
