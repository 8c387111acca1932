"""The command line: the only place that parses arguments and wires objects together."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any

from darksynth.cli.den_commands import estimate_command, train_command
from darksynth.cli.evaluate import evaluate_command
from darksynth.cli.synthesis import apply_command, convert_command, demo_command, preview_command
from darksynth.commands import COMMAND_HELP, new_app

__all__ = ["app", "main"]

COMMANDS: dict[str, Callable[..., Any]] = {
    "apply": apply_command,
    "convert": convert_command,
    "train": train_command,
    "estimate": estimate_command,
    "preview": preview_command,
    "evaluate": evaluate_command,
    "demo": demo_command,
}
"""Every command's function, by name; registered in the order of :data:`darksynth.commands.COMMAND_HELP`, the
order of the help and of the entry point's light app."""

app = new_app()
for name, summary in COMMAND_HELP.items():
    app.command(name, help=summary)(COMMANDS[name])


def main(argv: Sequence[str] | None = None) -> None:
    """Run a command (``argv``: the arguments after the program name; sys.argv's by default). The console
    script enters through :func:`darksynth.main.main`, which answers ``--version`` and ``--help`` without this
    module."""
    app(list(sys.argv[1:] if argv is None else argv), prog_name="darksynth")
