"""``darksynth apply`` and ``convert`` on videos: the encoding of the output, what it keeps of the input besides its
frames, and the messages."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
import pytest

from darksynth.io.video import VideoEncoding, VideoWriter
from tests.command_line import run_cli
from tests.videos_with_audio import audio_packets, video_with_audio


def _clean_video(path: Path, frames: int = 6, width: int = 48, height: int = 32) -> Path:
    with VideoWriter(
        path, width=width, height=height, fps=Fraction(25), encoding=VideoEncoding(codec="ffv1")
    ) as writer:
        for index in range(frames):
            writer.write(np.full((height, width, 3), 40 + 20 * index, np.uint8))
    return path


def _pix_fmt(path: Path) -> str | None:
    with av.open(str(path)) as container:
        return container.streams.video[0].codec_context.pix_fmt


@pytest.mark.parametrize(
    ("flags", "written", "recorded"), [((), "yuv420p", None), (("--pix-fmt", "yuv444p"), "yuv444p", "yuv444p")]
)
def test_apply_pix_fmt_default_playable_and_recorded(
    tmp_path: Path, profile_file: Path, flags: tuple[str, ...], written: str, recorded: str | None
) -> None:
    source = _clean_video(tmp_path / "clean.mkv")
    out = tmp_path / "dark.mp4"
    code, _, err = run_cli("apply", source, out, "-p", profile_file, "--seed", "0", *flags)
    assert code == 0, err
    assert _pix_fmt(out) == written
    assert json.loads((tmp_path / "dark.mp4.manifest.json").read_text())["pix_fmt"] == recorded


def test_apply_bad_pix_fmt_is_one_line_naming_it_and_the_choices(tmp_path: Path, profile_file: Path) -> None:
    source = _clean_video(tmp_path / "clean.mkv")
    code, _, err = run_cli("apply", source, tmp_path / "dark.mp4", "-p", profile_file, "--pix-fmt", "yuv9000p")
    assert code == 1
    (line,) = err.strip().splitlines()
    assert line.startswith(f"darksynth: error: {tmp_path / 'dark.mp4'}: libx264 cannot encode pixel format 'yuv9000p'")
    assert "(choices: " in line and " yuv420p " in line and " yuv444p " in line
    assert not (tmp_path / "dark.mp4").exists()


@pytest.mark.parametrize("command", ["apply", "convert"])
def test_bad_video_options_are_refused_once_before_any_work(tmp_path: Path, profile_file: Path, command: str) -> None:
    """A folder of videos with a codec or pixel format the writer refuses: one line, not one per video."""
    dataset = tmp_path / "ds"
    for name in ("a.mkv", "b.mkv", "c.mkv"):
        _clean_video(dataset / "videos" / name)
    output = tmp_path / "out"
    extra = ("--format", "video-folder") if command == "convert" else ()
    for flags, said in ((("--pix-fmt", "yuv9000p"), "'yuv9000p'"), (("--codec", "nocodec"), "'nocodec'")):
        code, _, err = run_cli(command, dataset, output, "-p", profile_file, *extra, *flags)
        assert code == 1
        (line,) = err.strip().splitlines()
        assert line.startswith("darksynth: error: ") and said in line, line
        assert not output.exists()


def test_convert_records_pix_fmt_and_refuses_to_resume_with_another(tmp_path: Path, profile_file: Path) -> None:
    dataset = tmp_path / "ds"
    _clean_video(dataset / "videos" / "walk.mkv")
    output = tmp_path / "out"
    arguments = ("convert", dataset, output, "-p", profile_file, "--format", "video-folder")
    code, _, err = run_cli(*arguments, "--pix-fmt", "yuv444p")
    assert code == 0, err
    assert _pix_fmt(output / "videos" / "walk.mkv") == "yuv444p"
    assert json.loads((output / "darksynth-manifest.json").read_text())["pix_fmt"] == "yuv444p"
    code, _, err = run_cli(*arguments)
    assert code == 1 and "other options (pix_fmt)" in err


@pytest.mark.parametrize(
    ("source_name", "codecs", "out_name"),
    [
        ("clean.mp4", ("aac",), "dark.mp4"),
        ("clean.mov", ("aac", "pcm_s16le"), "dark.mp4"),
        ("clean.mp4", ("aac",), "dark.mov"),
    ],
)
def test_apply_copiesaudio_packets_unchanged(
    tmp_path: Path, profile_file: Path, source_name: str, codecs: tuple[str, ...], out_name: str
) -> None:
    source = video_with_audio(tmp_path / source_name, codecs)
    out = tmp_path / out_name
    code, _, err = run_cli("apply", source, out, "-p", profile_file, "--seed", "0")
    assert code == 0, err
    before, after = audio_packets(source), audio_packets(out)
    assert len(after) == len(codecs)
    for track_before, track_after in zip(before, after, strict=True):
        assert len(track_before) >= 10
        assert track_after == track_before  # the same bytes at the same times, all of it (it outlasts the video)
    with av.open(str(out)) as container:
        assert [s.codec_context.codec.canonical_name for s in container.streams.audio] == list(codecs)
        # Interleaved as written: audio packets lie between video packets in the file, not all after them.
        kinds = [p.stream.type for p in container.demux() if p.size]
    assert kinds.index("audio") < len(kinds) // 2
    assert sum(1 for p in kinds if p == "video") == 25


def test_audio_stays_in_sync_when_the_source_starts_late(tmp_path: Path, profile_file: Path) -> None:
    # Video and audio both begin 2 s in; the output's video begins at 0, so its audio must too.
    source = video_with_audio(tmp_path / "late.mkv", ("pcm_s16le",), start=2)
    out = tmp_path / "dark.mkv"
    code, _, err = run_cli("apply", source, out, "-p", profile_file, "--seed", "0", "--codec", "ffv1")
    assert code == 0, err
    (before,), (after,) = audio_packets(source), audio_packets(out)
    assert before[0][1] == 2 and after[0][1] == 0
    assert [p[0] for p in after] == [p[0] for p in before]
    assert [p[1] for p in after] == [p[1] - 2 for p in before]  # type: ignore[operator]


def test_audio_the_container_cannot_hold_is_left_out_with_one_notice(
    tmp_path: Path, profile_file: Path, caplog: pytest.LogCaptureFixture
) -> None:
    source = video_with_audio(tmp_path / "clean.mov", ("pcm_mulaw", "pcm_mulaw"))
    out = tmp_path / "dark.mkv"  # Matroska has no pcm_mulaw
    code, _, err = run_cli("apply", source, out, "-p", profile_file, "--seed", "0", "--codec", "ffv1")
    assert code == 0, err
    notices = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert notices == [
        f"{source}: 2 audio tracks (codec pcm_mulaw, pcm_mulaw) cannot go into .mkv; written without them"
    ]
    with av.open(str(out)) as container:
        assert not container.streams.audio
        assert sum(1 for _ in container.decode(video=0)) == 25


def test_tracks_that_are_not_carried_get_one_notice(
    tmp_path: Path, profile_file: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A second video track (another angle, a thumbnail stream) is not carried: one line says so."""
    source = tmp_path / "two.mkv"
    with av.open(str(source), "w") as container:
        streams = [container.add_stream("ffv1", rate=25) for _ in range(2)]
        for stream in streams:
            stream.width, stream.height, stream.pix_fmt = 16, 16, "bgr0"
        for index in range(3):
            frame = av.VideoFrame.from_ndarray(np.full((16, 16, 3), 50, np.uint8), format="rgb24").reformat(
                format="bgr0"
            )
            frame.pts = index
            for stream in streams:
                container.mux(stream.encode(frame))
        for stream in streams:
            container.mux(stream.encode(None))
    out = tmp_path / "dark.mkv"
    code, _, err = run_cli("apply", source, out, "-p", profile_file, "--seed", "0", "--codec", "ffv1")
    assert code == 0, err
    notices = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert notices == [f"{source}: 1 video track not carried into the output (only the first video and the audio are)"]
    with av.open(str(out)) as container:
        assert len(container.streams.video) == 1


def test_convert_carries_audio(tmp_path: Path, profile_file: Path) -> None:
    dataset = tmp_path / "ds"
    (dataset / "videos").mkdir(parents=True)
    source = video_with_audio(dataset / "videos" / "walk.mp4", ("aac",))
    output = tmp_path / "out"
    code, _, err = run_cli("convert", dataset, output, "-p", profile_file, "--format", "video-folder")
    assert code == 0, err
    assert audio_packets(output / "videos" / "walk.mp4") == audio_packets(source)


def test_unreadable_video_gives_ffmpegs_reason_once(tmp_path: Path, profile_file: Path) -> None:
    source = tmp_path / "movie.mp4"
    source.write_bytes(b"\x00" * 1000)
    code, _, err = run_cli("apply", source, tmp_path / "out.mp4", "-p", profile_file)
    assert code == 1
    # Not "[Errno 1094995529] Invalid data found when processing input: '.../movie.mp4'".
    assert err.strip() == f"darksynth: error: {source}: not a readable video (Invalid data found when processing input)"
