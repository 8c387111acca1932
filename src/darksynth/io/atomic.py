"""Atomic file output: a result appears at its final path complete, or not at all."""

from __future__ import annotations

import contextlib
import os
import re
import secrets
from collections.abc import Iterable, Iterator
from pathlib import Path

__all__ = ["atomic_output", "remove_stale_temps", "temp_path_for", "write_text_atomic"]

TEMP_MARKER = ".tmp-"
_TEMP_NAME = re.compile(r"^\.(?P<stem>.*)" + re.escape(TEMP_MARKER) + r"[0-9a-f]{12}(?P<suffix>.*)$")


def temp_path_for(dest: Path) -> Path:
    """Return a fresh hidden temporary path next to ``dest``.

    The name is ``.STEM.tmp-RANDOM.SUFFIX``: hidden, so folder scans skip it, in the same folder, so the final
    rename stays on one file system and is atomic, and with dest's suffix, so encoders that choose a format from
    the suffix (Pillow, FFmpeg muxers) pick the right one.

    Args:
        dest: The final path the temporary file stands in for.

    Returns:
        A path that does not exist yet (barring a 48-bit random collision).
    """
    return dest.parent / f".{dest.stem}{TEMP_MARKER}{secrets.token_hex(6)}{dest.suffix}"


@contextlib.contextmanager
def atomic_output(dest: Path) -> Iterator[Path]:
    """Give a temporary path to write to, and move it to ``dest`` only if the block finishes without an error.

    Parent folders of ``dest`` are created. On normal exit the temporary file is flushed to disk and renamed over
    ``dest`` with :func:`os.replace`, so readers (and a run interrupted at any moment, even by a power cut) see
    either the old ``dest`` or the complete new one, never a half-written file. On any exception, including
    ``KeyboardInterrupt``, the temporary file is removed and the exception propagates.

    The temporary file is not created in advance: the writer creates it, with the usual permissions.

    Args:
        dest: Final path of the output.

    Yields:
        The temporary path to write the output to.
    """
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path_for(dest)
    try:
        yield tmp
        _fsync_file(tmp)
        os.replace(tmp, dest)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def remove_stale_temps(outputs: Iterable[Path]) -> int:
    """Remove the temporary files that a killed run left for any of ``outputs``; return how many.

    A run killed with SIGKILL (or by a power cut) cannot remove its temporary file; the next run that writes the
    same output removes it. Only temporaries of the given outputs are touched, so that a run writing other files
    into the same folder keeps its own.
    """
    by_folder: dict[Path, set[str]] = {}
    for output in outputs:
        by_folder.setdefault(output.parent, set()).add(output.name)
    removed = 0
    for folder, names in by_folder.items():
        try:
            entries = list(os.scandir(folder))
        except OSError:  # the folder does not exist yet: nothing was left in it
            continue
        for entry in entries:
            match = _TEMP_NAME.match(entry.name)
            if match is not None and match["stem"] + match["suffix"] in names:
                Path(entry.path).unlink(missing_ok=True)
                removed += 1
    return removed


def write_text_atomic(dest: Path, text: str) -> None:
    """Write ``text`` to ``dest`` as UTF-8, atomically (see :func:`atomic_output`).

    Args:
        dest: Path of the text file; parent folders are created.
        text: The whole content of the file.
    """
    with atomic_output(dest) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _fsync_file(path: Path) -> None:
    # Without this a crash shortly after the rename can leave dest pointing at blocks never written to disk.
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
