"""The one composer of the noise model: f(v) as the sum of its components, added to the darkened signal.

Everything that makes noise goes through :func:`add_noise`: the batch API on whole clips, the streaming
synthesizer frame by frame (it passes ``held`` so that per-clip components are drawn once), training and the
evaluation methods. The fused 8-bit kernel is a declared fast path for a subset of the table
(:attr:`~darksynth.noise.components.Parameter.fast_paths`): it takes the column components from
:func:`column_noise` here and replaces only the per-pixel sum, the clipping and the rounding.

Drawing order, the same for a clip and for a stream: the column components in table order, then the per-pixel
ones in table order, then the output stages on the clipped image.

Light, which is not noise, has its place around them (:mod:`darksynth.noise.light_components`): the ``scene``
components transform the clean clip before it is darkened (:func:`scene_stage`), and the ``exposure`` ones give
the gain per frame the darkened signal is multiplied by (:func:`exposure_gains`) before :func:`add_noise`.
"""

from __future__ import annotations

from typing import Any

import torch

from darksynth.noise.component_types import ExposureStream, SceneStream
from darksynth.noise.components import NoiseComponent, noise_components
from darksynth.noise.values import NoiseValues


def active_components(values: NoiseValues, structure: str) -> tuple[NoiseComponent, ...]:
    """The components of ``structure`` that draw anything for ``values``, in table order."""
    return tuple(c for c in noise_components() if c.structure == structure and values.is_active(c))


def column_noise(
    shape: torch.Size | tuple[int, ...],
    values: NoiseValues,
    *,
    generator: torch.Generator | None,
    held: dict[str, Any] | None = None,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """The sum of the active column components for clips of ``shape`` (*batch, T, C, H, W).

    Args:
        shape: the clips' shape; only the shape is needed, the column components do not read the signal.
        values: the noise values, on ``device``.
        generator: source of randomness.
        held: per-clip patterns (temporal banding) by component name, filled at the first call and reused:
            a stream passes the same dict for every frame of a clip.
        device: where to draw.

    Returns:
        A row pattern (*batch, T or 1, C, 1, W) on the [0, 1] scale, zeros when no column component is active.
    """
    # The components read only the shape and device of the signal: a zero-stride view has both and costs no
    # frame-sized allocation.
    probe = torch.empty((), device=device).expand(shape)
    total = torch.zeros((*shape[:-2], 1, shape[-1]), device=device)
    for component in active_components(values, "column"):
        if component.per_clip and held is not None:
            if component.name not in held:
                held[component.name] = component.draw(probe, values, generator)
            pattern = held[component.name]
            if pattern.shape[-3] != shape[-3] or pattern.shape[-1] != shape[-1]:
                raise ValueError(f"frame size changed within a clip: {tuple(shape)}")
        else:
            pattern = component.draw(probe, values, generator)
        total = total + pattern
    return total


def pixel_noise(
    signal: torch.Tensor,
    values: NoiseValues,
    *,
    generator: torch.Generator | None,
    held: dict[str, Any] | None = None,
) -> torch.Tensor:
    """The sum of the active per-pixel components for a darkened clip (*batch, T, C, H, W); ``held`` as for
    :func:`column_noise`, where components with memory from frame to frame keep their state."""
    total = torch.zeros_like(signal)
    for component in active_components(values, "pixel"):
        if held is not None and component.draw_in_stream is not None:
            total = total + component.draw_in_stream(signal, values, generator, held)
        else:
            total = total + component.draw(signal, values, generator)
    return total


def white_pixel_std(signal: torch.Tensor, values: NoiseValues) -> torch.Tensor:
    """The std at each value of the darkened ``signal`` of the active white Gaussian pixel components together: the
    square root of the sum of their ``white_variance`` laws (the std table of the fused 8-bit kernel)."""
    variance = torch.zeros_like(signal)
    for component in active_components(values, "pixel"):
        if component.white_variance is not None:
            variance = variance + component.white_variance(values, signal)
    return variance.sqrt()


def apply_output_stages(
    noisy: torch.Tensor, values: NoiseValues, *, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Run the active output stages (compression) on a clipped noisy clip (*batch, T, C, H, W) in [0, 1]."""
    for stage in active_components(values, "output"):
        noisy = stage.draw(noisy, values, generator)
    return noisy


def scene_stage(clean: torch.Tensor, values: NoiseValues, *, generator: torch.Generator | None) -> torch.Tensor:
    """The clean clips (*batch, T, C, H, W) as the shutter saw them: the active ``scene`` components (motion blur
    along the flow for clips, camera shake for single frames), before darkening. Unchanged when none is active."""
    for component in active_components(values, "scene"):
        clean = component.draw(clean, values, generator)
    return clean


def exposure_gains(
    clean: torch.Tensor, values: NoiseValues, *, generator: torch.Generator | None
) -> torch.Tensor | None:
    """The per-frame gains (*batch, T, 1, 1, 1) of the active ``exposure`` components (flicker) on the darkened
    clips, None when none is active."""
    gains = None
    for component in active_components(values, "exposure"):
        drawn = component.draw(clean, values, generator)
        gains = drawn if gains is None else gains * drawn
    return gains


def frames_finished_across(values: NoiseValues) -> bool:
    """Whether an active output stage acts across a clip's frames (``after_frame``: a codec's repeats)."""
    return any(c.after_frame is not None for c in active_components(values, "output"))


def finish_frame(
    clean: torch.Tensor,
    finished: torch.Tensor,
    values: NoiseValues,
    *,
    generator: torch.Generator | None,
    held: dict[str, Any],
) -> torch.Tensor:
    """A clip's finished frame (C, H, W) through the active output stages that act across frames, in table order:
    ``clean`` is its input on the [0, 1] scale, ``held`` the stream's state (the previous frame)."""
    for component in active_components(values, "output"):
        if component.after_frame is not None:
            finished = component.after_frame(clean, finished, values, generator, held)
    return finished


def finish_clip(
    clean: torch.Tensor, noisy: torch.Tensor, values: NoiseValues, *, generator: torch.Generator | None
) -> torch.Tensor:
    """A whole clip's finished frames (T, C, H, W) through :func:`finish_frame`, frame after frame as a stream runs
    them; ``clean`` (T, C, H, W) on the [0, 1] scale. Unchanged when no such stage is active or the clip is one
    frame."""
    if noisy.shape[0] < 2 or not frames_finished_across(values):
        return noisy
    held: dict[str, Any] = {}
    frames = [finish_frame(c, f, values, generator=generator, held=held) for c, f in zip(clean, noisy, strict=True)]
    return torch.stack(frames)


class LightStream:
    """The light components of a frame-by-frame stream, each run by the stage its table record builds
    (``stream_stage``), in table order: the ``scene`` stages chained (a frame goes through each in turn), the
    ``exposure`` stages' gains multiplied. A stage is built for every light component, active or not (an inactive
    one passes frames through or gives no gain), so a stream draws exactly what :func:`scene_stage` and
    :func:`exposure_gains` draw for a whole clip."""

    def __init__(self, values: NoiseValues, device: torch.device) -> None:
        self.scene: list[SceneStream] = []
        self.exposure: list[ExposureStream] = []
        for component in noise_components():
            if component.stream_stage is None:
                continue
            stage = component.stream_stage(values, device)
            if component.structure == "scene":
                self.scene.append(stage)
            elif component.structure == "exposure":
                self.exposure.append(stage)

    @property
    def flickers(self) -> bool:
        """Whether a frame's darkening changes from frame to frame (an active ``exposure`` stage)."""
        return any(stage.active for stage in self.exposure)

    def push(self, frame: torch.Tensor) -> list[torch.Tensor]:
        """A clip's next clean frame in, the frames every scene stage is done with out."""
        frames = [frame]
        for stage in self.scene:
            frames = [done for held in frames for done in stage.push(held)]
        return frames

    def finish(self) -> list[torch.Tensor]:
        """The frames the scene stages still hold at the end of the clip."""
        frames: list[torch.Tensor] = []
        for stage in self.scene:
            frames = [done for held in frames for done in stage.push(held)] + stage.finish()
        return frames

    def image(self, frame: torch.Tensor) -> torch.Tensor:
        """A single image through every scene stage."""
        for stage in self.scene:
            frame = stage.image(frame)
        return frame

    def gain(self, generator: torch.Generator | None) -> float:
        """The next frame's gain on the darkening: the active exposure stages' product."""
        gain = 1.0
        for stage in self.exposure:
            if stage.active:
                gain *= stage.next(generator)
        return gain


def noise_sum(signal: torch.Tensor, values: NoiseValues, *, generator: torch.Generator | None) -> torch.Tensor:
    """f(v) before clipping: the column and per-pixel components for a darkened clip (*batch, T, C, H, W)."""
    values = values.to(signal.device, signal.dtype)
    columns = column_noise(signal.shape, values, generator=generator, device=signal.device)
    return columns + pixel_noise(signal, values, generator=generator)


def add_noise(
    signal: torch.Tensor,
    values: NoiseValues,
    *,
    generator: torch.Generator | None,
    held: dict[str, Any] | None = None,
) -> torch.Tensor:
    """The noisy low-light clip: signal + f(v), clipped to [0, 1], then the output stages (compression).

    Args:
        signal: darkened clean clips (*batch, T, C, H, W), values in [0, 1].
        values: the noise values, unbatched or with the clips' batch shape.
        generator: source of randomness; pass a seeded one for reproducible output.
        held: see :func:`column_noise` (streams only).

    Returns:
        The noisy clips, shaped like ``signal``.
    """
    values = values.to(signal.device, signal.dtype)
    columns = column_noise(signal.shape, values, generator=generator, held=held, device=signal.device)
    noisy = (signal + columns + pixel_noise(signal, values, generator=generator, held=held)).clamp(0.0, 1.0)
    return apply_output_stages(noisy, values, generator=generator)
