"""A folder ``apply`` with worker processes: killing the parent with SIGKILL takes its workers down too."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from darksynth.profile import default_profile_path


def _children(pid: int) -> set[int]:
    children = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                children.add(int(entry.name))
    return children


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited; only its parent's wait is missing


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc (Linux)")
def test_workers_end_soon_after_the_parent_is_killed(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for index in range(24):
        Image.fromarray(rng.integers(0, 256, (720, 960, 3), dtype=np.uint8)).save(folder / f"{index:02d}.png")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "darksynth", "apply", str(folder), str(out), "-p", str(default_profile_path())]
    parent = subprocess.Popen([*command, "--workers", "2", "--seed", "0"], stderr=subprocess.DEVNULL)
    workers: set[int] = set()
    try:
        deadline = time.monotonic() + 120
        # Kill once the workers are busy: the first file has appeared.
        while not any(out.glob("*.png")) and time.monotonic() < deadline and parent.poll() is None:
            time.sleep(0.05)
        assert parent.poll() is None, "the run ended before it could be killed: give it more work"
        workers = _children(parent.pid)
        assert len(workers) >= 2, workers
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        killed = time.monotonic()
        while any(_alive(pid) for pid in workers) and time.monotonic() - killed < 10:
            time.sleep(0.1)
        survivors = [pid for pid in workers if _alive(pid)]
        assert not survivors, f"{len(survivors)} worker(s) still running {time.monotonic() - killed:.1f} s after"
        assert time.monotonic() - killed < 5
    finally:
        # Re-parented survivors are no longer the parent's children: kill them by the pids seen before.
        for pid in workers | _children(parent.pid) | ({parent.pid} if parent.poll() is None else set()):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
