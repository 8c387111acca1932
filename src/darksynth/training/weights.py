"""DEN weights on disk: safetensors with the model's name, version and shape in the metadata. No pickle."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

from darksynth.errors import DarksynthError
from darksynth.io.atomic import atomic_output
from darksynth.io.weights_file import read_checked_metadata
from darksynth.models.den import DEN, MODEL_NAME, MODEL_VERSION, READABLE_MODEL_VERSIONS, DENConfig


def save_weights(path: Path, model: DEN, *, training: dict[str, Any] | None = None) -> None:
    """Write the model's weights atomically, with what is needed to rebuild and to trust it."""
    metadata = {
        "model": MODEL_NAME,
        "version": str(MODEL_VERSION),
        "config": json.dumps(model.config.to_dict()),
        "training": json.dumps(training or {}),
    }
    tensors = {name: tensor.detach().cpu().contiguous() for name, tensor in model.state_dict().items()}
    with atomic_output(path) as temporary:
        save_file(tensors, str(temporary), metadata=metadata)


def read_metadata(path: Path) -> dict[str, str]:
    """The metadata of a weights file, checked to be this model's, of a version this darksynth reads."""
    return read_checked_metadata(path, model=MODEL_NAME, version=READABLE_MODEL_VERSIONS, label="DEN")


def load_weights(path: Path, *, device: torch.device | str = "cpu") -> DEN:
    """Rebuild a DEN from a weights file.

    Raises:
        DarksynthError: missing, corrupted, another model's or another version's weights.
    """
    metadata = read_metadata(path)
    try:
        settings = json.loads(metadata["config"])
        if metadata["version"] == "1":
            # Version 1 predates the sRGB model: its weights are the paper's model.
            settings["noise_model"] = "paper"
            settings["log_levels"] = False
        config = DENConfig(**settings)
        model = DEN(config)
        model.load_state_dict(load_file(str(path), device=str(device)))
    except (SafetensorError, KeyError, TypeError, ValueError, RuntimeError) as error:
        # torch lists every mismatched tensor on its own line; the first line says what is wrong.
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise DarksynthError(f"{path}: weights do not fit the DEN they describe ({first_line})") from None
    return model.to(device).eval()


def default_weights_path(variant: str = "v3", noise_model: str = "srgb") -> Path:
    """The DEN shipped with the package: the ``srgb`` model (default) or the ``paper`` model, as the full v3
    (default) or, for the paper model, the v2 ablation (encoder and head only)."""
    data = Path(__file__).resolve().parent.parent / "data"
    if noise_model == "srgb":
        return data / f"den_srgb_{variant}.safetensors"
    return data / f"den_{variant}.safetensors"
