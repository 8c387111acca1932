"""Progress without a terminal: dated lines at most every interval, none with --quiet; errors always printed."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from rich.console import Console

import darksynth.console_progress
from darksynth.console_progress import progress_display
from tests.command_line import run_cli


def _log_console() -> tuple[Console, io.StringIO]:
    buffer = io.StringIO()
    return Console(file=buffer, force_terminal=False, width=200), buffer


def test_log_lines_give_count_share_and_time_left() -> None:
    console, buffer = _log_console()
    with progress_display(console, "apply", unit="frames", interval=0.0) as display:
        display.update(total=40, description="4 file(s)")
        display.advance(10)
    lines = buffer.getvalue().splitlines()
    assert lines[-1].startswith("apply: 4 file(s) 10/40 frames (25%), ")
    assert "left" in lines[-1]


def test_log_lines_wait_for_the_interval() -> None:
    console, buffer = _log_console()
    with progress_display(console, "convert", unit="files", interval=3600.0) as display:
        for done in range(100):
            display.update(completed=done, total=100)
        display.say("darksynth: error: x.png: broken")
    # No progress line within the hour; the message is never held back.
    assert buffer.getvalue().splitlines() == ["darksynth: error: x.png: broken"]


def test_quiet_prints_messages_only() -> None:
    console, buffer = _log_console()
    with progress_display(console, "train", unit="steps", quiet=True, interval=0.0) as display:
        display.update(completed=5, total=10)
        display.say("darksynth: warning: w")
    assert buffer.getvalue().splitlines() == ["darksynth: warning: w"]


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    root = tmp_path / "in"
    root.mkdir()
    for index in range(3):
        Image.fromarray(np.full((16, 16, 3), 40 * index, np.uint8)).save(root / f"{index}.png")
    (root / "broken.png").write_bytes(b"not a png")
    return root


def test_apply_reports_progress_in_a_log(
    monkeypatch: pytest.MonkeyPatch, folder: Path, profile_file: Path, tmp_path: Path
) -> None:
    monkeypatch.setattr(darksynth.console_progress, "LOG_INTERVAL", 0.0)
    code, _, err = run_cli("apply", folder, tmp_path / "out", "-p", profile_file, "--seed", "1")
    assert code == 1  # the broken file
    progress = [line for line in err.splitlines() if line.startswith("apply: ")]
    assert progress and progress[-1].startswith("apply: 4 file(s) 3/4 frames (75%)"), err


def test_apply_quiet_keeps_only_the_errors(
    monkeypatch: pytest.MonkeyPatch, folder: Path, profile_file: Path, tmp_path: Path
) -> None:
    monkeypatch.setattr(darksynth.console_progress, "LOG_INTERVAL", 0.0)
    code, out, err = run_cli("apply", folder, tmp_path / "out", "-p", profile_file, "--seed", "1", "--quiet")
    assert code == 1
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 2 and all(line.startswith("darksynth: error: ") for line in lines), err
    assert "broken.png" in lines[0]
    assert len(list((tmp_path / "out").glob("*.png"))) == 3
