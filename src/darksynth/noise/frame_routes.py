"""The routes one frame of a clip takes through f(v): the general composer, and the fast 8-bit paths declared in the
table (:attr:`~darksynth.noise.components.Parameter.fast_paths`), each drawing what the composer draws.

A route is chosen once per clip, by the first row of :data:`ROUTES` whose test the values pass; the synthesizer
(:class:`darksynth.synthesize.ClipSynthesizer`) calls it frame by frame and tells it when the frame's darkening
changes (flicker). Every route keeps the clip's state in the same ``held`` dict (temporal banding, the spectrum's
frame-to-frame state), so a stream that leaves a fast route (a frame of another size) goes on through the composer.

* :class:`ComposerRoute`: :func:`darksynth.noise.simulate.add_noise` on the darkened frame, any dtype;
* :class:`FusedRoute`: the paper's white model on 8-bit frames, one fused kernel (:mod:`darksynth.noise.fused_8bit`);
* :class:`SpectralRoute`: the spectral model on 8-bit frames, level and std read from tables of the 256 levels
  (:mod:`darksynth.noise.spectral_8bit`);
* :class:`CompiledSpectralRoute`: the same law through compiled kernels with counter-based draws
  (:mod:`darksynth.noise.spectral_kernel`), for long streams; the eager spectral route where compiling fails.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import torch

from darksynth.light.darkening import Darkening, darken
from darksynth.noise.components import NoiseComponent, noise_parameter
from darksynth.noise.counter_rng import random_key
from darksynth.noise.fused_8bit import (
    FAST_PATH,
    FULL_SCALE,
    PixelKernel,
    compiled_pixel_kernel,
    draws,
    kernel_tables,
    pixel_kernel_8bit,
    pixel_kernel_in_pieces,
)
from darksynth.noise.paper_components import QUANTIZATION
from darksynth.noise.simulate import (
    active_components,
    add_noise,
    apply_output_stages,
    column_noise,
)
from darksynth.noise.spectral import clip_grid, octave_covariances
from darksynth.noise.spectral_8bit import (
    DRAW_QUANTIZATION,
    DRAW_SPECTRUM,
    SPECTRAL_PATH,
    DrawOrder,
    SpectralPixelPass,
    to_8bit,
)
from darksynth.noise.spectral_components import SPECTRAL
from darksynth.noise.spectral_kernel import SpectralKernelStream, compiled_spectral_kernels
from darksynth.noise.values import NoiseValues, covered_by, uncovered_by
from darksynth.tensors import to_dtype, unit_float

logger = logging.getLogger(__name__)


@dataclass
class ClipState:
    """What every route of one clip reads: its values (float32 on ``device``, as the composer reads them), where
    the work runs, the clip's held state and its generator."""

    values: NoiseValues
    device: torch.device
    generator: torch.Generator | None
    held: dict[str, Any] = field(default_factory=dict)

    def columns(self, shape: torch.Size) -> torch.Tensor:
        """The column components of a frame (C, H, W) on the [0, 1] scale (the composer's draws)."""
        columns = column_noise((1, *shape), self.values, generator=self.generator, held=self.held, device=self.device)
        return columns[0]


class FrameRoute(Protocol):
    """One route: a frame (C, H, W) in, its noisy version in the same dtype out, at the current darkening;
    ``name`` says which route draws the frames now."""

    @property
    def name(self) -> str: ...

    def __call__(self, frame: torch.Tensor) -> torch.Tensor: ...

    def set_darkening(self, darkening: Darkening | None) -> None: ...


class ComposerRoute:
    """The general composer on one frame (any dtype): darkened, f(v) added as for a clip of one frame."""

    name = "composer"

    def __init__(self, state: ClipState, darkening: Darkening | None) -> None:
        self.state, self.darkening = state, darkening

    def set_darkening(self, darkening: Darkening | None) -> None:
        self.darkening = darkening

    def __call__(self, frame: torch.Tensor) -> torch.Tensor:
        clean, darkening = unit_float(frame), self.darkening
        signal = clean if darkening is None else darken(clean, darkening.alpha, darkening.gamma)
        state = self.state
        noisy = add_noise(signal[None], state.values, generator=state.generator, held=state.held)[0]
        return to_dtype(noisy, frame.dtype)


class FusedRoute:
    """The paper's white model on an 8-bit frame: the white Gaussian components (by their laws) and quantization
    noise drawn in one fused kernel (compiled with ``compile``), the column components from the composer."""

    name = "fused"

    def __init__(self, state: ClipState, darkening: Darkening | None, *, compile: bool) -> None:
        self.state, self.darkening = state, darkening
        self._kernel: PixelKernel = compiled_pixel_kernel() if compile else pixel_kernel_8bit
        self._tables: tuple[torch.Tensor, ...] | None = None

    def set_darkening(self, darkening: Darkening | None) -> None:
        self.darkening, self._tables = darkening, None

    def __call__(self, frame: torch.Tensor) -> torch.Tensor:
        columns_8bit = self.state.columns(frame.shape) * FULL_SCALE
        if self._tables is None:
            self._tables = kernel_tables(self.darkening, self.state.values, device=self.state.device)
        key = random_key(self.state.generator).to(self.state.device)
        if self._kernel is not pixel_kernel_8bit:
            try:
                return self._kernel(frame, key, *self._tables, columns_8bit)
            except Exception as error:
                # torch.compile fails in many ways on a platform without a working compiler; the eager kernel
                # gives the same bits, only slower.
                logger.warning("compiled 8-bit kernel failed (%s); using the eager kernel", error)
                self._kernel = pixel_kernel_8bit
        return pixel_kernel_in_pieces(self._kernel, frame, key, self._tables, columns_8bit)


class SpectralRoute:
    """The spectral model on an 8-bit frame: the composer's draws in the composer's order (columns, the per-pixel
    components in table order: the white Gaussian ones by their laws, the spectral unit noise, quantization; then
    the output stages), the level and the stds read from 8-bit tables."""

    name = "spectral"

    def __init__(self, state: ClipState, darkening: Darkening | None) -> None:
        self.state, self.darkening = state, darkening
        self._pass: SpectralPixelPass | None = None

    def set_darkening(self, darkening: Darkening | None) -> None:
        self.darkening = darkening
        if self._pass is not None:
            self._pass.set_darkening(darkening, self.state.values["level_curve"])

    def __call__(self, frame: torch.Tensor) -> torch.Tensor:
        return self.noisy(frame, rounded=True)

    def noisy(self, frame: torch.Tensor, *, rounded: bool) -> torch.Tensor:
        """The frame's noisy version; not ``rounded``: the float32 result in [0, 1] before the rounding to 8 bits
        (a float image of 8-bit levels, as ``ToTensor`` gives it)."""
        state, values = self.state, self.state.values
        columns = state.columns(frame.shape) if active_components(values, "column") else None
        if self._pass is None:
            channels, height, width = frame.shape
            white, order = _spectral_draws(values)
            self._pass = SpectralPixelPass(
                channels,
                height,
                width,
                self.darkening,
                values["level_curve"],
                values.scalar("quantization"),
                device=state.device,
                texture=_texture(values),
                white=white,
                values=values,
                order=order,
            )
        grid = clip_grid(
            octave_covariances(values["octave_power"], values["octave_correlation"]),
            values["temporal_correlation"],
            frame.shape,
            device=state.device,
            dtype=torch.float32,
            state=state.held,
        )
        generator = state.generator if state.generator is not None else torch.default_generator
        compressed = not values.is_neutral(noise_parameter("compression"))
        # The per-pixel draws in the composer's order: the spectrum's unit noise, the quantization bytes, the white
        # components' normals.
        unit = None
        for item in self._pass.order:
            if item == DRAW_SPECTRUM:
                unit = grid.frame(generator)
            else:
                self._pass.draw(item, generator)
        assert unit is not None
        noisy = self._pass.noisy(frame, unit, columns, rounded=rounded and not compressed)
        if compressed:
            noisy = apply_output_stages(noisy[None], values, generator=state.generator)[0]
            return to_8bit(noisy) if rounded else noisy
        # Not rounded, the result is the pass's own array, which the next frame overwrites.
        return noisy if rounded else noisy.clone()


class CompiledSpectralRoute:
    """The spectral model's law through compiled kernels (counter-based draws), the texture factor and the white
    Gaussian components included. Where compiling fails, the stream goes on through :class:`SpectralRoute`."""

    def __init__(self, state: ClipState, darkening: Darkening | None) -> None:
        self.state, self.darkening = state, darkening
        self._stream: SpectralKernelStream | None = None
        self._eager: SpectralRoute | None = None

    @property
    def name(self) -> str:
        return "compiled spectral" if self._eager is None else SpectralRoute.name

    def set_darkening(self, darkening: Darkening | None) -> None:
        self.darkening = darkening
        if self._stream is not None:
            self._stream.set_darkening(darkening)
        if self._eager is not None:
            self._eager.set_darkening(darkening)

    def __call__(self, frame: torch.Tensor) -> torch.Tensor:
        if self._eager is not None:
            return self._eager(frame)
        state, values = self.state, self.state.values
        columns = state.columns(frame.shape) * FULL_SCALE if active_components(values, "column") else None
        try:
            if self._stream is None:
                white = bool(_spectral_draws(values)[0])
                mix, ar_mix, pixel = compiled_spectral_kernels(white)
                self._stream = SpectralKernelStream(
                    (frame.shape[0], frame.shape[1], frame.shape[2]),
                    octave_covariances(values["octave_power"], values["octave_correlation"]),
                    values["temporal_correlation"],
                    self.darkening,
                    values["level_curve"],
                    values.scalar("quantization"),
                    mix=mix,
                    ar_mix=ar_mix,
                    pixel=pixel,
                    device=state.device,
                    texture=_texture(values),
                    white=values if white else None,
                )
            out = self._stream(frame, state.generator, columns)
        except Exception as error:
            # A platform without a working compiler (as for the other kernels).
            logger.warning("compiled spectral kernels failed (%s); using the eager spectral path", error)
            self._eager = SpectralRoute(state, self.darkening)
            return self._eager(frame)
        if values.is_neutral(noise_parameter("compression")):
            return out
        compressed = apply_output_stages(out.to(torch.float32)[None] / FULL_SCALE, values, generator=state.generator)
        return to_dtype(compressed[0], frame.dtype)


def _pixel_draws(values: NoiseValues) -> tuple[list[NoiseComponent], DrawOrder] | None:
    """The active white Gaussian components, and the per-pixel draws of the spectral paths in the composer's
    (table) order; None when an active pixel component is neither the spectrum, quantization nor white with its law
    (the spectral paths cannot draw it)."""
    white: list[NoiseComponent] = []
    order: list[str | int] = []
    for component in active_components(values, "pixel"):
        if component is SPECTRAL:
            order.append(DRAW_SPECTRUM)
        elif component is QUANTIZATION:
            order.append(DRAW_QUANTIZATION)
        elif component.white_variance is not None:
            order.append(len(white))
            white.append(component)
        else:
            return None
    return white, tuple(order)


def _spectral_draws(values: NoiseValues) -> tuple[list[NoiseComponent], DrawOrder]:
    """:func:`_pixel_draws` of values a spectral route took (:func:`_spectral`)."""
    draws = _pixel_draws(values)
    assert draws is not None, "a spectral route was made for values it cannot draw"
    return draws


def _spectral(values: NoiseValues) -> bool:
    # A profile of the spectral model (its curve set) whose other values the spectral path draws; the paper's white
    # model never takes it, so its frames keep their bits.
    return (
        bool(uncovered_by(values, FAST_PATH))
        and values.is_active(SPECTRAL)
        and covered_by(values, SPECTRAL_PATH)
        and _pixel_draws(values) is not None
    )


def _texture(values: NoiseValues) -> tuple[float, float] | None:
    """(``texture_gain``, ``texture_scale``) of a profile whose noise follows texture, else None."""
    if values.is_neutral(noise_parameter("texture_gain")):
        return None
    return values.scalar("texture_gain"), values.scalar("texture_scale")


@dataclass(frozen=True)
class Route:
    """A row of :data:`ROUTES`: whether the route takes a clip's 8-bit frames (by the values and whether the
    stream is compiled) and how it is made."""

    takes: Callable[[NoiseValues, bool], bool]
    make: Callable[[ClipState, Darkening | None, bool], FrameRoute]


ROUTES: tuple[Route, ...] = (
    Route(lambda values, _: draws(values), lambda s, d, c: FusedRoute(s, d, compile=c)),
    Route(
        lambda values, compile: compile and _spectral(values),
        lambda s, d, _: CompiledSpectralRoute(s, d),
    ),
    Route(lambda values, _: _spectral(values), lambda s, d, _: SpectralRoute(s, d)),
    Route(lambda values, _: True, lambda s, d, _: ComposerRoute(s, d)),
)
"""The routes of a clip's 8-bit frames, fastest first (fused, compiled spectral, spectral, composer); the first
that takes the values is the clip's. Frames of another dtype always take the composer."""


def eight_bit_route(state: ClipState, darkening: Darkening | None, *, compile: bool) -> FrameRoute:
    """The route of a clip's 8-bit frames, by :data:`ROUTES`."""
    route = next(row for row in ROUTES if row.takes(state.values, compile)).make(state, darkening, compile)
    if isinstance(route, ComposerRoute):
        logger.debug("8-bit frames take the general composer: %s", uncovered_by(state.values, FAST_PATH))
    return route
