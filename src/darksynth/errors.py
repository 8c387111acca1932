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
