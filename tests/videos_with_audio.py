"""Videos with audio tracks made on the spot, and the audio packets of a file, for the tests of audio copying."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import av
import numpy as np


def _audio_frames(codec: str, rate: int, seconds: float, start: int) -> list[av.AudioFrame]:
    """A quiet mono tone cut into frames of the codec's frame size, in its first sample format."""
    encoder = av.Codec(codec, "w")
    sample_format = encoder.audio_formats[0]
    size = 1024
    frames = []
    for first in range(0, int(rate * seconds), size):
        tone = 0.25 * np.sin(2 * np.pi * 440 * np.arange(first, first + size) / rate)
        samples = (tone * 32767).astype(np.int16) if sample_format.name.startswith("s16") else tone.astype(np.float32)
        frame = av.AudioFrame.from_ndarray(samples[None, :], format=sample_format.name, layout="mono")
        frame.sample_rate, frame.pts = rate, start * rate + first
        frames.append(frame)
    return frames


def video_with_audio(
    path: Path, audio_codecs: tuple[str, ...], *, frames: int = 25, audio_seconds: float = 1.2, start: int = 0
) -> Path:
    """A 25 fps video (ffv1 in .mkv, else H.264), one audio track per codec, all beginning ``start`` s in."""
    with av.open(str(path), "w") as container:
        video = container.add_stream("ffv1" if path.suffix == ".mkv" else "libx264", rate=25)
        video.width, video.height = 48, 32
        video.pix_fmt = "yuv420p"
        tracks = [container.add_stream(codec, rate=8000, layout="mono") for codec in audio_codecs]
        for index in range(frames):
            frame = av.VideoFrame.from_ndarray(np.full((32, 48, 3), 40 + 5 * index % 200, np.uint8), format="rgb24")
            frame.pts = start * 25 + index
            container.mux(video.encode(frame))
        for codec, track in zip(audio_codecs, tracks, strict=True):
            for audio_frame in _audio_frames(codec, 8000, audio_seconds, start):
                container.mux(track.encode(audio_frame))
            container.mux(track.encode(None))
        container.mux(video.encode(None))
    return path


def audio_packets(path: Path) -> list[list[tuple[bytes, Fraction | None, Fraction | None, Fraction]]]:
    """Each audio track's packets in order: bytes, pts and dts in seconds, duration in seconds."""
    with av.open(str(path)) as container:
        tracks = []
        for stream in container.streams.audio:
            packets = []
            for packet in container.demux(stream):
                if packet.size:
                    tb = packet.time_base
                    pts = None if packet.pts is None else packet.pts * tb
                    dts = None if packet.dts is None else packet.dts * tb
                    packets.append((bytes(packet), pts, dts, packet.duration * tb))
            tracks.append(packets)
            container.seek(0)
    return tracks
