"""What every command shares: the console and its one-line messages, the options' defaults read from the job's
options and their values given back to them, and the checks of choices and of the darkening flags."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from typing import Annotated, Any, get_args

import typer
from rich.console import Console

from darksynth.errors import DarksynthError
from darksynth.light.darkening import Darkening
from darksynth.models.den import Variant
from darksynth.recipe import DarkeningChoice

console = Console(stderr=True)


def say(message: str) -> None:
    """Print a message as is: no markup, no highlighting, never wrapped, so that an error stays one line."""
    console.print(message, markup=False, highlight=False, soft_wrap=True)


class WarningLines(logging.Handler):
    """The library's logged warnings as the command line's own lines, ``darksynth: warning: ...`` on stderr
    (through the console, so that they print above a progress bar instead of through it)."""

    def emit(self, record: logging.LogRecord) -> None:
        kind = "error" if record.levelno >= logging.ERROR else "warning"
        say(f"darksynth: {kind}: {' '.join(record.getMessage().split())}")


_library_logger = logging.getLogger("darksynth")
if not any(isinstance(handler, WarningLines) for handler in _library_logger.handlers):
    _library_logger.addHandler(WarningLines(logging.WARNING))


def fail(message: str) -> typer.Exit:
    """Print a one-line error and return the exit to raise."""
    say(f"darksynth: error: {message}")
    return typer.Exit(code=1)


def default_of(options: type[Any], name: str) -> Any:
    """The default of a field of a job's options dataclass: the command line writes no default of its own."""
    for option in dataclasses.fields(options):
        if option.name == name:
            if option.default is not dataclasses.MISSING:
                return option.default
            if option.default_factory is not dataclasses.MISSING:
                return option.default_factory()
            raise TypeError(f"{options.__name__}.{name} has no default")
    raise TypeError(f"{options.__name__} has no field {name!r}")


def checked_choice(flag: str, value: str, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``, else a one-line error naming the flag."""
    if value not in choices:
        allowed = " or ".join(choices) if len(choices) == 2 else f"one of {', '.join(choices)}"
        raise DarksynthError(f"{flag} must be {allowed}, got {value!r}")
    return value


VARIANTS: tuple[str, ...] = get_args(Variant)


def darkening_choice(alpha: float | None, gamma: float | None, no_darken: bool) -> DarkeningChoice:
    """Turn the darkening flags into a choice, rejecting contradictory ones."""
    if no_darken:
        if alpha is not None or gamma is not None:
            raise DarksynthError("--no-darken cannot be combined with --alpha or --gamma")
        return None
    if (alpha is None) != (gamma is None):
        raise DarksynthError("--alpha and --gamma must be given together")
    if alpha is None or gamma is None:
        return "profile"
    if not 0.0 < alpha <= 1.0:
        raise DarksynthError(f"--alpha must lie in (0, 1], got {alpha}")
    if not 0.0 < gamma <= 10.0:
        raise DarksynthError(f"--gamma must lie in (0, 10], got {gamma}")
    return Darkening(alpha=alpha, gamma=gamma)


QuietOption = Annotated[
    bool, typer.Option("--quiet", "-q", help="No progress and no summary; warnings and errors are still printed.")
]
