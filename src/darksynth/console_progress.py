"""Progress of a long command on stderr: a live bar on a terminal, a dated line now and then in a log, or nothing.

A bar redrawn in place is useless in a batch job's log (rich draws nothing when stderr is not a terminal), and a
line per file would flood the log of a 100 000-image dataset; so without a terminal a plain line is printed at most
every :data:`LOG_INTERVAL` seconds. ``quiet`` drops progress (and the commands drop their summary lines), never
warnings or errors: messages passed to :meth:`ProgressDisplay.say` always go out.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

__all__ = ["LOG_INTERVAL", "ProgressDisplay", "progress_display"]

LOG_INTERVAL = 10.0
"""Seconds between two progress lines when stderr is not a terminal."""


class ProgressDisplay(Protocol):
    """What a command tells its user while it runs."""

    def update(self, *, completed: float | None = None, total: float | None = None, description: str = "") -> None:
        """Set the work done and the total (None: unknown), and what is being done."""

    def advance(self, amount: float = 1) -> None:
        """Count ``amount`` more units of work done."""

    def say(self, message: str) -> None:
        """Print one line (a warning, an error) without garbling the display; never suppressed."""


class _Silent:
    """No progress, only the messages; the other displays add their progress to it."""

    def __init__(self, console: Console) -> None:
        self._console = console

    def update(self, *, completed: float | None = None, total: float | None = None, description: str = "") -> None:
        del completed, total, description

    def advance(self, amount: float = 1) -> None:
        del amount

    def say(self, message: str) -> None:
        # No markup, no highlighting, no wrapping: an error stays one line whatever it quotes.
        self._console.print(message, markup=False, highlight=False, soft_wrap=True)


class _RichBar(_Silent):
    def __init__(self, progress: Progress, label: str) -> None:
        super().__init__(progress.console)
        self._progress = progress
        self._bar = progress.add_task(label, total=None)

    def update(self, *, completed: float | None = None, total: float | None = None, description: str = "") -> None:
        self._progress.update(self._bar, completed=completed, total=total, description=description or None)

    def advance(self, amount: float = 1) -> None:
        self._progress.advance(self._bar, amount)


class _LogLines(_Silent):
    """Plain lines, at most one per ``interval`` seconds: ``apply: 120/400 frames (30%), 1m05s, about 2m32s left``."""

    def __init__(self, console: Console, label: str, unit: str, interval: float) -> None:
        super().__init__(console)
        self._label, self._unit, self._interval = label, unit, interval
        self._started = self._last = time.monotonic()
        self._completed = 0.0
        self._total: float | None = None
        self._description = ""

    def update(self, *, completed: float | None = None, total: float | None = None, description: str = "") -> None:
        if completed is not None:
            self._completed = completed
        if total is not None:
            self._total = total
        if description:
            self._description = description
        self._maybe_report()

    def advance(self, amount: float = 1) -> None:
        self._completed += amount
        self._maybe_report()

    def _maybe_report(self) -> None:
        now = time.monotonic()
        if now - self._last < self._interval:
            return
        self._last = now
        elapsed = now - self._started
        parts = [f"{self._label}:"]
        if self._description:
            parts.append(self._description)
        if self._total:
            parts.append(
                f"{self._completed:g}/{self._total:g} {self._unit} ({100 * self._completed / self._total:.0f}%),"
            )
        elif self._completed:
            parts.append(f"{self._completed:g} {self._unit},")
        parts.append(_duration(elapsed))
        if self._total and self._completed:
            left = elapsed * (self._total - self._completed) / self._completed
            parts[-1] += f", about {_duration(left)} left"
        self.say(" ".join(parts))


@contextmanager
def progress_display(
    console: Console, label: str, *, unit: str = "", quiet: bool = False, interval: float | None = None
) -> Iterator[ProgressDisplay]:
    """A progress display for one command run.

    Args:
        console: the stderr console.
        label: the command's name, at the start of each log line and as the bar's first description.
        unit: what is counted (``"frames"``, ``"files"``, ``"steps"``), for the log lines.
        quiet: no progress at all (messages still print).
        interval: seconds between log lines (default :data:`LOG_INTERVAL`).
    """
    if quiet:
        yield _Silent(console)
    elif console.is_terminal:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
        with Progress(*columns, console=console, transient=True) as progress:
            yield _RichBar(progress, label)
    else:
        yield _LogLines(console, label, unit, LOG_INTERVAL if interval is None else interval)


def _duration(seconds: float) -> str:
    minutes, rest = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    if hours:
        return f"{hours}h{minutes:02d}m"
    return f"{minutes}m{rest:02d}s" if minutes else f"{rest}s"
