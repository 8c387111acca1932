"""Reading and writing videos frame by frame with PyAV, as (H, W, 3) uint8 RGB arrays.

Frames are streamed: neither reading nor writing holds more than the codec's own few frames in memory, whatever
the length of the video. The writer can carry a source video's audio tracks over unchanged, packet by packet
(:mod:`darksynth.io.audio_copy`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import Final, Self

import av
import numpy as np
from av.container import InputContainer, OutputContainer
from av.video.reformatter import ColorRange, Colorspace
from av.video.stream import VideoStream
from PIL import Image as PILImage

from darksynth.errors import DarksynthError, InputFileError, error_reason
from darksynth.io.atomic import atomic_output
from darksynth.io.audio_copy import AudioCopy
from darksynth.io.video_encoding import DEFAULT_CODEC, DEFAULT_CRF, DEFAULT_ENCODING, VideoEncoding, configure_stream

__all__ = [
    "DEFAULT_CODEC",
    "DEFAULT_CRF",
    "DEFAULT_ENCODING",
    "VIDEO_SUFFIXES",
    "VideoEncoding",
    "VideoInfo",
    "VideoWriter",
    "iter_video_frames",
    "probe_video",
]

logger = logging.getLogger(__name__)

VIDEO_SUFFIXES: Final[frozenset[str]] = frozenset({".mp4", ".mov", ".avi", ".mkv"})

# x265 (4.2, as bundled with PyAV) computes its first packets' decoding times as pts - m_bframeDelayTime, a field it
# sets only once it has received b-frame-delay + 1 frames (the delay is 2 with B-frames and their pyramid, the
# defaults, 1 or 0 otherwise) and never initialises: a clip of at most 2 frames gets a decoding time offset by
# whatever the heap held (x265 issue #781, fixed upstream by PR #936). That garbage depends on what the process
# allocated before (cv2, torch...), so the muxer refused it (EINVAL, pts < dts) in about 1 full test run in 3,
# never in a fresh process. Such a clip is coded without reordering (the first frame is the keyframe, decoded
# first) and comes out whole at the flush, so its decoding times are set to its presentation times, as the fixed
# x265 gives. (Moving a bad decoding time past the last one hid the error but wrote absurd presentation times.)
_X265_MAX_BFRAME_DELAY: Final = 2


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`probe_video` learns about a video's first video stream.

    Attributes:
        width: Width of the upright frames in pixels (after the display rotation, if any).
        height: Height of the upright frames in pixels.
        fps: Frame rate in frames per second, exact (for example ``Fraction(30000, 1001)``).
        frame_count: Number of frames the container declares, or None when it does not say (for example MKV).
        codec: FFmpeg's name for the codec (for example ``"h264"``).
    """

    width: int
    height: int
    fps: Fraction
    frame_count: int | None
    codec: str


def probe_video(path: Path) -> VideoInfo:
    """Read a video's size, frame rate, frame count and codec, decoding at most its first frame.

    The first frame is decoded to learn the display rotation (phone videos are often stored sideways with a
    rotation tag) and to check that the stream is decodable at all.

    Args:
        path: The video file.

    Returns:
        The properties of the first video stream.

    Raises:
        InputFileError: If the file is missing, is not a readable container, has no video stream, no known frame
            rate or no decodable frame.
    """
    with _open_input(path) as container:
        stream = _video_stream(path, container)
        fps = stream.guessed_rate or stream.average_rate or stream.base_rate
        if not fps:
            raise InputFileError(path, "video frame rate is unknown")
        first = next(_decoded_frames(path, container, stream), None)
        if first is None:
            raise InputFileError(path, "no decodable video frames")
        quarter_turns = _quarter_turns(first)
        width, height = first.width, first.height
        if quarter_turns % 2:
            width, height = height, width
        return VideoInfo(
            width=width,
            height=height,
            fps=Fraction(fps),
            frame_count=stream.frames or None,
            codec=stream.codec_context.name,
        )


def iter_video_frames(path: Path) -> Iterator[np.ndarray]:
    """Decode a video's first video stream one frame at a time.

    Frames are converted with the colour matrix and range the stream declares and turned upright by its display
    rotation, so they match :func:`probe_video`'s width and height.

    Args:
        path: The video file.

    Yields:
        Each frame as a new (H, W, 3) uint8 RGB array.

    Raises:
        InputFileError: If the file cannot be opened as a video, or a frame cannot be decoded (the message gives
            the index of the first frame that failed).
    """
    with _open_input(path) as container:
        stream = _video_stream(path, container)
        stream.thread_type = "AUTO"
        for frame in _decoded_frames(path, container, stream):
            rgb = frame.to_ndarray(format="rgb24", src_color_range=frame.color_range)
            quarter_turns = _quarter_turns(frame)
            yield np.ascontiguousarray(np.rot90(rgb, k=quarter_turns)) if quarter_turns else rgb


class VideoWriter:
    """Encode (H, W, 3) uint8 RGB frames into a video file that appears only once it is complete.

    Use as a context manager. Frames go to a hidden temporary file next to ``path``; on a normal exit the encoder
    is flushed, the container closed and the file renamed to ``path``. On an exception nothing is left at
    ``path`` (a file already there is kept unchanged).

    Example:
        >>> with VideoWriter(Path("out.mp4"), width=64, height=48, fps=Fraction(25)) as writer:
        ...     for frame in frames:
        ...         writer.write(frame)

    Args:
        path: Output path; the suffix (.mp4 .mov .avi .mkv) chooses the container; parent folders are created.
        width: Frame width in pixels (odd sizes work with the default codec).
        height: Frame height in pixels.
        fps: Frame rate, kept exactly (``Fraction(30000, 1001)`` stays 29.97...).
        encoding: The codec, CRF and pixel format (:class:`~darksynth.io.video_encoding.VideoEncoding`; the
            defaults of each codec where it leaves a choice). ``self.encoding`` is the one used, every choice made.
        audio_from: A video whose audio tracks are copied into the output unchanged (packets remuxed, not
            re-encoded), shifted as its first video frame is to time 0 so they stay in sync; tracks whose codec
            the container cannot hold are left out with one logged notice. None writes no audio.

    Raises:
        DarksynthError: On construction, if the size, frame rate, codec, crf or pixel format is not usable; on
            entering, if the suffix or the codec/container pair is not, or the encoder refuses the settings; on
            writing or closing, if the encoder fails. Each message is one line and names the path.
    """

    def __init__(
        self,
        path: Path,
        *,
        width: int,
        height: int,
        fps: Fraction,
        encoding: VideoEncoding = DEFAULT_ENCODING,
        audio_from: Path | None = None,
    ) -> None:
        if width < 1 or height < 1:
            raise DarksynthError(f"{path}: video size must be positive, got {width}x{height}")
        if fps <= 0:
            raise DarksynthError(f"{path}: frame rate must be positive, got {fps}")
        self.path, self.width, self.height = path, width, height
        self.fps = Fraction(fps)
        self.encoding = encoding.resolved(path, width, height)
        self.audio_from = audio_from
        self.audio_codecs: tuple[str, ...] = ()
        """The codecs of the audio tracks copied from ``audio_from``, known once the writer is open."""
        self._audio: AudioCopy | None = None
        self._colorspace = self.encoding.colorspace()
        self._stack: contextlib.ExitStack | None = None
        self._container: OutputContainer | None = None
        self._stream: VideoStream | None = None
        self._frames_written = 0

    def __enter__(self) -> Self:
        if self.path.suffix.lower() not in VIDEO_SUFFIXES:
            raise DarksynthError(f"{self.path}: not a video suffix (use one of {' '.join(sorted(VIDEO_SUFFIXES))})")
        stack = contextlib.ExitStack()
        try:
            tmp = stack.enter_context(atomic_output(self.path))
            container = stack.enter_context(av.open(str(tmp), mode="w"))
            if self.encoding.codec not in container.supported_codecs:
                raise DarksynthError(
                    f"{self.path}: the {self.path.suffix.lower()} container cannot hold {self.encoding.codec} video"
                )
            self._stream = _output_stream(container, self.path, self.width, self.height, self.fps, self.encoding)
            self._container = container
            if self.audio_from is not None:
                source = stack.enter_context(_open_input(self.audio_from))
                self._audio = AudioCopy(self.audio_from, source, self.path, container)
                self.audio_codecs = self._audio.codecs
            # Opening the encoder and writing the header now makes a bad size or option fail here, before any work.
            self._stream.codec_context.open()
            container.start_encoding()
        except BaseException as err:
            stack.__exit__(type(err), err, err.__traceback__)
            if isinstance(err, av.FFmpegError | ValueError):
                raise DarksynthError(f"{self.path}: cannot encode {self._describe()} ({error_reason(err)})") from err
            raise
        self._stack = stack
        return self

    def write(self, frame: np.ndarray) -> None:
        """Encode one frame.

        Args:
            frame: A (height, width, 3) uint8 RGB array.

        Raises:
            ValueError: If the frame's shape or dtype is wrong.
            RuntimeError: If the writer is not open (used outside its ``with`` block).
            DarksynthError: If the encoder fails.
        """
        if self._container is None or self._stream is None:
            raise RuntimeError("VideoWriter.write called outside its with block")
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frame must be a ({self.height}, {self.width}, 3) uint8 array, got {frame.shape} {frame.dtype}"
            )
        video_frame = _stream_frame(frame, self._stream.codec_context.pix_fmt, self._colorspace)
        video_frame.pts = self._frames_written
        video_frame.time_base = 1 / self.fps
        if self._audio is not None:
            self._audio.mux_until(self._container, (self._frames_written + 1) / self.fps)
        try:
            self._container.mux(self._stream.encode(video_frame))
        except av.FFmpegError as err:
            raise DarksynthError(
                f"{self.path}: encoding frame {self._frames_written} failed ({error_reason(err)})"
            ) from err
        self._frames_written += 1

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> bool:
        stack, container, stream, audio = self._stack, self._container, self._stream, self._audio
        self._stack = self._container = self._stream = self._audio = None
        if stack is None:
            return False
        if exc is not None:
            # atomic_output sees the exception and removes the temporary file.
            return bool(stack.__exit__(exc_type, exc, traceback))
        try:
            if self._frames_written == 0:
                raise DarksynthError(f"{self.path}: no frames were written")
            if container is None or stream is None:
                raise RuntimeError("VideoWriter lost its container")
            _flush(container, stream, self.encoding, self._frames_written)
            if audio is not None:
                audio.mux_until(container, None)
        except BaseException as err:
            stack.__exit__(type(err), err, err.__traceback__)
            if isinstance(err, av.FFmpegError):
                raise DarksynthError(f"{self.path}: finishing the video failed ({error_reason(err)})") from err
            raise
        try:
            stack.__exit__(None, None, None)
        except av.FFmpegError as err:
            raise DarksynthError(f"{self.path}: finishing the video failed ({error_reason(err)})") from err
        return False

    def _describe(self) -> str:
        encoding = self.encoding
        return f"{self.width}x{self.height} at {self.fps} fps with {encoding.codec} in {encoding.pix_fmt}"


def _output_stream(
    container: OutputContainer, path: Path, width: int, height: int, fps: Fraction, encoding: VideoEncoding
) -> VideoStream:
    """The output's video stream, configured as ``encoding`` says."""
    codec = encoding.codec or DEFAULT_CODEC
    stream = container.add_stream(codec, rate=fps)
    if not isinstance(stream, VideoStream):
        raise DarksynthError(f"{path}: {codec} is not a video codec")
    stream.width = width
    stream.height = height
    # An explicit time base of 1/fps keeps rates like 30000/1001 exact in every container.
    stream.codec_context.time_base = 1 / fps
    configure_stream(stream, encoding)
    return stream


def _stream_frame(frame: np.ndarray, pix_fmt: str | None, colorspace: Colorspace) -> av.VideoFrame:
    """An (H, W, 3) uint8 RGB frame as the stream's pixel format."""
    video_frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
    if pix_fmt is not None and not av.VideoFormat(pix_fmt).is_rgb:
        # Converting here, not in the encoder, fixes the matrix and range to the ones the stream is tagged with.
        video_frame = video_frame.reformat(format=pix_fmt, dst_colorspace=colorspace, dst_color_range=ColorRange.MPEG)
    return video_frame


def _flush(container: OutputContainer, stream: VideoStream, encoding: VideoEncoding, frames: int) -> None:
    """The encoder's last packets muxed (a short x265 clip's decoding times are its presentation times: see
    :data:`_X265_MAX_BFRAME_DELAY`)."""
    packets = stream.encode(None)
    if encoding.codec == "libx265" and frames <= _X265_MAX_BFRAME_DELAY:
        for packet in packets:
            packet.dts = packet.pts
    container.mux(packets)


def _open_input(path: Path) -> InputContainer:
    if not path.exists():
        raise InputFileError(path, "no such file")
    if path.is_dir():
        raise InputFileError(path, "is a folder, not a video file")
    try:
        # Tags are never read here, so a tag that is not valid UTF-8 (a damaged header) must not stop the pixels.
        return av.open(str(path), mode="r", metadata_errors="replace")
    except av.FFmpegError as err:
        raise InputFileError(path, f"not a readable video ({error_reason(err)})") from None
    except OSError as err:
        raise InputFileError(path, f"cannot open ({error_reason(err)})") from None


def _video_stream(path: Path, container: InputContainer) -> VideoStream:
    if not container.streams.video:
        raise InputFileError(path, "no video stream")
    return container.streams.video[0]


def _decoded_frames(path: Path, container: InputContainer, stream: VideoStream) -> Iterator[av.VideoFrame]:
    index = 0
    frames = container.decode(stream)
    while True:
        try:
            frame = next(frames)
        except StopIteration:
            return
        except av.FFmpegError as err:
            raise InputFileError(path, f"cannot decode video frame {index} ({error_reason(err)})") from None
        yield frame
        index += 1


def _quarter_turns(frame: av.VideoFrame) -> int:
    """Counter-clockwise quarter turns that make a frame upright, from its display matrix (0 when absent)."""
    return round(frame.rotation / 90) % 4


def to_stream_size(source: Path, frame: np.ndarray, width: int, height: int, *, first: bool) -> np.ndarray:
    """A frame (H, W, C) of another size than its stream's scaled to it (the first time with a warning)."""
    # A stream that switches resolution mid-way (adaptive streaming, a camera's mode change) cannot go into one
    # encoded stream at two sizes: the clean frame is scaled to the stream's declared size, as ffmpeg does by
    # default, before the noise is drawn, so the noise keeps its per-pixel law.
    if first:
        logger.warning(
            "%s: a frame of %dx%d in a %dx%d stream is scaled to the stream's size",
            source, frame.shape[1], frame.shape[0], width, height,
        )  # fmt: skip
    scaled = PILImage.fromarray(frame).resize((width, height), PILImage.Resampling.BILINEAR)
    return np.asarray(scaled)
