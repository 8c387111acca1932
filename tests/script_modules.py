"""Scripts, benchmarks and examples (files of no package) loaded as modules, as the tests of each load them."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType


def load_script(path: Path, name: str | None = None) -> ModuleType:
    """The file ``path`` run as the module ``name`` (its stem by default), without running its main guard.

    The module is registered in ``sys.modules`` before it runs: a dataclass looks its module up while being made."""
    spec = importlib.util.spec_from_file_location(name or path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
