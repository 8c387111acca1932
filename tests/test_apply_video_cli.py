"""``darksynth apply`` on videos: what the output keeps of the input besides its frames, and its messages."""

from __future__ import annotations

from pathlib import Path

from tests.command_line import run_cli


def test_unreadable_video_gives_ffmpegs_reason_once(tmp_path: Path, profile_file: Path) -> None:
    source = tmp_path / "movie.mp4"
    source.write_bytes(b"\x00" * 1000)
    code, _, err = run_cli("apply", source, tmp_path / "out.mp4", "-p", profile_file)
    assert code == 1
    # Not "[Errno 1094995529] Invalid data found when processing input: '.../movie.mp4'".
    assert err.strip() == f"darksynth: error: {source}: not a readable video (Invalid data found when processing input)"
