"""DEN weights on disk (safetensors with the model's name, version and shape in the metadata; no pickle), and which
shipped DEN serves which noise model and variant."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file

from darksynth.errors import DarksynthError
from darksynth.io.weights_file import first_line, read_checked_metadata, write_weights_file
from darksynth.models.den import DEN, MODEL_NAME, MODEL_VERSION, READABLE_MODEL_VERSIONS, DENConfig
from darksynth.noise.components import NoiseModel

SHIPPED_WEIGHTS: Final[Mapping[tuple[str, str], str]] = {
    ("srgb", "v3"): "den_srgb_v3.safetensors",
    ("paper", "v3"): "den_v3.safetensors",
    ("paper", "v2"): "den_v2.safetensors",
}
"""The DENs shipped in ``darksynth/data``, by (noise model, variant): the sRGB model as the full v3, the paper's
model as v3 and as its v2 ablation (encoder and head only). docs/den.md gives the command that made each."""

NETWORK_MODELS: Final[tuple[NoiseModel, ...]] = ("paper", "srgb")
"""The noise models a DEN predicts (and ``train`` trains): the ``spectral`` model's parameters are measured on the
reference instead (:mod:`darksynth.estimation.noise.spectrum`), on top of the ``srgb`` network's estimate."""

LOG_LEVELS: Final[Mapping[NoiseModel, bool]] = {"srgb": True, "paper": False}
"""Whether a noise model's DEN predicts the noise levels on a log scale: the sRGB model does (docs/den.md); the
paper's model keeps the linear scale its shipped weights were trained on."""


@dataclass(frozen=True)
class DENChoice:
    """Which DEN to load: a weights file, or else the shipped DEN of a noise model and variant.

    Attributes:
        weights: a weights file; when given, ``noise_model`` and ``variant`` are not read (the file says them).
        noise_model: the noise model of the shipped DEN (see :data:`SHIPPED_WEIGHTS`).
        variant: the variant of the shipped DEN.
    """

    weights: Path | None = None
    noise_model: str = "srgb"
    variant: str = "v3"

    def path(self) -> Path:
        """The weights file to load.

        Raises:
            DarksynthError: no weights file is given and no DEN of this noise model and variant is shipped.
        """
        return self.weights if self.weights is not None else default_weights_path(self.variant, self.noise_model)


def save_weights(path: Path, model: DEN, *, training: dict[str, Any] | None = None) -> None:
    """Write the model's weights atomically, with what is needed to rebuild and to trust it."""
    config = model.config.to_dict()
    write_weights_file(path, model, model=MODEL_NAME, version=MODEL_VERSION, config=config, training=training)


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
        # Weights written before the rename call the profile version "table_version"; versions 1 and 2 predate
        # it in the config: their heads were built for the table of their time.
        if "table_version" in settings:
            settings["profile_version"] = settings.pop("table_version")
        settings.setdefault("profile_version", int(metadata["version"]))
        config = DENConfig(**settings)
        model = DEN(config)
        model.load_state_dict(load_file(str(path), device=str(device)))
    except (SafetensorError, KeyError, TypeError, ValueError, RuntimeError) as error:
        # torch lists every mismatched tensor on its own line; the first line says what is wrong.
        raise DarksynthError(f"{path}: weights do not fit the DEN they describe ({first_line(error)})") from None
    return model.to(device).eval()


def default_weights_path(variant: str = DENChoice.variant, noise_model: str = DENChoice.noise_model) -> Path:
    """The shipped DEN of a noise model and variant (see :data:`SHIPPED_WEIGHTS`).

    Raises:
        DarksynthError: no DEN of that noise model and variant is shipped (one line naming those that are).
    """
    name = SHIPPED_WEIGHTS.get((noise_model, variant))
    if name is None:
        shipped = ", ".join(f"{model} {shipped_variant}" for model, shipped_variant in SHIPPED_WEIGHTS)
        raise DarksynthError(
            f"no shipped DEN for noise model {noise_model!r} and variant {variant!r}; shipped: {shipped}"
        )
    return Path(__file__).resolve().parent.parent / "data" / name
