"""The Starlight noise generator (Monakhova et al. 2022), adapted to sRGB: physics with learned scalars + U-Net.

The generator takes a dark clean image or clip in [0, 1] and returns a noisy version of it:

1. Physics part, every scale a learned positive scalar held as its logarithm:

   - shot and read noise, n ~ N(0, shot^2 x + read^2) at every pixel of every frame;
   - uniform noise u ~ U(0, q) at every pixel (Starlight's "uniform" term, one-sided as in its code);
   - row noise: one N(0, row^2) offset per frame, channel and column index, constant along the other axis of
     the frame (Starlight's ``row`` term, drawn like its code: a vector over the last axis, broadcast over the
     second last);
   - temporal row noise: the same pattern drawn once per clip and held over its frames (Starlight's ``rowt``);
   - periodic noise: a column pattern whose spectrum has peaks at column frequencies 0, W/4 and 3W/4 with
     N(0, s_k^2) coefficients (Starlight's ``periodic``), per frame and channel.

2. A small U-Net reads the physics-noisy frame beside channels of standard normal noise and adds a learned
   residual: in sRGB it can correlate the noise across neighbouring pixels and colour channels, which the
   per-pixel physics cannot. Its last convolution starts at zero, so an untrained generator is pure physics.

3. The result is clipped to [0, 1] and, by default, rounded to 8-bit levels (straight-through gradient), the
   form in which real references and the DEN's training data arrive.

Nothing depends on the frame size: frames are padded to a multiple of 2 ** depth for the U-Net and cropped
back, and every physics term is defined per pixel, row or column.

The weights file is safetensors with the model name, version and configuration in its metadata; nothing is
pickled.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from safetensors import SafetensorError
from safetensors.torch import load_file
from torch import nn

from darksynth.errors import DarksynthError
from darksynth.io.weights_file import first_line, read_checked_metadata, write_weights_file
from darksynth.noise.periodic import periodic_basis

MODEL_NAME = "darksynth-starlight"
MODEL_VERSION = 1
"""Weights carry this version; a file of another version is refused on load."""

PHYSICS_NAMES: tuple[str, ...] = ("shot", "read", "row", "row_temporal", "uniform", "periodic")
"""The learned physics scales, in drawing order; ``periodic`` holds three values (DC, cosine, sine)."""

INITIAL_PHYSICS: dict[str, tuple[float, ...]] = {
    "shot": (0.02,),
    "read": (0.01,),
    "row": (0.002,),
    "row_temporal": (0.002,),
    "uniform": (0.002,),
    "periodic": (0.002, 0.002, 0.002),
}
"""Starting values: small noise of every kind, as Starlight starts from small values."""

RESIDUAL_SCALE = 0.1
"""The U-Net's output is multiplied by this: residuals are of the order of the noise (a few hundredths)."""


@dataclass(frozen=True)
class StarlightConfig:
    """Shape of the generator, stored beside its weights.

    Attributes:
        width: channels of the U-Net's first level; each level below doubles them.
        depth: down-sampling steps of the U-Net; frames are padded to a multiple of 2 ** depth.
        noise_channels: standard normal channels fed to the U-Net beside the noisy frame.
        quantize: round the output to 8-bit levels (with a straight-through gradient).
        channels: colour channels of the images.
    """

    width: int = 16
    depth: int = 2
    noise_channels: int = 3
    quantize: bool = True
    channels: int = 3

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _normal(shape: Sequence[int], generator: torch.Generator | None, device: torch.device) -> torch.Tensor:
    """Standard normals drawn on the generator's device and moved to ``device`` (a CPU generator serves CUDA)."""
    source = generator.device if generator is not None else device
    return torch.randn(tuple(shape), generator=generator, device=source).to(device)


def _uniform(shape: Sequence[int], generator: torch.Generator | None, device: torch.device) -> torch.Tensor:
    source = generator.device if generator is not None else device
    return torch.rand(tuple(shape), generator=generator, device=source).to(device)


class _Block(nn.Module):
    """Two 3x3 convolutions with leaky ReLU."""

    def __init__(self, inputs: int, outputs: int) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(inputs, outputs, 3, padding=1),
            nn.LeakyReLU(0.2),
            nn.Conv2d(outputs, outputs, 3, padding=1),
            nn.LeakyReLU(0.2),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        result: torch.Tensor = self.body(x)
        return result


class ResidualUNet(nn.Module):
    """A small U-Net: (N, inputs, H, W) -> (N, outputs, H, W), H and W multiples of 2 ** depth."""

    def __init__(self, inputs: int, outputs: int, width: int, depth: int) -> None:
        super().__init__()
        widths = [width * 2**level for level in range(depth + 1)]
        self.encoders = nn.ModuleList([_Block(inputs, widths[0])])
        self.downs = nn.ModuleList()
        for level in range(depth):
            self.downs.append(nn.Conv2d(widths[level], widths[level], 2, stride=2))
            self.encoders.append(_Block(widths[level], widths[level + 1]))
        self.ups = nn.ModuleList()
        self.decoders = nn.ModuleList()
        for level in reversed(range(depth)):
            self.ups.append(nn.ConvTranspose2d(widths[level + 1], widths[level], 2, stride=2))
            self.decoders.append(_Block(2 * widths[level], widths[level]))
        self.out = nn.Conv2d(widths[0], outputs, 1)
        self.zero_output()

    @torch.no_grad()
    def zero_output(self) -> None:
        """Set the last convolution to zero: the network then outputs exactly zero."""
        self.out.weight.zero_()
        if self.out.bias is not None:
            self.out.bias.zero_()

    def add_residual(self, frames: torch.Tensor, *extra: torch.Tensor, quantize: bool) -> torch.Tensor:
        """``frames`` (N, C, H, W) plus the residual the network makes of them and the ``extra`` channels beside
        them, times :data:`RESIDUAL_SCALE`, clipped to [0, 1] and, with ``quantize``, rounded to 8-bit levels
        (straight through for the gradient). Any H and W: the input is padded to a multiple of 2 ** depth and the
        residual cropped back."""
        height, width = frames.shape[-2:]
        inputs = torch.cat([frames, *extra], dim=1)
        multiple = 2 ** len(self.downs)
        pad_h, pad_w = (-height) % multiple, (-width) % multiple
        if pad_h or pad_w:
            inputs = F.pad(inputs, (0, pad_w, 0, pad_h), mode="replicate")
        residual: torch.Tensor = self(inputs)[..., :height, :width] * RESIDUAL_SCALE
        out = (frames + residual).clamp(0.0, 1.0)
        if quantize:
            out = out + ((out * 255.0).round() / 255.0 - out).detach()
        return out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        x = self.encoders[0](x)
        for down, encoder in zip(self.downs, list(self.encoders)[1:], strict=True):
            skips.append(x)
            x = encoder(down(x))
        for up, decoder in zip(self.ups, self.decoders, strict=True):
            x = decoder(torch.cat([up(x), skips.pop()], dim=1))
        result: torch.Tensor = self.out(x)
        return result


class StarlightGenerator(nn.Module):
    """Starlight's noise generator for sRGB images and clips.

    ``forward(clean, generator)`` takes a dark clean image batch (B, C, H, W) or clip batch (B, T, C, H, W)
    in [0, 1] and returns the noisy version, same shape, in [0, 1]. All randomness comes from ``generator``
    (the global one when None); a CPU generator also serves a model on CUDA.
    """

    def __init__(self, config: StarlightConfig | None = None) -> None:
        super().__init__()
        self.config = config or StarlightConfig()
        for name in PHYSICS_NAMES:
            initial = torch.tensor(INITIAL_PHYSICS[name], dtype=torch.float32).log()
            self.register_parameter(f"log_{name}", nn.Parameter(initial))
        self.net = ResidualUNet(
            self.config.channels + self.config.noise_channels,
            self.config.channels,
            self.config.width,
            self.config.depth,
        )

    # -- the learned scales ---------------------------------------------------------------------------------

    def scale(self, name: str) -> torch.Tensor:
        """The positive scale(s) of one physics term: exp of its logarithm, shape (1,) or (3,) for periodic."""
        parameter: torch.Tensor = getattr(self, f"log_{self._check_name(name)}")
        return parameter.exp()

    def physics_values(self) -> dict[str, float | list[float]]:
        """Every learned scale as plain numbers (periodic as a list of three)."""
        values: dict[str, float | list[float]] = {}
        for name in PHYSICS_NAMES:
            scale = [float(v) for v in self.scale(name).detach().cpu()]
            values[name] = scale if len(scale) > 1 else scale[0]
        return values

    @torch.no_grad()
    def set_physics_values(self, values: Mapping[str, float | Sequence[float]]) -> None:
        """Set some scales (strictly positive numbers; periodic takes one or three)."""
        for name, value in values.items():
            parameter: torch.Tensor = getattr(self, f"log_{self._check_name(name)}")
            target = torch.as_tensor(value, dtype=torch.float32).reshape(-1)
            if bool((target <= 0).any()) or target.numel() not in (1, parameter.numel()):
                raise ValueError(f"{name}: expected positive value(s) for {parameter.numel()} entries, got {value}")
            parameter.copy_(target.log().expand_as(parameter))

    @torch.no_grad()
    def zero_residual(self) -> None:
        """Make the U-Net's residual exactly zero (its last convolution zero): the generator is pure physics."""
        self.net.zero_output()

    @staticmethod
    def _check_name(name: str) -> str:
        if name not in PHYSICS_NAMES:
            raise KeyError(f"unknown Starlight physics term {name!r}; known: {', '.join(PHYSICS_NAMES)}")
        return name

    # -- generation -----------------------------------------------------------------------------------------

    def physics_noise(self, clip: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """The physics noise for a clip batch (B, T, C, H, W), shaped like it (before any clipping)."""
        if clip.dim() != 5:
            raise ValueError(f"expected a clip batch (B, T, C, H, W), got shape {tuple(clip.shape)}")
        batch, frames, channels, _height, width = clip.shape
        device = clip.device
        # Column structures first (row, held over the clip, periodic), then per-pixel terms: a fixed order.
        row = self.scale("row") * _normal((batch, frames, channels, 1, width), generator, device)
        held = self.scale("row_temporal") * _normal((batch, 1, channels, 1, width), generator, device)
        coefficients = _normal((batch, frames, channels, 3), generator, device) * self.scale("periodic")
        # The inverse DFT of a column spectrum with peaks at 0, W/4 and 3W/4 (conjugate pair, so real), each
        # with unit mean square: the same per-pixel strength at every frame width (see docs/noise-model.md).
        periodic = (coefficients @ periodic_basis(width, device=device)).unsqueeze(-2)
        shot, read = self.scale("shot"), self.scale("read")
        std = torch.sqrt(shot.square() * clip.clamp_min(0.0) + read.square())
        pixel = std * _normal(clip.shape, generator, device)
        uniform = self.scale("uniform") * _uniform(clip.shape, generator, device)
        return row + held + periodic + pixel + uniform

    def forward(self, clean: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """The noisy image or clip: physics, then the U-Net's residual, clipped to [0, 1] (8-bit levels)."""
        if clean.dim() not in (4, 5) or clean.shape[-3] != self.config.channels:
            raise ValueError(
                f"expected (B, {self.config.channels}, H, W) or (B, T, {self.config.channels}, H, W), "
                f"got shape {tuple(clean.shape)}"
            )
        clip = clean.unsqueeze(1) if clean.dim() == 4 else clean
        batch, frames, channels, height, width = clip.shape
        noisy = clip + self.physics_noise(clip, generator)
        frames_in = noisy.reshape(batch * frames, channels, height, width)
        latent = _normal((batch * frames, self.config.noise_channels, height, width), generator, clip.device)
        out = self.net.add_residual(frames_in, latent, quantize=self.config.quantize)
        out = out.reshape(batch, frames, channels, height, width)
        return out.squeeze(1) if clean.dim() == 4 else out


# -- weights on disk ----------------------------------------------------------------------------------------


def default_starlight_path() -> Path:
    """The Starlight generator shipped with the package."""
    return Path(__file__).resolve().parent.parent / "data" / "starlight.safetensors"


def save_starlight(path: Path, model: StarlightGenerator, *, training: Mapping[str, Any] | None = None) -> None:
    """Write the generator's weights atomically, with its name, version and configuration in the metadata."""
    config = model.config.to_dict()
    write_weights_file(Path(path), model, model=MODEL_NAME, version=MODEL_VERSION, config=config, training=training)


def load_starlight(path: Path | str | None = None, device: torch.device | str = "cpu") -> StarlightGenerator:
    """Rebuild a Starlight generator from a weights file (the shipped one by default), in eval mode.

    Raises:
        DarksynthError: a missing or corrupted file, another model's weights or another version's.
    """
    path = Path(path) if path is not None else default_starlight_path()
    metadata = read_checked_metadata(path, model=MODEL_NAME, version=MODEL_VERSION, label="Starlight")
    try:
        config = StarlightConfig(**json.loads(metadata["config"]))
        model = StarlightGenerator(config)
        model.load_state_dict(load_file(str(path), device=str(device)))
    except (SafetensorError, KeyError, TypeError, ValueError, RuntimeError) as error:
        raise DarksynthError(f"{path}: weights do not fit the Starlight generator ({first_line(error)})") from None
    if not all(bool(torch.isfinite(t).all()) for t in model.state_dict().values()):
        raise DarksynthError(f"{path}: Starlight weights hold non-finite values")
    return model.to(device).eval()
