"""Carrying a source video's audio tracks into a video being written, unchanged, packet by packet."""

from __future__ import annotations

import contextlib
import io
import logging
from collections import Counter
from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path

import av
from av.audio.stream import AudioStream
from av.container import InputContainer, OutputContainer

from darksynth.errors import DarksynthError, InputFileError, error_reason

logger = logging.getLogger(__name__)


class AudioCopy:
    """The audio tracks of a source video, remuxed into an output container alongside the video being encoded.

    The packets come from a second demuxer of the source, opened on the same file, that reads only its audio, so
    they can be interleaved with the encoded video as it is written: each frame's audio goes in just before the
    frame, and memory holds one packet, whatever the length. (Taking the audio from the frame reader's demuxer
    would tie the writer to the reader; writing it all after the video would leave the output badly interleaved,
    its video and audio far apart in the file.) The source is read twice, which costs little next to decoding
    and encoding its frames.
    """

    def __init__(self, source_path: Path, source: InputContainer, path: Path, container: OutputContainer) -> None:
        self.source_path = source_path
        self.path = path
        self._outputs: dict[int, AudioStream] = {}
        codecs: list[str] = []
        dropped: list[str] = []
        for stream in source.streams.audio:
            codec = _codec_name(stream)
            if not _can_hold(container, stream):
                dropped.append(codec)
                continue
            self._outputs[stream.index] = _add_copy(container, stream)
            codecs.append(codec)
        self.codecs = tuple(codecs)
        if dropped:
            tracks = "audio track" if len(dropped) == 1 else f"{len(dropped)} audio tracks"
            logger.warning(
                "%s: %s (codec %s) cannot go into %s; written without %s",
                source_path, tracks, ", ".join(dropped), path.suffix.lower(), "it" if len(dropped) == 1 else "them",
            )  # fmt: skip
        # The output's first frame is at time 0: the audio moves with the source's first video frame.
        video = source.streams.video[0]
        left_out = Counter(s.type for s in source.streams if s.type != "audio" and s.index != video.index)
        if left_out:
            kinds = " and ".join(f"{count} {kind} track{'s' if count > 1 else ''}" for kind, count in left_out.items())
            logger.warning(
                "%s: %s not carried into the output (only the first video and the audio are)", source_path, kinds
            )
        self._offset = Fraction(video.start_time or 0) * (video.time_base or 1)
        kept = [s for s in source.streams.audio if s.index in self._outputs]
        self._packets: Iterator[av.Packet[AudioStream]] = source.demux(tuple(kept)) if kept else iter(())
        self._next: av.Packet[AudioStream] | None = None
        self._done = not kept

    def mux_until(self, container: OutputContainer, end: Fraction | None) -> None:
        """Mux the source's audio packets that start before ``end`` seconds of output time (None: all that remain).

        Raises:
            InputFileError: The source's audio cannot be read.
            DarksynthError: The muxer refuses a packet.
        """
        while True:
            packet = self._next if self._next is not None else self._read()
            self._next = None
            if packet is None:
                return
            start = self._start(packet)
            if end is not None and start is not None and start >= end:
                self._next = packet
                return
            self._shift(packet)
            packet.stream = self._outputs[packet.stream.index]
            try:
                container.mux(packet)
            except av.FFmpegError as err:
                raise DarksynthError(f"{self.path}: writing the audio failed ({error_reason(err)})") from err

    def _read(self) -> av.Packet[AudioStream] | None:
        while not self._done:
            try:
                packet = next(self._packets)
            except StopIteration:
                self._done = True
                return None
            except av.FFmpegError as err:
                raise InputFileError(self.source_path, f"cannot read its audio ({error_reason(err)})") from None
            if packet.size:  # the demuxer ends each stream with an empty packet
                return packet
        return None

    def _start(self, packet: av.Packet[AudioStream]) -> Fraction | None:
        """When a packet starts in output time, in seconds (None if it carries no time)."""
        ticks = packet.dts if packet.dts is not None else packet.pts
        if ticks is None or packet.time_base is None:
            return None
        return ticks * packet.time_base - self._offset

    def _shift(self, packet: av.Packet[AudioStream]) -> None:
        if not self._offset or packet.time_base is None:
            return
        ticks = round(self._offset / packet.time_base)
        if packet.pts is not None:
            packet.pts -= ticks
        if packet.dts is not None:
            packet.dts -= ticks


def _add_copy(container: OutputContainer, stream: AudioStream) -> AudioStream:
    output = container.add_stream_from_template(stream)
    # A codec tag is a container's own code for the codec (AVI's 0x00FF for AAC, say); left unset, the muxer picks
    # the output's own, as ffmpeg's stream copy does.
    output.codec_tag = "\0\0\0\0"
    return output


def _can_hold(container: OutputContainer, stream: AudioStream) -> bool:
    """Whether the container can take a copy of the stream: its muxer lists the codec and accepts the stream."""
    if _codec_name(stream) not in container.supported_codecs:
        return False
    # Some pairs the muxer lists are refused when the header is written (Opus or FLAC in .mov, for one): the stream
    # is tried alone in a throwaway container of the same format first, since a container cannot drop a stream.
    probe = av.open(io.BytesIO(), "w", format=container.format.name)
    try:
        _add_copy(probe, stream)
        probe.start_encoding()
    except (av.FFmpegError, ValueError):
        return False
    finally:
        with contextlib.suppress(av.FFmpegError):
            probe.close()
    return True


def _codec_name(stream: AudioStream) -> str:
    """FFmpeg's name of a stream's codec ("mp3", not its decoder's "mp3float"), as the muxers list them."""
    try:
        return stream.codec_context.codec.canonical_name
    except (AttributeError, av.FFmpegError):
        return "unknown"
