"""The console entry point: ``--version`` and the top-level help without importing torch.

Every command needs torch, and importing it takes 2-4 s, longer than any answer about the tool itself should. A
call that runs no command (``darksynth``, ``darksynth --help``, ``darksynth --version``) is answered here by a
typer app that has the commands' names and summaries but not their code, so its help is the same as the full
one's; any other call loads :mod:`darksynth.cli` and runs it. Both apps are built by :mod:`darksynth.commands`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import typer

from darksynth.commands import COMMAND_HELP, new_app

ROOT_ONLY = frozenset({"--help", "--version"})
"""Arguments answered without loading the commands (as is no argument at all)."""


def _light_app() -> typer.Typer:
    app = new_app()
    for name, summary in COMMAND_HELP.items():
        app.command(name, help=summary)(lambda: None)
    return app


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    if set(arguments) <= ROOT_ONLY:
        _light_app()(arguments, prog_name="darksynth")
        return
    from darksynth.cli import main as run_command

    run_command(arguments)
