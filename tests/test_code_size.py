"""The size rules of the source: no module over 500 lines, no function over 60 lines (docstring included).

A typer command's signature is not counted: its options are declarations, one per line (the body is what counts).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parent.parent / "src" / "darksynth"
SOURCES = sorted(SOURCE.rglob("*.py"))
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 60


def long_functions(path: Path, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """Functions of a source file whose body (from its first statement, docstring included) is over ``limit``
    lines, as ``name (lines)``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            assert node.end_lineno is not None
            lines = node.end_lineno - node.body[0].lineno + 1
            if lines > limit:
                found.append(f"{node.name} ({lines})")
    return found


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(SOURCE)))
def test_module_and_function_sizes(path: Path) -> None:
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_MODULE_LINES, f"{path.relative_to(SOURCE)}: {lines} lines (at most {MAX_MODULE_LINES})"
    assert not long_functions(path), f"{path.relative_to(SOURCE)}: functions over {MAX_FUNCTION_LINES} lines"


def test_the_check_sees_a_long_function(tmp_path: Path) -> None:
    """The control: a function of 61 body lines is caught, one of 60 is not."""
    body = "".join(f"    x{i} = {i}\n" for i in range(60))
    module = tmp_path / "long.py"
    module.write_text(f'def fits():\n{body}\n\ndef too_long():\n    """One line more."""\n{body}', encoding="utf-8")
    assert long_functions(module) == ["too_long (61)"]


def repeated_module_names(root: Path) -> dict[str, list[str]]:
    """Module file names (``__init__.py`` aside) that stand in more than one package below ``root``."""
    places: dict[str, list[str]] = {}
    for path in sorted(root.rglob("*.py")):
        if path.name != "__init__.py":
            places.setdefault(path.name, []).append(str(path.relative_to(root)))
    return {name: paths for name, paths in places.items() if len(paths) > 1}


def test_each_module_name_stands_for_one_module() -> None:
    # One name, one meaning: "darkening.py" in two packages made every mention of it ambiguous.
    assert repeated_module_names(SOURCE) == {}


def test_the_check_sees_a_repeated_module_name(tmp_path: Path) -> None:
    for package in ("light", "estimation"):
        (tmp_path / package).mkdir()
        (tmp_path / package / "darkening.py").write_text("", encoding="utf-8")
    assert repeated_module_names(tmp_path) == {"darkening.py": ["estimation/darkening.py", "light/darkening.py"]}
