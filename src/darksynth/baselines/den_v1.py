"""The paper's ablation v1: a U-Net that makes the noisy image directly, without the noise model f.

v2 and v3 predict v and leave the pixels to f(v). v1 keeps the DEN's encoder as the reader of the reference
(its pooled bottleneck and noise statistics, :meth:`darksynth.models.den.DEN.features`), turns what it reads into
a code of ``code_size`` numbers by a small MLP in place of the head that predicted v, and hands the code to a
generator U-Net that receives the dark clean frame beside standard normal channels and the code broadcast over
the frame, and outputs the noisy frame: the dark frame plus the U-Net's residual, clipped to [0, 1] and rounded
to 8-bit levels (straight through for the gradient), as a real reference arrives.

Nothing in the network names a noise parameter: what a reference's noise looks like, and how to draw it, are
both learned. It is trained on the same synthetic data as v2 and v3 (:mod:`darksynth.baselines.den_v1_training`).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
from safetensors import safe_open
from safetensors.torch import load_file
from torch import nn

from darksynth.baselines.starlight_model import ResidualUNet
from darksynth.errors import DarksynthError
from darksynth.io.weights_file import write_weights_file
from darksynth.models.den import DEN, DENConfig

MODEL_NAME = "darksynth-den-v1"
MODEL_VERSION = 1


@dataclass(frozen=True)
class DENv1Config:
    """Shape of the v1 network, stored beside its weights.

    Attributes:
        encoder_width: width of the DEN encoder that reads the reference (the shipped v2 and v3: 8).
        encoder_depth: its depth.
        code_size: numbers the reference is summarised in.
        width: channels of the generator U-Net's first level.
        depth: down-sampling steps of the generator U-Net.
        noise_channels: standard normal channels the generator receives.
        channels: colour channels.
    """

    encoder_width: int = 8
    encoder_depth: int = 3
    code_size: int = 16
    width: int = 16
    depth: int = 2
    noise_channels: int = 3
    channels: int = 3

    def to_dict(self) -> dict[str, int]:
        return asdict(self)


class DENv1(nn.Module):
    """v1 (see the module docstring): ``encode(reference)`` gives a code, ``generate(dark, code)`` the noisy clip."""

    def __init__(self, config: DENv1Config | None = None) -> None:
        super().__init__()
        self.config = config = config or DENv1Config()
        # The encoder of the paper-model DEN reads the reference; its head, which would predict v, is emptied
        # (an empty Sequential passes its input through) and to_code reads the features instead.
        self.encoder = DEN(
            DENConfig(variant="v2", width=config.encoder_width, depth=config.encoder_depth, noise_model="paper")
        )
        self.encoder.head = nn.Sequential()
        self.to_code = nn.Sequential(
            nn.Linear(self._feature_size(), 64), nn.GELU(), nn.Linear(64, config.code_size), nn.Tanh()
        )
        self.generator = ResidualUNet(
            config.channels + config.noise_channels + config.code_size, config.channels, config.width, config.depth
        )

    def _feature_size(self) -> int:
        with torch.no_grad():
            probe = torch.zeros(1, 1, self.config.channels, self.encoder.multiple, self.encoder.multiple)
            return int(self.encoder.features(probe).shape[-1])

    def encode(self, reference: torch.Tensor) -> torch.Tensor:
        """The code (B, code_size) of noisy reference clips (B, T, C, H, W) in [0, 1]."""
        code: torch.Tensor = self.to_code(self.encoder.features(reference))
        return code

    def generate(
        self, dark: torch.Tensor, code: torch.Tensor, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """Noisy clips (B, T, C, H, W) on 8-bit levels from dark clean clips of that shape and codes (B, K).

        The normal channels are drawn on the CPU generator ``generator`` (the global one when None), so a seed
        gives the same noise on every device."""
        if dark.dim() != 5 or dark.shape[2] != self.config.channels:
            raise ValueError(f"expected clips (B, T, {self.config.channels}, H, W), got shape {tuple(dark.shape)}")
        batch, frames, channels, height, width = dark.shape
        flat = dark.reshape(batch * frames, channels, height, width)
        latent = torch.randn(
            (batch * frames, self.config.noise_channels, height, width), generator=generator, dtype=dark.dtype
        ).to(dark.device)
        codes = code.repeat_interleave(frames, dim=0)[:, :, None, None].expand(-1, -1, height, width)
        noisy = self.generator.add_residual(flat, latent, codes.to(dark.dtype), quantize=True)
        return noisy.reshape(batch, frames, channels, height, width)

    def forward(
        self, reference: torch.Tensor, dark: torch.Tensor, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """``dark`` (B, T, C, H, W) made noisy like the reference clips (B, T', C, H', W')."""
        return self.generate(dark, self.encode(reference), generator)


def default_den_v1_path() -> Path:
    """The shipped v1 weights."""
    return Path(__file__).resolve().parents[1] / "data" / "den_v1.safetensors"


def save_den_v1(path: Path, model: DENv1, *, training: dict[str, object] | None = None) -> None:
    """Write the weights and config as safetensors, atomically."""
    config = model.config.to_dict()
    write_weights_file(path, model, model=MODEL_NAME, version=MODEL_VERSION, config=config, training=training)


def load_den_v1(path: Path | None = None, *, device: str | torch.device = "cpu") -> DENv1:
    """Read v1 weights (the shipped ones by default), in eval mode; DarksynthError naming the file otherwise."""
    path = path or default_den_v1_path()
    if not path.is_file():
        raise DarksynthError(f"{path}: no v1 weights there")
    try:
        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata() or {}
        if metadata.get("model") != MODEL_NAME:
            raise DarksynthError(f"{path}: not {MODEL_NAME} weights (model {metadata.get('model')!r})")
        model = DENv1(DENv1Config(**json.loads(metadata["config"])))
        model.load_state_dict(load_file(str(path)))
    except DarksynthError:
        raise
    except Exception as error:
        raise DarksynthError(f"{path}: cannot read v1 weights ({error})") from None
    return model.to(device).eval()
