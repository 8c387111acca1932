"""The darksynth command line run in-process, as the tests of every command use it."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from darksynth.cli import app


def run_cli(*args: str | Path) -> tuple[int, str, str]:
    """Invoke the CLI in-process; returns (exit code, stdout, stderr)."""
    result = CliRunner().invoke(app, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr
