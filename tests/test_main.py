"""main.py: the console entry point answers --version and --help without importing torch, with the same help as
the full command line."""

from __future__ import annotations

import subprocess
import sys

import pytest
from typer.testing import CliRunner

from darksynth import main as entry
from darksynth.cli import app
from darksynth.commands import COMMAND_HELP
from darksynth.version import __version__

WIDE = {"COLUMNS": "200", "TERMINAL_WIDTH": "200"}  # as tests/test_cli.py: typer reads the width once


@pytest.mark.parametrize("arguments", [["--help"], []])
def test_the_light_help_is_the_full_command_lines_help(arguments: list[str]) -> None:
    light = CliRunner().invoke(entry._light_app(), arguments, env=WIDE, prog_name="darksynth")
    full = CliRunner().invoke(app, arguments, env=WIDE, prog_name="darksynth")
    assert light.exit_code == full.exit_code
    assert light.output == full.output
    for name, summary in COMMAND_HELP.items():
        assert name in light.output and summary.split()[0] in light.output


def test_every_command_of_the_full_app_is_in_the_table_in_order() -> None:
    registered = [(command.name, command.help) for command in app.registered_commands]
    assert registered == list(COMMAND_HELP.items())


def test_version_from_both_apps() -> None:
    for runner_app in (entry._light_app(), app):
        result = CliRunner().invoke(runner_app, ["--version"])
        assert result.exit_code == 0 and result.output == f"darksynth {__version__}\n"


@pytest.mark.parametrize("arguments", [["--version"], ["--help"], []])
def test_answers_without_the_command_modules_or_torch(arguments: list[str]) -> None:
    script = (
        "import sys\n"
        "from darksynth.main import main\n"
        "try:\n"
        f"    main({arguments!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "print('loaded:', sorted(m for m in ('torch', 'numpy', 'darksynth.cli') if m in sys.modules))\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert "loaded: []" in result.stdout


def test_a_command_goes_to_the_full_command_line() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "darksynth", "apply", "absent.png", "out.png", "--profile", "absent.json"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 1
    assert result.stderr.strip() == "darksynth: error: absent.json: no such profile file"


def test_the_package_keeps_its_public_names_lazily() -> None:
    import darksynth
    import darksynth.synthesize as module_or_function
    from darksynth.synthesize import synthesize

    # The function, not the submodule of the same name, as when the package imported it eagerly.
    assert darksynth.synthesize is synthesize and module_or_function is synthesize
    assert darksynth.Profile.__name__ == "Profile"
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = darksynth.nope  # type: ignore[attr-defined]


def test_the_public_names_are_the_lazy_table() -> None:
    import darksynth

    assert sorted(darksynth.__all__) == sorted([*darksynth._PUBLIC, "__version__"])
