"""Weights files: a network's weights written as safetensors, their metadata read back checked to be a model's.

Weights are never unpickled: safetensors holds raw tensors, and the metadata says which model and version
wrote them, so a wrong file is refused with a one-line message before any tensor is read.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from safetensors import SafetensorError, safe_open
from safetensors.torch import save_file
from torch import nn

from darksynth.errors import DarksynthError
from darksynth.io.atomic import atomic_output


def first_line(error: BaseException) -> str:
    """The first line of an error's message (the reason a one-line message ends with), or its type's name."""
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def read_checked_metadata(path: Path, *, model: str, version: int | tuple[int, ...], label: str) -> dict[str, str]:
    """The metadata of ``path``, checked to name ``model`` at ``version`` (or one of several versions).

    Args:
        label: how messages name the model ("DEN", "Starlight").

    Raises:
        DarksynthError: a missing or unreadable file, another model's weights or another version's.
    """
    try:
        with safe_open(str(path), framework="pt") as handle:
            metadata: dict[str, str] = handle.metadata() or {}
    except FileNotFoundError:
        raise DarksynthError(f"{path}: no such {label} weights file") from None
    except (SafetensorError, OSError, ValueError) as error:
        raise DarksynthError(f"{path}: not a readable safetensors file ({first_line(error)})") from None
    if metadata.get("model") != model:
        raise DarksynthError(f"{path}: not darksynth {label} weights (model {metadata.get('model')!r})")
    versions = (version,) if isinstance(version, int) else version
    if metadata.get("version") not in {str(v) for v in versions}:
        readable = " and ".join(str(v) for v in versions)
        raise DarksynthError(
            f"{path}: weights of {label} version {metadata.get('version')}, this darksynth reads version {readable}"
        )
    return metadata


def write_weights_file(
    path: Path,
    module: nn.Module,
    *,
    model: str,
    version: int,
    config: Mapping[str, Any],
    training: Mapping[str, Any] | None = None,
) -> None:
    """Write ``module``'s weights atomically, with what is needed to rebuild and to trust them in the metadata:
    the ``model`` name and ``version`` (as :func:`read_checked_metadata` checks them), its ``config`` and what its
    ``training`` recorded, as JSON."""
    metadata = {
        "model": model,
        "version": str(version),
        "config": json.dumps(config),
        "training": json.dumps(dict(training or {})),
    }
    tensors = {name: tensor.detach().cpu().contiguous() for name, tensor in module.state_dict().items()}
    with atomic_output(path) as temporary:
        save_file(tensors, str(temporary), metadata=metadata)
