"""Errors that the command line reports as one line and a non-zero exit, never as a traceback."""

from __future__ import annotations

from pathlib import Path


class DarksynthError(Exception):
    """A problem with the user's input: a file, a profile or an argument.

    The message is complete on its own, names the file or field at fault and fits on one line.
    """


class InputFileError(DarksynthError):
    """A file that cannot be read as what it claims to be (corrupt, truncated, unsupported)."""

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


class ProfileError(DarksynthError):
    """A noise profile that is missing a field, has an invalid value or an unknown version."""


def error_reason(error: BaseException) -> str:
    """The readable reason of an OS or FFmpeg error, for the end of a message that already names the file.

    ``str()`` of an ``OSError`` or of PyAV's ``av.FFmpegError`` reads ``[Errno 1094995529] Invalid data found when
    processing input: 'in.mp4'``: FFmpeg's error numbers are four-character tags that mean nothing to a user, and
    the path would be said twice. This is the ``strerror`` part alone, or ``str(error)`` for other errors.
    """
    strerror = getattr(error, "strerror", None)
    return strerror if isinstance(strerror, str) and strerror else str(error)
