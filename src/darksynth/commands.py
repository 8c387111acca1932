"""The command line's shape: the app's settings, every command's summary and ``--version``, without the commands.

Both the full command line (:mod:`darksynth.cli`) and the entry point's light app (:mod:`darksynth.main`), which
answers ``--version`` and ``--help`` without importing torch, are built from this, so their help is one text.
"""

from __future__ import annotations

from typing import Annotated

import typer

from darksynth.version import __version__

APP_HELP = "Realistic synthetic low-light images and videos from clean ones."

COMMAND_HELP: dict[str, str] = {
    "apply": "Make low-light versions of clean images, videos or folders with a noise profile.",
    "convert": "Convert a whole annotated dataset to low light; annotations carried over, resumable, shardable.",
    "train": "Train the DEN self-supervised on clean material: random crops, darkening, random v, f(v).",
    "estimate": "Estimate a noise profile from one real low-light reference, zero-shot.",
    "evaluate": "Compare each method's synthetic noise with real noise on sets of real pairs.",
    "demo": "Run the whole job on the shipped sample: low-light image, clip and a side-by-side preview.",
}
"""Every command's one-line summary, in the order the help lists them."""


def new_app() -> typer.Typer:
    """A darksynth app with its settings and the root's ``--version``, and no command yet."""
    app = typer.Typer(
        name="darksynth", help=APP_HELP, no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False
    )

    @app.callback()
    def root(
        version: Annotated[
            bool, typer.Option("--version", help="Print the version and exit.", callback=_print_version, is_eager=True)
        ] = False,
    ) -> None:
        del version

    return app


def _print_version(version: bool) -> None:
    # Eager: it answers before any command is looked at.
    if version:
        typer.echo(f"darksynth {__version__}")
        raise typer.Exit()
