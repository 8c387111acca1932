"""How a noise component is declared: the records of the component table and their vocabulary.

The table itself is :data:`darksynth.noise.components.NOISE_COMPONENTS`; the components are declared by noise
model in :mod:`~darksynth.noise.paper_components`, :mod:`~darksynth.noise.heteroscedastic_components`,
:mod:`~darksynth.noise.spectral_components` and :mod:`~darksynth.noise.compression`.

All values are on the [0, 1] intensity scale of the image.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import torch

Structure = Literal["pixel", "column", "output", "scene", "exposure"]
"""How a component varies in the frame.

``pixel``: a new value at every pixel of every frame. ``column``: one value per channel and column, the same
down the whole column, so the component can be drawn as a (..., T or 1, C, 1, W) row and broadcast.
``output``: not added but applied to the finished noisy image (after summing and clipping), like a camera's
compression; its ``draw`` returns the transformed image instead of noise.

Two structures are light, not noise (:mod:`darksynth.noise.light_components`): ``scene`` transforms the clean clip
before it is darkened (motion blur, camera shake; its ``draw`` returns the transformed clean clip), ``exposure``
multiplies the darkened signal frame by frame (flicker; its ``draw`` returns gains shaped (*batch, T, 1, 1, 1)).
"""

LIGHT_STRUCTURES: frozenset[str] = frozenset({"scene", "exposure"})
"""The structures of light: in the profile's ``light`` section, outside the estimation network's v."""

NoiseModel = Literal["paper", "srgb", "spectral"]
"""``paper``: the paper's five components (profile version 1, DEN model version 1). ``srgb``: those plus the
structure of real sRGB noise (per-channel gains, spatial and cross-channel correlation, JPEG; profile versions 2
and 3): the vocabulary of the estimation network's vector, drawn as the spectral model
(:mod:`darksynth.noise.structure_translation`). ``spectral``: those plus the measured spectrum (per-octave colour
covariances, level curves, temporal correlation; docs/spectral-noise.md, profile version 4), estimated by
measurement on the reference rather than by the network."""

StatisticsName = Literal["paper", "multiscale"]
"""The statistics vectors the estimation network reads (:data:`darksynth.models.statistics.STATISTICS`): the
paper's level-binned pixel noise and column patterns, and the sRGB model's multi-scale, per-channel and JPEG
statistics."""

Role = Literal["amplitude", "shape"]
"""``amplitude``: the component draws nothing when all its amplitude parameters are neutral. ``shape``: shapes
what the amplitudes draw (a correlation length, a channel gain) and draws nothing by itself."""

FastPath = Literal["fused_8bit", "spectral_8bit"]
"""A specialised implementation of part of f(v). ``fused_8bit``: :mod:`darksynth.noise.fused_8bit`, one pass over
an 8-bit frame that draws white heteroscedastic and quantization noise and adds the column components: the path of
the paper's model. ``spectral_8bit``: :mod:`darksynth.noise.spectral_8bit`, the spectral model's unit noise scaled by
the level curve's std read from a table of the 256 input levels, then the composer's quantization, column components
and compression: the default path of a profile from ``estimate``, and of a translated sRGB structure."""

FUSED_PATHS: frozenset[FastPath] = frozenset({"fused_8bit"})
"""The white 8-bit kernel: the white Gaussian pixel components (by their ``white_variance`` laws), quantization,
which it draws itself, and the column components, which the composer draws and it adds."""

SPECTRAL_PATHS: frozenset[FastPath] = frozenset({"spectral_8bit"})
"""The spectrum and the level curve: the spectral path only."""

ALL_8BIT_PATHS: frozenset[FastPath] = FUSED_PATHS | SPECTRAL_PATHS
"""Quantization, the column components and the white Gaussian components (by their laws), which every 8-bit path
draws as the composer does."""

ALL_PATHS: frozenset[FastPath] = ALL_8BIT_PATHS
"""Every fast path: what a parameter that none of them needs to draw declares (light, which runs outside them)."""

COMPRESSION_PATHS: frozenset[FastPath] = SPECTRAL_PATHS
"""The compression stage, which the spectral path runs after its per-pixel pass."""

DrawFunction = Callable[[torch.Tensor, Mapping[str, torch.Tensor], torch.Generator | None], torch.Tensor]
"""``draw(signal, values, generator) -> noise``: ``signal`` is the darkened clean clip (..., T, C, H, W),
``values`` maps each of the component's parameter names to a tensor shaped (*batch, size), where *batch are
the clip's leading dimensions. The noise broadcasts against ``signal``."""

StreamDrawFunction = Callable[
    [torch.Tensor, Mapping[str, torch.Tensor], torch.Generator | None, dict[str, Any]], torch.Tensor
]
"""``draw_in_stream(signal, values, generator, held) -> noise`` for a component whose frames depend on the frames
before them (temporal correlation): ``held`` is the stream's dict of per-clip objects, the same for every frame
of a clip, where the component keeps its state."""

VarianceFunction = Callable[[Mapping[str, torch.Tensor], torch.Tensor], torch.Tensor]
"""``variance(values, channel_means) -> (B, C)``: the component's contribution to the mean noise variance of
clips whose channels have the mean levels ``channel_means`` (B, C), with ``values`` shaped (B, size)."""


class SceneStream(Protocol):
    """What a frame-by-frame stream runs for a ``scene`` component (:class:`darksynth.light.shutter.ShutterStage`):
    a clip's clean frames in, the transformed frames out as they are done, and a single image."""

    def push(self, frame: torch.Tensor) -> list[torch.Tensor]: ...

    def finish(self) -> list[torch.Tensor]: ...

    def image(self, frame: torch.Tensor) -> torch.Tensor: ...


class ExposureStream(Protocol):
    """What a frame-by-frame stream runs for an ``exposure`` component (:class:`darksynth.light.flicker.FlickerGains`):
    each frame's gain on the darkening, drawn from the stream's generator."""

    @property
    def active(self) -> bool: ...

    def next(self, generator: torch.Generator | None) -> float: ...


AfterFrameFunction = Callable[[torch.Tensor, torch.Tensor, Any, torch.Generator | None, dict[str, Any]], torch.Tensor]
"""``after_frame(clean, finished, values, generator, held) -> finished`` for an output stage that acts across a
clip's frames (a codec's repeats of still cells): the finished frame (C, H, W) of a clip, given its clean input on
the [0, 1] scale, the clip's :class:`~darksynth.noise.values.NoiseValues` and the stream's ``held`` state, where it
keeps the previous frame."""

StreamStageFunction = Callable[[Any, torch.device], Any]
"""``stream_stage(values, device) -> stage`` for a light component: the :class:`SceneStream` (structure ``scene``)
or :class:`ExposureStream` (structure ``exposure``) a frame-by-frame stream runs for it, built from the clip's
:class:`~darksynth.noise.values.NoiseValues`."""

WhiteVarianceFunction = Callable[[Mapping[str, torch.Tensor], torch.Tensor], torch.Tensor]
"""``white_variance(values, signal) -> variance``: for a component that draws independent zero-mean Gaussian noise
at every pixel, its variance at each value of the darkened ``signal`` (*batch, T, C, H, W), shaped like it, with
``values`` shaped (*batch, size)."""


@dataclass(frozen=True)
class Parameter:
    """One named entry of the noise parameter vector v.

    Attributes:
        name: key in the profile's ``noise`` object.
        size: number of values (1 is a JSON number, more is a JSON list of that length).
        unit: what the value measures, for documentation and error messages.
        maximum: largest valid value; every value must lie in [0, maximum].
        training_range: the range drawn from when training the estimator or jittering without a profile range.
        minimum: smallest valid value.
        neutral: the value that changes nothing (0 for most, 1 for a gain): what a profile of an older version
            or a model without the parameter means.
        noise_model: the first noise model that has the parameter (see :data:`NoiseModel`).
        since_version: the profile version the parameter arrived in. Parameters of version 1 are required in
            every profile; later ones are optional (neutral when absent) and refused in older documents.
        role: see :data:`Role`.
        training_off_probability: when set, training sets this parameter alone to its neutral value with this
            probability (shape parameters, so the estimator also sees white, uncompressed noise).
        log_floor: for a noise level spanning decades: with a log level prior, training draws it log-uniformly
            over [log_floor, training high] and the estimator predicts its logarithm (values below the floor
            read as the floor), so a level of 0.005 is estimated as precisely, relatively, as one of 0.05.
            This is also the scale of the estimator's output head for the parameter.
        statistics: the name of the fixed statistics that reveal the parameter to the estimator; the network of a
            noise model reads those of all its parameters (:func:`darksynth.models.statistics.model_statistics`,
            beside the network, which is their only reader). None for a parameter no network predicts (the
            spectral model's, measured on the reference).
        fast_paths: the fast paths that draw this parameter at any value; every other fast path is taken only
            while the parameter is neutral (:meth:`darksynth.noise.values.NoiseValues.covered_by`).
    """

    name: str
    size: int
    unit: str
    maximum: float
    training_range: tuple[float, float]
    minimum: float = 0.0
    neutral: float = 0.0
    noise_model: NoiseModel = "paper"
    since_version: int = 1
    role: Role = "amplitude"
    training_off_probability: float | None = None
    log_floor: float | None = None
    statistics: StatisticsName | None = "paper"
    fast_paths: frozenset[FastPath] = frozenset()


@dataclass(frozen=True)
class NoiseComponent:
    """One term of f(v) with the parameters it reads, the function that draws it and its variance."""

    name: str
    parameters: tuple[Parameter, ...]
    structure: Structure
    draw: DrawFunction
    reference: str
    variance: VarianceFunction | None
    """Its term of the mean noise variance (:func:`darksynth.noise.level.mean_noise_variance`); None for an
    output stage, which transforms the image instead of adding to it."""
    per_clip: bool = False
    """True when one draw is held over all frames of a clip: a frame-by-frame stream draws it once."""
    draw_in_stream: StreamDrawFunction | None = None
    """How a frame-by-frame stream draws it, for a component with memory from frame to frame; None: ``draw``."""
    after_frame: AfterFrameFunction | None = None
    """How an output stage that acts across frames runs: after each finished frame, in streams and, frame after
    frame, on whole clips (:func:`darksynth.noise.simulate.finish_frame`); None: ``draw`` alone."""
    stream_stage: StreamStageFunction | None = None
    """How a frame-by-frame stream runs a light component (``draw`` is its whole-clip form); None for noise."""
    white_variance: WhiteVarianceFunction | None = None
    """The law of a white Gaussian pixel component, the one every route draws it by: ``draw`` (the composer), the
    fused 8-bit kernel (its std table is the square root of the active components' laws summed at the 256 darkened
    levels, :func:`darksynth.noise.simulate.white_pixel_std`) and the spectral paths (a std table per component,
    its normals drawn in table order). A component with a law whose parameters declare :data:`ALL_8BIT_PATHS` is
    fast on 8-bit input with its module and its line in the table. None: the component is not white Gaussian noise
    (or only with its shape parameters neutral, which the law then assumes)."""


def shapes_neutral(parameters: tuple[Parameter, ...], values: Mapping[str, torch.Tensor]) -> bool:
    """Whether none of ``parameters``' shape parameters is set: what they shape is the paper's white noise."""
    return all(bool((values[p.name] == p.neutral).all()) for p in parameters if p.role == "shape")
