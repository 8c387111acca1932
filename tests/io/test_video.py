from __future__ import annotations

import ctypes
import tracemalloc
from fractions import Fraction
from pathlib import Path
from typing import Any

import av
import numpy as np
import pytest

from darksynth.errors import DarksynthError, InputFileError
from darksynth.io.video import (
    DEFAULT_CODEC,
    DEFAULT_CRF,
    VIDEO_SUFFIXES,
    VideoEncoding,
    VideoInfo,
    VideoWriter,
    iter_video_frames,
    probe_video,
)
from tests.videos_with_audio import audio_packets, video_with_audio


def _gradient_frames(count: int, height: int = 48, width: int = 64) -> list[np.ndarray]:
    y, x = np.mgrid[0:height, 0:width]
    frames = []
    for i in range(count):
        red = (x * 255 // max(width - 1, 1) + 7 * i) % 256
        green = y * 255 // max(height - 1, 1)
        blue = np.full_like(x, (40 + 20 * i) % 256)
        frames.append(np.stack([red, green, blue], axis=-1).astype(np.uint8))
    return frames


def _write(path: Path, frames: list[np.ndarray], fps: Fraction = Fraction(25), **encoding: Any) -> None:
    height, width = frames[0].shape[:2]
    with VideoWriter(path, width=width, height=height, fps=fps, encoding=VideoEncoding(**encoding)) as writer:
        for frame in frames:
            writer.write(frame)


def test_video_suffixes() -> None:
    assert frozenset({".mp4", ".mov", ".avi", ".mkv"}) == VIDEO_SUFFIXES


@pytest.mark.parametrize(
    ("pix_fmt", "written", "profile", "mean_error", "quantile"),
    [
        # 4:2:0 shares one chroma sample between 2x2 pixels: the steep red ramp loses more than in 4:4:4 (mean
        # error 1.9-3.6 against 0.9-1.0), and at the edge where red wraps from 255 to 0, two pixels that share a
        # chroma sample are off by up to 104, so the bound holds for 95% of the values there, not all.
        (None, "yuv420p", "High", 4.0, 0.95),
        ("yuv444p", "yuv444p", "High 4:4:4 Predictive", 1.5, 1.0),
    ],
)
@pytest.mark.parametrize("fps", [Fraction(25), Fraction(30000, 1001)])
def test_default_codec_round_trip(
    tmp_path: Path, fps: Fraction, pix_fmt: str | None, written: str, profile: str, mean_error: float, quantile: float
) -> None:
    frames = _gradient_frames(10)
    path = tmp_path / "clip.mp4"
    _write(path, frames, fps=fps, pix_fmt=pix_fmt)
    assert probe_video(path) == VideoInfo(width=64, height=48, fps=fps, frame_count=10, codec="h264")
    back = list(iter_video_frames(path))
    assert len(back) == 10
    for original, decoded in zip(frames, back, strict=True):
        assert decoded.shape == (48, 64, 3)
        assert decoded.dtype == np.uint8
        error = np.abs(decoded.astype(int) - original)
        assert error.mean() < mean_error
        assert np.quantile(error, quantile) <= 12
    with av.open(str(path)) as container:
        context = container.streams.video[0].codec_context
        assert context.pix_fmt == written
        assert context.profile == profile


@pytest.mark.parametrize(("suffix", "codec", "crf"), [(".mkv", "ffv1", None), (".avi", "ffv1", None)])
@pytest.mark.parametrize("fps", [Fraction(25), Fraction(30000, 1001)])
def test_lossless_codecs_are_exact(tmp_path: Path, suffix: str, codec: str, crf: int | None, fps: Fraction) -> None:
    frames = _gradient_frames(10)
    path = tmp_path / f"clip{suffix}"
    _write(path, frames, fps=fps, codec=codec, crf=crf)
    info = probe_video(path)
    assert (info.width, info.height, info.fps, info.codec) == (64, 48, fps, codec)
    assert info.frame_count in (10, None)
    back = list(iter_video_frames(path))
    np.testing.assert_array_equal(np.stack(back), np.stack(frames))


@pytest.mark.parametrize("suffix", [".mkv", ".mp4", ".mov"])
def test_libx264rgb_crf0_is_exact(tmp_path: Path, suffix: str) -> None:
    frames = _gradient_frames(6)
    path = tmp_path / f"clip{suffix}"
    _write(path, frames, codec="libx264rgb", crf=0)
    np.testing.assert_array_equal(np.stack(list(iter_video_frames(path))), np.stack(frames))


def test_mpeg4_avi_round_trip(tmp_path: Path) -> None:
    frames = _gradient_frames(5)
    path = tmp_path / "clip.avi"
    _write(path, frames, codec="mpeg4")
    assert probe_video(path).codec == "mpeg4"
    back = np.stack(list(iter_video_frames(path)))
    assert np.abs(back.astype(int) - np.stack(frames)).mean() < 4


def test_odd_size_with_default_codec(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    # x264 cannot code an odd side in 4:2:0; the size is kept (annotations depend on it) and 4:4:4 used instead.
    frames = _gradient_frames(3, height=143, width=175)
    path = tmp_path / "odd.mp4"
    _write(path, frames, fps=Fraction(24000, 1001))
    info = probe_video(path)
    assert (info.width, info.height, info.fps) == (175, 143, Fraction(24000, 1001))
    back = list(iter_video_frames(path))
    assert [f.shape for f in back] == [(143, 175, 3)] * 3
    assert np.abs(np.stack(back).astype(int) - np.stack(frames)).mean() < 1.5
    with av.open(str(path)) as container:
        assert container.streams.video[0].codec_context.pix_fmt == "yuv444p"
    notices = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert notices == [f"{path}: 175x143 has an odd side, which libx264 cannot code in yuv420p; written as yuv444p"]


@pytest.mark.parametrize(("width", "height"), [(175, 144), (176, 143)])
def test_odd_size_with_explicit_420_is_refused(tmp_path: Path, width: int, height: int) -> None:
    with pytest.raises(DarksynthError, match=f"cannot code {width}x{height} in yuv420p.*use yuv444p"):
        VideoWriter(
            tmp_path / "odd.mp4",
            width=width,
            height=height,
            fps=Fraction(25),
            encoding=VideoEncoding(pix_fmt="yuv420p"),
        )


def test_even_size_keeps_420_without_notice(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    writer = VideoWriter(tmp_path / "even.mp4", width=176, height=144, fps=Fraction(25))
    assert writer.encoding.pix_fmt == "yuv420p"
    assert not caplog.records


@pytest.mark.parametrize(
    ("codec", "pix_fmt", "written"),
    [
        ("libx264", "yuv422p", "yuv422p"),
        ("libx265", None, "yuv420p"),
        ("ffv1", None, "bgr0"),
        ("ffv1", "yuv444p", "yuv444p"),
        ("libvpx-vp9", None, "yuv420p"),
    ],
)
def test_pix_fmt_choice_reaches_the_stream(tmp_path: Path, codec: str, pix_fmt: str | None, written: str) -> None:
    path = tmp_path / "clip.mkv"
    _write(path, _gradient_frames(2), codec=codec, pix_fmt=pix_fmt)
    with av.open(str(path)) as container:
        assert container.streams.video[0].codec_context.pix_fmt == written


# glibc's mallopt parameter that fills every block malloc returns with the complement of the given byte.
_M_PERTURB = -6


@pytest.mark.parametrize("perturb_byte", [1, 85])
def test_a_two_frame_x265_clip_gets_its_own_timestamps_whatever_the_heap_held(
    tmp_path: Path, perturb_byte: int
) -> None:
    # x265 gives the packets of a clip of at most 2 frames decoding times offset by a field it never initialises, so
    # they depend on what the heap held before (the flaky EINVAL of test_pix_fmt_choice_reaches_the_stream in full
    # runs). Filling new heap blocks with a known byte makes that deterministic: 0xFE... put the decoding time past
    # the presentation time (EINVAL), 0xAA... overflowed it when rescaled to the container's time base.
    mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    if mallopt is None or mallopt(_M_PERTURB, perturb_byte) != 1:
        pytest.skip("needs glibc's malloc perturbation (mallopt M_PERTURB)")
    path = tmp_path / "clip.mkv"
    try:
        _write(path, _gradient_frames(2), codec="libx265")
    finally:
        mallopt(_M_PERTURB, 0)
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        assert [packet.pts for packet in container.demux(stream) if packet.size] == [0, 40]  # 1/1000 s at 25 fps


def test_full_range_yuvj_format_is_refused_naming_its_replacement(tmp_path: Path) -> None:
    with pytest.raises(DarksynthError, match=r"yuvj420p is FFmpeg's deprecated full-range format; use yuv420p$"):
        VideoWriter(
            tmp_path / "clip.mp4", width=16, height=16, fps=Fraction(25), encoding=VideoEncoding(pix_fmt="yuvj420p")
        )


def _noisy_frames(count: int) -> tuple[np.ndarray, list[np.ndarray]]:
    rng = np.random.default_rng(7)
    base = _gradient_frames(1, height=72, width=96)[0].astype(float) * 0.2
    return base, [np.clip(base + rng.normal(0, 4, base.shape), 0, 255).round().astype(np.uint8) for _ in range(count)]


def _luma_chroma(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BT.709 luma and the blue-difference chroma (Cb) of RGB values (any scale, last axis the channels)."""
    luma = rgb @ np.array([0.2126, 0.7152, 0.0722])
    return luma, (rgb[..., 2] - luma) / 1.8556


def test_noise_survives_yuv444p(tmp_path: Path) -> None:
    # With full-resolution chroma, a low CRF and tune=grain, fine per-pixel noise is not smoothed away.
    base, frames = _noisy_frames(8)
    path = tmp_path / "noisy.mp4"
    _write(path, frames, pix_fmt="yuv444p")
    back = np.stack(list(iter_video_frames(path))).astype(float)
    noise_in = np.std(np.stack(frames) - base)
    noise_out = np.std(back - base)
    assert 0.9 * noise_in < noise_out < 1.2 * noise_in


def test_default_420_keeps_luma_noise_and_averages_chroma_noise(tmp_path: Path) -> None:
    base, frames = _noisy_frames(8)
    path = tmp_path / "noisy.mp4"
    _write(path, frames)
    back = np.stack(list(iter_video_frames(path))).astype(float)
    luma_in, chroma_in = _luma_chroma(np.stack(frames) - base)
    luma_out, chroma_out = _luma_chroma(back - base)
    assert 0.9 * luma_in.std() < luma_out.std() < 1.2 * luma_in.std()
    # One chroma sample per 2x2 pixels: independent chroma noise keeps about half its std (the mean of four), a
    # little less once the encoder has quantized it (0.39 here).
    assert 0.25 * chroma_in.std() < chroma_out.std() < 0.6 * chroma_in.std()


def test_frames_are_streamed(tmp_path: Path) -> None:
    path = tmp_path / "long.mkv"
    frame = _gradient_frames(1, height=120, width=160)[0]
    with VideoWriter(path, width=160, height=120, fps=Fraction(25), encoding=VideoEncoding(codec="ffv1")) as writer:
        for _ in range(60):
            writer.write(frame)
    tracemalloc.start()
    try:
        count = 0
        for decoded in iter_video_frames(path):
            count += 1
            del decoded
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert count == 60
    assert peak < 10 * frame.nbytes  # 60 frames kept would be 60 * frame.nbytes


def test_display_rotation_is_applied(tmp_path: Path) -> None:
    frame = _gradient_frames(1)[0]
    path = tmp_path / "portrait.mp4"
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264rgb", rate=25)
        stream.width, stream.height, stream.pix_fmt = 64, 48, "rgb24"
        stream.options = {"crf": "0"}
        stream.set_display_rotation(-90)  # stored landscape, shown turned 90 degrees clockwise
        for i in range(2):
            video_frame = av.VideoFrame.from_ndarray(frame, format="rgb24")
            video_frame.pts = i
            container.mux(stream.encode(video_frame))
        container.mux(stream.encode(None))
    info = probe_video(path)
    assert (info.width, info.height) == (48, 64)
    back = list(iter_video_frames(path))
    np.testing.assert_array_equal(back[0], np.rot90(frame, k=-1))


def test_exception_inside_writer_leaves_nothing(tmp_path: Path) -> None:
    path = tmp_path / "out" / "clip.mp4"
    with pytest.raises(RuntimeError, match="stop"), VideoWriter(path, width=64, height=48, fps=Fraction(25)) as w:
        for frame in _gradient_frames(3):
            w.write(frame)
        raise RuntimeError("stop")
    assert list(path.parent.iterdir()) == []


def test_exception_keeps_an_existing_output(tmp_path: Path) -> None:
    path = tmp_path / "clip.mp4"
    path.write_bytes(b"previous run")
    with pytest.raises(KeyboardInterrupt), VideoWriter(path, width=64, height=48, fps=Fraction(25)) as writer:
        writer.write(_gradient_frames(1)[0])
        raise KeyboardInterrupt
    assert path.read_bytes() == b"previous run"
    assert [p.name for p in tmp_path.iterdir()] == ["clip.mp4"]


def test_no_frames_written_leaves_nothing(tmp_path: Path) -> None:
    path = tmp_path / "empty.mp4"
    with (
        pytest.raises(DarksynthError, match="no frames were written"),
        VideoWriter(path, width=64, height=48, fps=Fraction(25)),
    ):
        pass
    assert list(tmp_path.iterdir()) == []


def test_wrong_frame_shape_is_a_programming_error(tmp_path: Path) -> None:
    with (
        pytest.raises(ValueError, match=r"\(48, 64, 3\) uint8"),
        VideoWriter(tmp_path / "a.mp4", width=64, height=48, fps=Fraction(25)) as writer,
    ):
        writer.write(np.zeros((48, 64, 3), dtype=np.float32))
    assert list(tmp_path.iterdir()) == []


STREAM = frozenset({"width", "height", "fps"})
"""The writer's arguments that describe the stream; the others of the table below are its encoding's."""


@pytest.mark.parametrize(
    ("name", "kwargs", "message"),
    [
        ("a.mov", {"codec": "ffv1"}, r"a\.mov: the \.mov container cannot hold ffv1 video"),
        ("a.mp4", {"codec": "nosuchcodec"}, "unknown video codec 'nosuchcodec'"),
        ("a.mp4", {"codec": "aac"}, "aac is not a video codec"),
        ("a.webm", {}, "not a video suffix"),
        ("a.mkv", {"codec": "ffv1", "crf": 10}, "ffv1 has no CRF setting"),
        ("a.mp4", {"pix_fmt": "yuv9000p"}, r"a\.mp4: libx264 cannot encode pixel format 'yuv9000p' \(choices: gray "),
        ("a.mp4", {"codec": "libx264rgb", "pix_fmt": "yuv420p"}, r"choices: bgr0 bgr24 rgb24\)$"),
        ("a.avi", {"codec": "mpeg4", "width": 0}, "size must be positive"),
        ("a.mp4", {"codec": "libx264", "crf": 99}, r"a\.mp4: CRF for libx264 must be in 0\.\.51, got 99"),
        (
            "a.mkv",
            {"codec": "mpeg2video", "fps": Fraction(13)},
            r"a\.mkv: cannot encode 64x48 at 13 fps with mpeg2video",
        ),
    ],
)
def test_unusable_settings_raise_one_line_errors(
    tmp_path: Path, name: str, kwargs: dict[str, object], message: str
) -> None:
    stream = {"width": 64, "height": 48, "fps": Fraction(25)} | {k: v for k, v in kwargs.items() if k in STREAM}
    encoding = VideoEncoding(**{k: v for k, v in kwargs.items() if k not in STREAM})  # type: ignore[arg-type]
    with (
        pytest.raises(DarksynthError, match=message) as info,
        VideoWriter(tmp_path / name, encoding=encoding, **stream) as writer,  # type: ignore[arg-type]
    ):
        writer.write(_gradient_frames(1)[0])
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_write_outside_with_block_raises(tmp_path: Path) -> None:
    writer = VideoWriter(tmp_path / "a.mp4", width=64, height=48, fps=Fraction(25))
    with pytest.raises(RuntimeError, match="outside its with block"):
        writer.write(_gradient_frames(1)[0])


def test_default_codec_is_libx264() -> None:
    assert DEFAULT_CODEC == "libx264"


def test_codec_names_resolve_to_the_encoder(tmp_path: Path) -> None:
    writer = VideoWriter(
        tmp_path / "a.mp4", width=64, height=48, fps=Fraction(25), encoding=VideoEncoding(codec="h264")
    )
    assert writer.encoding == VideoEncoding(codec="libx264", crf=DEFAULT_CRF, pix_fmt="yuv420p")


# --- bad inputs --------------------------------------------------------------------------------------------------


def test_missing_video(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="no such file"):
        probe_video(tmp_path / "missing.mp4")
    with pytest.raises(InputFileError, match="no such file"):
        next(iter_video_frames(tmp_path / "missing.mp4"))


def test_garbage_mp4(tmp_path: Path) -> None:
    path = tmp_path / "garbage.mp4"
    path.write_bytes(np.random.default_rng(3).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(InputFileError, match="not a readable video") as info:
        probe_video(path)
    assert info.value.path == path
    # FFmpeg's readable reason only: no "[Errno 1094995529]", no second copy of the path.
    assert info.value.problem == "not a readable video (Invalid data found when processing input)"
    assert str(info.value).count(path.name) == 1
    with pytest.raises(InputFileError, match="not a readable video"):
        list(iter_video_frames(path))


def test_truncated_mp4(tmp_path: Path) -> None:
    path = tmp_path / "cut.mp4"
    _write(path, _gradient_frames(10))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputFileError) as info:
        probe_video(path)
    assert info.value.path == path
    with pytest.raises(InputFileError):
        list(iter_video_frames(path))


def test_a_tag_that_is_not_utf8_does_not_stop_the_read(tmp_path: Path) -> None:
    # Found by tests/test_fuzz.py: a flipped byte in the MP4 brand raised UnicodeDecodeError on opening.
    path = tmp_path / "brand.mp4"
    _write(path, _gradient_frames(3))
    data = bytearray(path.read_bytes())
    assert data[4:12] == b"ftypisom"
    data[8] = 0x80
    path.write_bytes(bytes(data))
    info = probe_video(path)
    assert (info.width, info.height) == (64, 48)
    assert len(list(iter_video_frames(path))) == 3


def test_file_without_video_stream(tmp_path: Path) -> None:
    path = tmp_path / "sound.mkv"
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("pcm_s16le", rate=8000)
        frame = av.AudioFrame.from_ndarray(np.zeros((1, 800), dtype=np.int16), format="s16", layout="mono")
        frame.sample_rate = 8000
        container.mux(stream.encode(frame))
        container.mux(stream.encode(None))
    with pytest.raises(InputFileError, match="no video stream"):
        probe_video(path)
    with pytest.raises(InputFileError, match="no video stream"):
        list(iter_video_frames(path))


def test_corrupt_frames_mid_stream_name_the_frame(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "clip.mkv"
    _write(path, _gradient_frames(5), codec="ffv1")
    real_decode = av.container.InputContainer.decode

    def failing_decode(self: av.container.InputContainer, *args: object, **kwargs: object) -> object:
        for index, frame in enumerate(real_decode(self, *args, **kwargs)):  # type: ignore[arg-type]
            if index == 3:
                raise av.InvalidDataError(1094995529, "Invalid data found when processing input")
            yield frame

    monkeypatch.setattr(av.container.InputContainer, "decode", failing_decode)
    frames = iter_video_frames(path)
    assert len([next(frames) for _ in range(3)]) == 3
    with pytest.raises(InputFileError, match="cannot decode video frame 3") as info:
        next(frames)
    assert info.value.path == path
    assert info.value.problem == "cannot decode video frame 3 (Invalid data found when processing input)"


# --- audio carried over ------------------------------------------------------------------------------------------


def test_audio_is_interleaved_as_frames_are_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Streaming: each frame's audio goes in with it, none read ahead, so memory does not grow with the length (the
    # muxer's own interleaving would hide a writer that kept all the audio for the end in a file this short).
    source = video_with_audio(tmp_path / "clean.mov", ("pcm_s16le",), frames=50, audio_seconds=2.0)
    muxed: list[tuple[str, int]] = []
    real_mux = av.container.OutputContainer.mux

    def spying_mux(self: av.container.OutputContainer, packets: object) -> None:
        for packet in packets if isinstance(packets, list) else [packets]:  # type: ignore[attr-defined]
            muxed.append((packet.stream.type, packet.pts))
        real_mux(self, packets)  # type: ignore[arg-type]

    monkeypatch.setattr(av.container.OutputContainer, "mux", spying_mux)
    fps = Fraction(25)
    with VideoWriter(
        tmp_path / "out.mkv", width=48, height=32, fps=fps, encoding=VideoEncoding(codec="ffv1"), audio_from=source
    ) as writer:
        for index in range(50):
            writer.write(np.zeros((32, 48, 3), np.uint8))
            audio_end = max((pts for kind, pts in muxed if kind == "audio"), default=-1) / 8000  # pcm at 8 kHz
            # The audio that went in starts before the end of the frame just written, and reaches close to it.
            assert (index + 1) / fps - 0.2 < audio_end < (index + 1) / fps
    assert writer.audio_codecs == ("pcm_s16le",)
    assert audio_packets(tmp_path / "out.mkv") == audio_packets(source)
