"""Reading the metadata of a safetensors weights file and checking it is the expected model and version.

Weights are never unpickled: safetensors holds raw tensors, and the metadata says which model and version
wrote them, so a wrong file is refused with a one-line message before any tensor is read.
"""

from __future__ import annotations

from pathlib import Path

from safetensors import SafetensorError, safe_open

from darksynth.errors import DarksynthError


def _first_line(error: BaseException) -> str:
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
        raise DarksynthError(f"{path}: not a readable safetensors file ({_first_line(error)})") from None
    if metadata.get("model") != model:
        raise DarksynthError(f"{path}: not darksynth {label} weights (model {metadata.get('model')!r})")
    versions = (version,) if isinstance(version, int) else version
    if metadata.get("version") not in {str(v) for v in versions}:
        readable = " and ".join(str(v) for v in versions)
        raise DarksynthError(
            f"{path}: weights of {label} version {metadata.get('version')}, this darksynth reads version {readable}"
        )
    return metadata
