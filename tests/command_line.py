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


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    """The run failed with exit 1 and one line ``darksynth: error: ...`` that holds every needle."""
    assert code == 1, err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("darksynth: error:"), err
    for needle in needles:
        assert needle in lines[0], (needle, err)
