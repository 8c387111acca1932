from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from darksynth.cli import app
from darksynth.profile import default_profile_path


@pytest.fixture
def profile_file(tmp_path: Path) -> Path:
    return default_profile_path()


@pytest.fixture
def write_profile(tmp_path: Path) -> Callable[..., Path]:
    """Write a variant of the default profile: noise values replaced, other fields changed or removed."""

    def write(name: str = "profile.json", noise: dict[str, object] | None = None, **fields: object) -> Path:
        document = json.loads(default_profile_path().read_text())
        document["noise"].update(noise or {})
        for key, value in fields.items():
            if value is None:
                document.pop(key, None)
            else:
                document[key] = value
        path = tmp_path / name
        path.write_text(json.dumps(document))
        return path

    return write


@pytest.fixture
def rgb_image(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    pixels = rng.integers(0, 256, (40, 56, 3), dtype=np.uint8)
    path = tmp_path / "in" / "photo.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).save(path)
    return path


def run_cli(*args: str | Path) -> tuple[int, str, str]:
    """Invoke the CLI in-process; returns (exit code, stdout, stderr)."""
    result = CliRunner().invoke(app, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr
