"""The command line's shape: the app's settings, every command's summary and ``--version``, without the commands.

Both the full command line (:mod:`darksynth.cli`) and the entry point's light app (:mod:`darksynth.main`), which
answers ``--version`` and ``--help`` without importing torch, are built from this, so their help is one text.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Annotated, Any

import typer
from typer.core import TyperGroup

try:  # typer 0.2x carries its own copy of click, whose exceptions its commands raise
    from typer._click import exceptions as click_errors
except ImportError:  # older typer runs on click itself
    from click import exceptions as click_errors  # type: ignore[no-redef]

from darksynth.version import __version__

APP_HELP = "Realistic synthetic low-light images and videos from clean ones."

COMMAND_HELP: dict[str, str] = {
    "apply": "Make low-light versions of clean images, videos or folders with a noise profile.",
    "convert": "Convert a whole annotated dataset to low light; annotations carried over, resumable, shardable.",
    "train": "Train the DEN self-supervised on clean material: random crops, darkening, random v, f(v).",
    "estimate": "Estimate a noise profile from one real low-light reference, zero-shot.",
    "preview": "Preview one image with a profile before converting: clean, darkened, noisy and the real reference.",
    "evaluate": "Compare each method's synthetic noise with real noise on sets of real pairs.",
    "demo": "Run the whole job on the shipped sample: low-light image, clip and a side-by-side preview.",
}
"""Every command's one-line summary, in the order the help lists them."""


INTERRUPTED = "darksynth: interrupted; finished files are complete, no partial file was left"


class OneLineErrors(TyperGroup):
    """The command group, with click's usage errors reported as darksynth reports every error: one line.

    Click prints a usage error as a usage line, a hint and the message (typer boxes them); here it is
    ``darksynth: error: apply: Invalid value for '--workers': ...``. A bad value of an option exits 1, as a
    bad value found later does (``--shard 9/8``); a malformed command line (unknown option, missing
    argument) exits 2, click's and argparse's status for it. Ctrl-C exits 130 with one line.
    """

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        windows_expand_args: bool = True,
        **extra: Any,
    ) -> Any:
        try:
            result = super().main(
                args, prog_name, complete_var, standalone_mode=False, windows_expand_args=windows_expand_args, **extra
            )
        except click_errors.NoArgsIsHelpError as error:
            error.show()  # the command's help, as click gives it
            result = error.exit_code
        except click_errors.UsageError as error:
            command = error.ctx.command_path if error.ctx is not None else "darksynth"
            value_error = isinstance(error, click_errors.BadParameter) and not isinstance(
                error, click_errors.MissingParameter
            )
            where = command.removeprefix("darksynth").strip()
            typer.echo(f"darksynth: error: {where + ': ' if where else ''}{_one_line(error.format_message())}"
                       f" (see '{command} --help')", err=True)  # fmt: skip
            result = 1 if value_error else 2
        except click_errors.ClickException as error:
            typer.echo(f"darksynth: error: {_one_line(error.format_message())}", err=True)
            result = error.exit_code
        except typer.Abort:
            typer.echo(INTERRUPTED, err=True)
            result = 130
        if not standalone_mode:
            return result
        sys.exit(result if isinstance(result, int) else 0)


def _one_line(message: str) -> str:
    return " ".join(message.split())


def new_app() -> typer.Typer:
    """A darksynth app with its settings and the root's ``--version``, and no command yet.

    Help is click's plain text (``rich_markup_mode=None``): rich markup read ``darksynth[ray]`` as a tag and
    dropped it, and showed flags as taking a ``<bool>`` value.
    """
    app = typer.Typer(
        name="darksynth",
        help=APP_HELP,
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        rich_markup_mode=None,
        cls=OneLineErrors,
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
