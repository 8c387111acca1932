"""scripts/ stays runnable and findable: every script imports as it runs, names the doc it makes and its command, and
is in scripts/README.md's table; every path to a script that a doc, test or module names exists."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "scripts"
ALL_SCRIPTS = sorted(SCRIPTS.glob("*/*.py"))

RETIRED = ("roundtrip_distribution.py", "srgb_model_pictures.py", "srgb_noise_pictures.py")
"""Scripts removed with the version-3 model that docs still quote as history; scripts/README.md lists them."""

SCRIPT_PATH = re.compile(r"scripts/[a-z0-9_/]+\.py")


def test_scripts_are_grouped_in_folders() -> None:
    assert ALL_SCRIPTS
    assert not list(SCRIPTS.glob("*.py")), "a script belongs in the folder of its concern"


@pytest.mark.parametrize("path", ALL_SCRIPTS, ids=lambda path: path.relative_to(SCRIPTS).as_posix())
def test_script_imports_as_it_runs_and_its_docstring_says_what_it_makes_and_how(path: Path) -> None:
    """Loaded as ``python scripts/GROUP/NAME.py`` loads it (its folder first on the path), without running main."""
    relative = path.relative_to(ROOT).as_posix()
    saved_path, saved_modules = list(sys.path), set(sys.modules)
    sys.path.insert(0, str(path.parent))
    try:
        module = load_script(path)
    finally:
        sys.path[:] = saved_path
        for name in set(sys.modules) - saved_modules:
            if (SCRIPTS / path.parent.name / f"{name}.py").is_file():
                del sys.modules[name]
    assert callable(getattr(module, "main", None))
    docstring = module.__doc__ or ""
    assert "\nMakes: " in docstring
    assert "Run from the repo root" in docstring
    assert relative in docstring, "the command names the script by its path from the repository root"


def test_the_readme_table_lists_every_script_and_no_other() -> None:
    readme = (SCRIPTS / "README.md").read_text()
    listed = set(re.findall(r"^\| `([\w/]+\.py)` \|", readme, flags=re.MULTILINE))
    assert listed == {path.relative_to(SCRIPTS).as_posix() for path in ALL_SCRIPTS}
    for name in RETIRED:
        assert f"`{name}`" in readme


def test_every_script_path_named_in_the_repository_exists() -> None:
    texts = [ROOT / "README.md", *ROOT.glob("docs/*.md"), *SCRIPTS.rglob("*.md"), *SCRIPTS.rglob("*.py")]
    for folder in ("src", "tests", "benchmarks"):
        texts += [p for p in (ROOT / folder).rglob("*") if p.suffix in {".py", ".md"}]
    missing = {
        f"{text.relative_to(ROOT)}: {found}"
        for text in texts
        for found in SCRIPT_PATH.findall(text.read_text())
        if not (ROOT / found).is_file() and Path(found).name not in RETIRED
    }
    assert not missing
