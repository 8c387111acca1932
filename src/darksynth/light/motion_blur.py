"""Motion blur that follows the scene: each frame integrated over its exposure along the scene's own motion.

A camera exposes frame t over a window of ``s`` frame intervals centred on t (``s`` is the exposure fraction: 0 an
instant, 1 a shutter open for the whole interval, a 360-degree shutter). What moves by ``d`` pixels per frame is
smeared along its motion over ``s * |d|`` pixels. Here the motion is the dense optical flow between consecutive
clean frames (OpenCV's DIS flow, no network weights; one flow a pair, whose inverse gives the way back): a frame's
velocity is half its flow to the next frame minus its flow to the previous one, taken constant over the exposure,
and the integral over the window is the mean of the frame resampled at points spread evenly along each pixel's
path (:func:`blur_along`). The mean is taken in linear light (sRGB decoded, averaged, encoded again), as a sensor
sums photons; the result is a clean frame, darkened and noised after.

What it does not model: a pixel is resampled along its own flow (backward warping), so a moving object is smeared
within its own outline and its edge into the background behind it, but does not spill a trail over a still
background beyond its outline (that needs the flow of the object at the background's pixels, i.e. splatting).

Still parts stay untouched, byte for byte: a pixel whose blur length is under :data:`STILL_LENGTH` keeps its value,
and one between that and :data:`FULL_LENGTH` is blended, so flow jitter of a fraction of a pixel in a still scene
changes nothing. A scene cut, a change of frame size or a flow that does not hold between two frames
(:func:`flow_holds`: black frames, unrelated frames) stops the blur there: each side is blurred with its own motion
only.

Frames are numpy arrays (H, W, C), uint8, uint16 or float in [0, 1], as images and videos are read; the flow runs on
the CPU.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from darksynth.light.linear_light import (
    LEVEL_OF_LINEAR16,
    LINEAR16_OF_LEVEL,
    decode,
    encode,
    levels_of_linear16,
    unit_scale,
)

STILL_LENGTH = 0.5
"""Blur length (px) under which a pixel is left as it is: half a pixel of smear is below what resampling itself
blurs, and DIS flow in a still textured scene jitters by a few tenths of a pixel."""

FULL_LENGTH = 1.0
"""Blur length (px) from which a pixel takes the full integral (between the two: a linear blend)."""

SAMPLE_SPACING = 1.0
"""Largest distance (px) between two points of a path: points a pixel apart, each read bilinearly, sum to the
continuous box exactly (the triangles of the interpolation tile the line)."""

MAX_STEPS = 3
"""At most 3^3 = 27 points per path (6 resamplings), exact up to 26 px of blur, which covers handheld night video
(the shared phone clips move 2-21 px a frame). Longer paths get points further apart: at 50 px, 1.9 px, whose
ripple is a few percent of an edge's contrast, under the noise of a night frame. An 81-point path (8 resamplings)
cost a fifth more on 1080p, for blur longer than a sixth of a 1080p frame's height."""

MIN_FLOW_SIDE = 16
"""Flow images smaller than this on a side are not followed (DIS refuses under 12 px, and a frame that small has
no motion worth blurring): their pairs are treated as cuts."""

FLOW_MAX_WIDTH = 960
"""The flow is computed on frames scaled down to at most this width (half a 1080p frame): DIS at full 1080p costs
30 ms a pair against 6, and the motion of a blur worth rendering is many pixels long."""

BAND_ROWS = 64
"""The frame is integrated in bands of rows; a band with no motion is copied, so the cost follows what moves."""

SCENE_CUT_CHANGE = 0.08
"""A change of the 16x16-block means between two consecutive frames above this (mean absolute, [0, 1] scale) is
a scene cut: noise, which averages out over 256 pixels, moves the block means by well under 0.01 at the
strongest training level; a camera pan or a light switched on in a dim scene moves them by a few hundredths. The
one threshold of the blur's cut test (:func:`is_scene_cut`) and the estimator's
(:func:`darksynth.estimation.reference.scene_cuts`)."""


FLOW_MATCH = 0.6
"""A flow whose warp leaves a residual above this share of the image's contrast (mean absolute deviation) did not
find the same scene: the pair is treated as a cut. A flow that holds leaves a tenth or less (noise, occlusions);
two unrelated images about the full contrast."""

FLAT_CONTRAST = 2.0
"""Flow images (8-bit) with a mean absolute deviation under this have nothing for a flow to follow (black, flat)."""

_RELATIVE_LINEAR = cv2.INTER_LINEAR | cv2.WARP_RELATIVE_MAP
"""Bilinear resampling whose map holds each pixel's displacement, not its source position: no grid to add."""


def flow_image(frame: np.ndarray) -> tuple[np.ndarray, float]:
    """The 8-bit grey image the flow is computed on, and its scale (frame width / flow width)."""
    scale = max(1.0, frame.shape[1] / FLOW_MAX_WIDTH)
    levels = frame if frame.dtype == np.uint8 else np.round(unit_scale(frame).clip(0, 1) * 255.0).astype(np.uint8)
    grey = levels if levels.ndim == 2 else levels[..., 0]
    if levels.ndim == 3 and levels.shape[-1] > 1:
        grey = cv2.cvtColor(np.ascontiguousarray(levels[..., :3]), cv2.COLOR_RGB2GRAY)
    if scale > 1.0:
        size = (max(1, round(frame.shape[1] / scale)), max(1, round(frame.shape[0] / scale)))
        grey = cv2.resize(grey, size, interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(grey), scale


def is_scene_cut(previous: np.ndarray, following: np.ndarray) -> bool:
    """Whether two flow images (:func:`flow_image`) show different scenes (see :data:`SCENE_CUT_CHANGE`)."""
    if previous.shape != following.shape:
        return True
    size = (max(1, previous.shape[1] // 16), max(1, previous.shape[0] // 16))
    blocks = [
        cv2.resize(g, size, interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0 for g in (previous, following)
    ]
    return float(np.abs(blocks[1] - blocks[0]).mean()) > SCENE_CUT_CHANGE


@functools.lru_cache(maxsize=4)
def pixel_grid(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's x and y (H, W), float32 and contiguous, the identity maps of ``cv2.remap``; made once per size
    (read-only: the estimator's every pair shares them; the blur's own resamplings use relative maps instead)."""
    grid_x = np.tile(np.arange(width, dtype=np.float32), (height, 1))
    grid_y = np.tile(np.arange(height, dtype=np.float32)[:, None], (1, width))
    grid_x.flags.writeable = grid_y.flags.writeable = False
    return grid_x, grid_y


def dense_flow(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Per-pixel displacement (h, w, 2: x, y) from ``source`` to ``target``, two flow images (:func:`flow_image`,
    each side at least :data:`MIN_FLOW_SIDE`), in their pixels.

    A new DIS engine for every call (6 us): an engine kept between calls carries state from one to the next (after a
    pair of 40x40 noise frames, the flow of an unrelated pair moved by a third of a pixel)."""
    engine = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_FAST)  # type: ignore[attr-defined]
    flow: np.ndarray = engine.calc(source, target, None)
    return flow


def inverse_flow(flow: np.ndarray, iterations: int = 2) -> np.ndarray:
    """The flow from the target back to the source, on the target's pixels, from ``flow`` (source to target).

    A target pixel y came from the source pixel x with x + F(x) = y, so the flow back is -F(x); x is found by
    fixed-point steps x = y - F(x) from x = y - F(y), each a resampling of F (exact for a translation, and within a
    few hundredths of a pixel for the smooth fields of camera and object motion; at an occlusion neither this nor
    a flow computed backwards has a right answer)."""
    back = flow
    for _ in range(iterations):
        back = cv2.remap(flow, -back, None, _RELATIVE_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    inverse: np.ndarray = -back
    return inverse


def flow_holds(source: np.ndarray, target: np.ndarray, flow: np.ndarray) -> bool:
    """Whether ``target`` warped back along ``flow`` matches ``source``: the flow found the same scene. Unrelated
    frames (a cut the block means miss, black or flat frames) leave a residual as large as the image's contrast."""
    as_float = source.astype(np.float32)
    contrast = float(cv2.mean(cv2.absdiff(as_float, float(cv2.mean(as_float)[0])))[0])  # type: ignore[call-overload]
    if contrast < FLAT_CONTRAST:
        return False
    warped = cv2.remap(target, flow, None, _RELATIVE_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    residual = float(cv2.mean(cv2.absdiff(warped, source))[0])
    return residual < FLOW_MATCH * contrast


def full_resolution(
    flow: np.ndarray, scale: float, shape: tuple[int, int], workspace: Workspace | None = None
) -> np.ndarray:
    """A flow of the flow images at the frame's size (H, W) and in its pixels (in ``workspace``'s buffer if given:
    valid until its next use)."""
    if scale <= 1.0:
        return flow
    resized = _buffer(workspace, "velocity", (shape[0], shape[1], 2), np.float32)
    cv2.resize(flow, (shape[1], shape[0]), dst=resized, interpolation=cv2.INTER_LINEAR)
    cv2.multiply(resized, scale, dst=resized)
    return resized


class Workspace:
    """Scratch buffers kept from one frame to the next, by name.

    A 1080p blur needs a dozen frame-sized arrays; allocated afresh at every frame, their pages are faulted in and
    zeroed by the system each time, which cost as much as the arithmetic written into them (a third of the
    integral's time). A stream keeps one workspace; a buffer is valid until the next request of its name."""

    def __init__(self) -> None:
        self._buffers: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype: npt.DTypeLike) -> np.ndarray:
        """A C-contiguous array of ``shape`` and ``dtype`` (contents undefined), kept for the next call by ``name``."""
        size = math.prod(shape)
        buffer = self._buffers.get(name)
        if buffer is None or buffer.dtype != dtype or buffer.size < size:
            buffer = np.empty(size, dtype)
            self._buffers[name] = buffer
        return buffer[:size].reshape(shape)


def _buffer(workspace: Workspace | None, name: str, shape: tuple[int, ...], dtype: npt.DTypeLike) -> np.ndarray:
    return np.empty(shape, dtype) if workspace is None else workspace.get(name, shape, dtype)


def blur_frame(
    frame: np.ndarray, exposure_fraction: float, to_previous: np.ndarray | None, to_next: np.ndarray | None
) -> np.ndarray:
    """One frame integrated over its exposure along its motion.

    The frame's velocity is taken constant over its exposure: half the flow to the next frame minus the flow to
    the previous one (where one is missing, the other alone). The integral over the path, ``3^K`` points evenly
    spread, is built in K steps, each the mean of the running image and of it shifted both ways along the
    velocity by a third of the last step's spread: 2K resamplings make ``3^K`` points (27 in 6, 81 in 8).
    Only rows that move are integrated (runs of bands of :data:`BAND_ROWS` rows, each with a margin as long as
    its longest path, so the shifted reads stay inside).

    Args:
        frame: the clean frame (H, W, C), uint8, uint16 or float in [0, 1], sRGB.
        exposure_fraction: ``s`` in [0, 1].
        to_previous, to_next: flow (H, W, 2) from this frame to the previous and the next one, in the frame's
            pixels (:func:`dense_flow`, :func:`full_resolution`); None where there is none (the first or last frame,
            a cut). Without either, the frame is returned as it is.

    Returns:
        The blurred frame, same shape and dtype; pixels whose blur is under :data:`STILL_LENGTH` keep their value.
    """
    if exposure_fraction <= 0 or (to_previous is None and to_next is None):
        return frame
    return blur_along(frame, exposure_fraction, frame_velocity(to_previous, to_next))


def blur_along(
    frame: np.ndarray, exposure_fraction: float, velocity: np.ndarray, workspace: Workspace | None = None
) -> np.ndarray:
    """:func:`blur_frame` with the frame's velocity (H, W, 2) given: px per frame interval, constant over the
    exposure. ``workspace`` (a stream's) keeps the scratch buffers from one frame to the next."""
    if exposure_fraction <= 0:
        return frame
    height, width = frame.shape[:2]
    # The path's extent s * v per pixel (x, y interleaved: the relative map of the resamplings), and its length.
    if exposure_fraction == 1.0 and velocity.dtype == np.float32 and velocity.flags.c_contiguous:
        path = velocity  # read only (a stream passes its velocity with s folded in)
    else:
        path = _buffer(workspace, "path", (height, width, 2), np.float32)
        cv2.multiply(np.ascontiguousarray(velocity, dtype=np.float32), float(exposure_fraction), dst=path)
    # x and y apart for the length, in the buffer the resamplings' offsets take later.
    x, y = cv2.split(path, list(_buffer(workspace, "offsets", (2, height, width), np.float32)))
    lengths = cv2.magnitude(x, y, _buffer(workspace, "lengths", (height, width), np.float32))
    if float(lengths.max()) < STILL_LENGTH:
        return frame
    # 8-bit frames are integrated as 16-bit linear light: half the memory traffic of float32 (the resamplings are
    # bound by it: a third faster at 1080p), and a 16-bit step is a fifteenth of the darkest 8-bit level's.
    eight_bit = frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[-1] <= 4
    if eight_bit:
        linear = cv2.LUT(frame, LINEAR16_OF_LEVEL, dst=_buffer(workspace, "linear", frame.shape, np.uint16))
    else:
        linear = decode(frame)
    if linear.ndim == 2:
        linear = linear[..., None]
    out = frame.copy()
    for top, bottom in _moving_runs(lengths):
        # The path's points are spread for the 99.5th percentile of the lengths (read on every 4th pixel of every
        # 4th row): the flow's few outliers (where content enters the frame) would otherwise set the count of
        # resamplings for the whole run.
        longest = float(np.percentile(lengths[top:bottom:4, ::4], 99.5))
        margin = math.ceil(float(lengths[top:bottom].max())) + 2
        low, high = max(0, top - margin), min(height, bottom + margin)
        total = _path_mean(linear[low:high], path[low:high], longest, workspace)[top - low : bottom - low]
        if eight_bit:
            _blend_levels(frame[top:bottom], linear[top:bottom], total, lengths[top:bottom], out[top:bottom])
        else:
            out[top:bottom] = _blend(frame[top:bottom], linear[top:bottom], total, lengths[top:bottom])
    return out


def _moving_runs(lengths: np.ndarray) -> list[tuple[int, int]]:
    """Runs of consecutive bands of rows whose longest blur reaches :data:`STILL_LENGTH`, as (top, bottom) rows."""
    height = lengths.shape[0]
    runs: list[tuple[int, int]] = []
    for top in range(0, height, BAND_ROWS):
        bottom = min(height, top + BAND_ROWS)
        if float(lengths[top:bottom].max()) < STILL_LENGTH:
            continue
        if runs and runs[-1][1] == top:
            runs[-1] = (runs[-1][0], bottom)
        else:
            runs.append((top, bottom))
    return runs


def _path_mean(linear: np.ndarray, path: np.ndarray, longest: float, workspace: Workspace | None) -> np.ndarray:
    """The mean of ``linear`` (h, w, C) over each pixel's path, ``path`` (h, w, 2) the path's full extent (s times
    the velocity), by ternary steps (see :func:`blur_frame`). The result may be a workspace buffer."""
    steps = 1
    while 3**steps < longest / SAMPLE_SPACING + 1 and steps < MAX_STEPS:
        steps += 1
    shape = linear.shape
    image = linear
    # Three image buffers: the shift one way (then the pair's mean), and two that take in turn the shift the other
    # way and the step's result, so that the running image is never written while it is read.
    minus = _buffer(workspace, "minus", shape, linear.dtype)
    turns = [_buffer(workspace, f"turn{index}", shape, linear.dtype) for index in (0, 1)]
    current = -1  # the running image is the linear frame, in no buffer
    # Step j shifts by 3^(K - j) / 3^K of the path, the coarsest last, so that the finest shifts see the sharp frame.
    for step in range(steps, 0, -1):
        spread = 3 ** (steps - step) / 3**steps
        target = 1 if current == 0 else 0
        for sign, into in ((-1.0, minus), (1.0, turns[target])):
            offsets = cv2.multiply(path, sign * spread, dst=_buffer(workspace, "offsets", path.shape, np.float32))
            cv2.remap(image, offsets, None, _RELATIVE_LINEAR, borderMode=cv2.BORDER_REPLICATE, dst=into)
        # OpenCV's arithmetic runs on every core; numpy's on one.
        cv2.addWeighted(minus, 1 / 3, turns[target], 1 / 3, 0.0, dst=minus)
        cv2.addWeighted(image, 1 / 3, minus, 1.0, 0.0, dst=turns[target])
        image, current = turns[target], target
    return image


def _blend_levels(
    frame: np.ndarray, linear: np.ndarray, integrated: np.ndarray, lengths: np.ndarray, out: np.ndarray
) -> None:
    """:func:`_blend` for an 8-bit frame integrated in 16-bit linear light, written into ``out`` (rows of the
    frame's copy): the integral encoded by one table read, the few pixels between :data:`STILL_LENGTH` and
    :data:`FULL_LENGTH` blended, and the still pixels' bytes put back."""
    levels_of_linear16(integrated.reshape(frame.shape), out=out)
    # Both ends inclusive (OpenCV's range test): at either end the blend gives the pixel's own level or the
    # integral's (the 16-bit table returns every level it was made from), so they change nothing.
    between = cv2.findNonZero(cv2.inRange(lengths, STILL_LENGTH, FULL_LENGTH))
    if between is not None:
        x, y = between.reshape(-1, 2).T  # (N, 1, 2) or (N, 2) by OpenCV version
        weight = ((lengths[y, x] - STILL_LENGTH) / (FULL_LENGTH - STILL_LENGTH))[:, None]
        own = linear[y, x].astype(np.float32)
        mixed = own + weight * (integrated[y, x].astype(np.float32) - own)
        out[y, x] = LEVEL_OF_LINEAR16[np.round(mixed).astype(np.uint16)]
    still = cv2.compare(lengths, STILL_LENGTH, cv2.CMP_LE)  # type: ignore[call-overload]
    if cv2.countNonZero(still):
        cv2.copyTo(frame, still, out)


def _blend(frame: np.ndarray, linear: np.ndarray, integrated: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The integrated rows blended with the frame's own by blur length (:data:`STILL_LENGTH` to
    :data:`FULL_LENGTH`), in linear light, encoded; fully still pixels keep their exact value."""
    weight = np.clip((lengths - STILL_LENGTH) / (FULL_LENGTH - STILL_LENGTH), 0.0, 1.0)
    if float(weight.min()) >= 1.0:
        return encode(integrated, frame.dtype).reshape(frame.shape)
    mixed = encode(linear + weight[..., None] * (integrated - linear), frame.dtype).reshape(frame.shape)
    still = (weight <= 0.0)[..., None] if frame.ndim == 3 else weight <= 0.0
    return np.where(still, frame, mixed)


def frame_velocity(to_previous: np.ndarray | None, to_next: np.ndarray | None) -> np.ndarray:
    """Displacement per frame interval (H, W, 2) of each pixel of a frame, from its flows to its neighbours."""
    if to_previous is None and to_next is not None:
        return to_next
    if to_next is None and to_previous is not None:
        return -to_previous
    if to_next is None or to_previous is None:
        raise ValueError("a frame's velocity needs a flow to at least one neighbour")
    velocity: np.ndarray = (to_next - to_previous) * np.float32(0.5)
    return velocity


def shake_blur(frame: np.ndarray, length: float, angle: float) -> np.ndarray:
    """A still image blurred by camera shake: a straight path of ``length`` px at ``angle`` degrees
    (counter-clockwise from the x axis), integrated in linear light. Under :data:`STILL_LENGTH` nothing changes."""
    if length < STILL_LENGTH:
        return frame
    kernel = line_kernel(length, angle)
    linear = decode(frame)
    blurred = cv2.filter2D(linear, -1, kernel, borderType=cv2.BORDER_REPLICATE)
    return encode(blurred.reshape(linear.shape), frame.dtype).reshape(frame.shape)


def line_kernel(length: float, angle: float) -> np.ndarray:
    """A normalised kernel of a straight path of ``length`` px through the centre at ``angle`` degrees, drawn as
    the mean of bilinear splats of points spaced by at most a tenth of a pixel (so any length and angle has an
    exact first moment)."""
    radius = math.ceil(length / 2) + 1
    size = 2 * radius + 1
    kernel = np.zeros((size, size), np.float64)
    count = max(2, math.ceil(length * 10))
    theta = math.radians(angle)
    for t in (np.arange(count) + 0.5) / count - 0.5:
        x = radius + t * length * math.cos(theta)
        y = radius - t * length * math.sin(theta)
        x0, y0 = math.floor(x), math.floor(y)
        fx, fy = x - x0, y - y0
        kernel[y0, x0] += (1 - fx) * (1 - fy)
        kernel[y0, x0 + 1] += fx * (1 - fy)
        kernel[y0 + 1, x0] += (1 - fx) * fy
        kernel[y0 + 1, x0 + 1] += fx * fy
    normalised: np.ndarray = (kernel / kernel.sum()).astype(np.float32)
    return normalised


@dataclass
class _Held:
    frame: np.ndarray
    grey: np.ndarray
    scale: float
    to_previous: np.ndarray | None
    """The flow to the previous frame, at the flow image's size."""


class MotionBlurStream:
    """Frames in, blurred frames out, one frame behind (a frame's blur needs the next one); at most two frames are
    held, so memory does not grow with the length.

    ``push(frame)`` returns the frames finished so far (none for the first); ``finish()`` the last one.

    Args:
        exposure_fraction: ``s`` in [0, 1]; 0 passes frames through without computing any flow.
    """

    def __init__(self, exposure_fraction: float) -> None:
        self.exposure_fraction = float(exposure_fraction)
        self._held: _Held | None = None
        self._workspace = Workspace()
        self.cuts = 0
        """Pairs of frames across which nothing was blurred: scene cuts, size changes, a flow that failed."""

    def push(self, frame: np.ndarray) -> list[np.ndarray]:
        if self.exposure_fraction <= 0:
            return [frame]
        grey, scale = flow_image(frame)
        held = self._held
        if held is None:
            self._held = _Held(frame, grey, scale, None)
            return []
        # Flows stay at the flow images' size: the frame's velocity is formed there and scaled up once.
        to_next = to_previous = None
        if held.frame.shape == frame.shape and min(grey.shape) >= MIN_FLOW_SIDE and not is_scene_cut(held.grey, grey):
            # One flow a pair: the way back, on the next frame's pixels, is this one inverted (a DIS flow of its
            # own cost a fifth of the blur for the same field where the motion is smooth).
            forward = dense_flow(held.grey, grey)
            if flow_holds(held.grey, grey, forward):
                to_next, to_previous = forward, inverse_flow(forward)
        if to_next is None:
            self.cuts += 1
        finished = self._blur(held, to_next)
        self._held = _Held(frame, grey, scale, to_previous)
        return [finished]

    def finish(self) -> list[np.ndarray]:
        held, self._held = self._held, None
        return [] if held is None else [self._blur(held, None)]

    def _blur(self, held: _Held, to_next: np.ndarray | None) -> np.ndarray:
        if held.to_previous is None and to_next is None:
            return held.frame
        shape = (held.frame.shape[0], held.frame.shape[1])
        # s folded into the velocity at the flow's size: the path comes out of the upscaling as it is.
        velocity = frame_velocity(held.to_previous, to_next) * np.float32(self.exposure_fraction)
        path = full_resolution(velocity, held.scale, shape, self._workspace)
        return blur_along(held.frame, 1.0, path, self._workspace)

    def run(self, frames: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
        """All frames of an iterator, blurred, in order."""
        for frame in frames:
            yield from self.push(frame)
        yield from self.finish()
