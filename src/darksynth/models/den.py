"""The Degradation Estimation Network: a U-Net whose encoder feeds an MLP head that predicts v.

The encoder reads each frame of a clip beside the frame minus the clip's mean frame (what changes over the
clip), so that patterns held over the clip (temporal banding) can be told from per-frame ones. Its
bottleneck is pooled over frames and positions (mean and standard deviation of every channel) and goes,
with fixed noise statistics of the clip (:mod:`darksynth.models.statistics`), into an MLP that
predicts v in a normalised space: a sigmoid over each parameter's training range, so every prediction is a
valid value. The decoder (variant v3) reconstructs the dark clean clip from the encoder's features, which is
the paper's auxiliary task. Nothing depends on the frame size: frames are padded to a multiple of
2 ** (depth + 1) and cropped back.

Variants (the paper's ablation): ``v3`` the full DEN; ``v2`` encoder and head only (no decoder).

Noise models: ``paper`` predicts the paper's v (8 values) from the paper's statistics (model version 1);
``srgb`` predicts the extended v (per-channel gains, correlation length, channel correlations, JPEG strength
besides the paper's) and reads multi-scale, per-channel statistics as well (model version 2). Version-1
weights are read as the ``paper`` model.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Literal

import torch
import torch.nn.functional as F
from torch import nn

from darksynth.models.statistics import model_statistics
from darksynth.noise.components import NoiseModel, model_parameters, vector_size
from darksynth.noise.components import profile_version as current_profile_version
from darksynth.noise.values import NoiseValues, values_from_vector

Variant = Literal["v2", "v3"]
MODEL_NAME = "darksynth-den"
MODEL_VERSION = 3
"""Weights are written with this version (2: the noise model is part of the config)."""
READABLE_MODEL_VERSIONS = (1, 2, 3)
"""Versions read on load; version 1 weights are the ``paper`` noise model."""


@dataclass(frozen=True)
class DENConfig:
    """Shape of the network, stored beside its weights.

    Attributes:
        variant: ``v3`` (U-Net + head, the default) or ``v2`` (encoder + head).
        width: channels of the first level; each level below doubles them.
        depth: number of down-sampling steps after the 2x2 stem; sides are padded to a multiple of 2 ** (depth + 1).
        head_width: hidden units of the MLP head.
        channels: colour channels of the input (grey references are repeated to 3).
        noise_model: which v the head predicts (see the module docstring).
        log_levels: the noise levels with a ``log_floor`` are predicted on a log scale and trained with a
            log-uniform prior (relative precision at every level; version-1 weights: False).
    """

    variant: Variant = "v3"
    width: int = 16
    depth: int = 3
    head_width: int = 128
    channels: int = 3
    noise_model: NoiseModel = "srgb"
    log_levels: bool = True
    profile_version: int = field(default_factory=current_profile_version)
    """The profile version whose parameters the head was built for: it predicts the noise model's parameters that had
    arrived by then (:func:`darksynth.noise.components.model_parameters`), so a component added to the table
    later leaves a trained network readable (version-1 weights: 1, version-2 weights: 2)."""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def parameter_bounds(
    device: torch.device | str | None = None,
    noise_model: NoiseModel = "srgb",
    log_levels: bool = False,
    version: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Low and high ends of every entry of a noise model's v, from the training ranges of the parameter table,
    and which entries are on a log scale (their low end is then the log floor)."""
    entries = [p for p in model_parameters(noise_model, version) for _ in range(p.size)]  # one per value of v
    logarithmic = [log_levels and p.log_floor is not None for p in entries]
    low = [p.log_floor if log_levels and p.log_floor else p.training_range[0] for p in entries]
    high = [p.training_range[1] for p in entries]
    return (
        torch.tensor(low, device=device),
        torch.tensor(high, device=device),
        torch.tensor(logarithmic, device=device),
    )


def normalise(
    vector: torch.Tensor, noise_model: NoiseModel = "srgb", log_levels: bool = False, version: int | None = None
) -> torch.Tensor:
    """v (..., vector_size(model)) -> [0, 1] per entry over its training range; log-scale entries (with
    ``log_levels``) through their logarithm, values below the floor at 0."""
    low, high, logarithmic = parameter_bounds(vector.device, noise_model, log_levels, version)
    linear = (vector - low) / (high - low)
    logs = (vector.clamp_min(low).log() - low.log()) / (high.log() - low.log())
    return torch.where(logarithmic, logs, linear)


def denormalise(
    normalised: torch.Tensor, noise_model: NoiseModel = "srgb", log_levels: bool = False, version: int | None = None
) -> torch.Tensor:
    """Inverse of :func:`normalise` (0 on a log scale gives the floor)."""
    low, high, logarithmic = parameter_bounds(normalised.device, noise_model, log_levels, version)
    linear = low + normalised * (high - low)
    # Bounds of the linear entries replaced by 1 inside the log branch: log(0) there would make the unused
    # branch infinite and its gradient NaN (the level loss differentiates through this function).
    log_low = torch.where(logarithmic, low, torch.ones_like(low)).log()
    log_high = torch.where(logarithmic, high, torch.ones_like(high)).log()
    logs = (log_low + normalised * (log_high - log_low)).exp()
    return torch.where(logarithmic, logs, linear)


class ConvBlock(nn.Module):
    """Two 3x3 convolutions with GELU."""

    def __init__(self, inputs: int, outputs: int) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(inputs, outputs, 3, padding=1),
            nn.GELU(),
            nn.Conv2d(outputs, outputs, 3, padding=1),
            nn.GELU(),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.body(x)  # type: ignore[no-any-return]


@dataclass
class DENOutput:
    """What the network returns: v in normalised space, and the dark clean clip (v3 only)."""

    normalised: torch.Tensor
    dark: torch.Tensor | None
    noise_model: NoiseModel = "srgb"
    log_levels: bool = False
    profile_version: int | None = None

    @property
    def values(self) -> NoiseValues:
        """The estimated noise values in the parameters' units, batched (B,); those the noise model lacks neutral."""
        return values_from_vector(
            denormalise(self.normalised, self.noise_model, self.log_levels, self.profile_version),
            self.noise_model,
            self.profile_version,
        )


class DEN(nn.Module):
    """Degradation Estimation Network (see the module docstring)."""

    statistics_mean: torch.Tensor
    statistics_scale: torch.Tensor

    def __init__(self, config: DENConfig | None = None) -> None:
        super().__init__()
        self.config = config = config or DENConfig()
        widths = [config.width * 2**level for level in range(config.depth + 1)]
        self.encoders = nn.ModuleList()
        self.downs = nn.ModuleList()
        # A lossless 2x2 space-to-depth stem: the convolutions run at half resolution, 4x cheaper on a CPU.
        self.stem = nn.PixelUnshuffle(2)
        inputs = 4 * 2 * config.channels
        for level in range(config.depth):
            self.encoders.append(ConvBlock(inputs, widths[level]))
            self.downs.append(nn.Conv2d(widths[level], widths[level + 1], 2, stride=2))
            inputs = widths[level + 1]
        self.bottleneck = ConvBlock(widths[-1], widths[-1])
        self.ups = nn.ModuleList()
        self.decoders = nn.ModuleList()
        if config.variant == "v3":
            for level in reversed(range(config.depth)):
                self.ups.append(nn.ConvTranspose2d(widths[level + 1], widths[level], 2, stride=2))
                self.decoders.append(ConvBlock(2 * widths[level], widths[level]))
            self.to_image = nn.Sequential(nn.Conv2d(widths[0], 4 * config.channels, 1), nn.PixelShuffle(2))
        # The statistics span many decades and are standardised with the mean and spread measured on training
        # data before training starts (set_statistics_scale); the buffers travel with the weights.
        statistics = sum(s.size for s in model_statistics(config.noise_model, config.profile_version))
        self.register_buffer("statistics_mean", torch.zeros(statistics))
        self.register_buffer("statistics_scale", torch.ones(statistics))
        self.pooled_norm = nn.LayerNorm(2 * widths[-1])
        self.head = nn.Sequential(
            nn.Linear(2 * widths[-1] + statistics, config.head_width),
            nn.GELU(),
            nn.Linear(config.head_width, config.head_width),
            nn.GELU(),
            nn.Linear(config.head_width, vector_size(config.noise_model, config.profile_version)),
        )

    @torch.no_grad()
    def set_statistics_scale(self, statistics: torch.Tensor) -> None:
        """Standardise the head's statistics input with those measured on training clips (N, statistics size)."""
        self.statistics_mean.copy_(statistics.mean(0))
        self.statistics_scale.copy_(statistics.std(0).clamp_min(1e-3))

    @property
    def noise_model(self) -> NoiseModel:
        return self.config.noise_model

    @property
    def multiple(self) -> int:
        """Frame sides are padded to a multiple of this."""
        return int(2 ** (self.config.depth + 1))

    def forward(self, clip: torch.Tensor) -> DENOutput:
        """Estimate v from noisy clips.

        Args:
            clip: (B, T, C, H, W), values in [0, 1], C = config.channels.

        Returns:
            v in normalised space (B, vector_size(noise_model)) and, for v3, the dark clean clip (B, T, C, H, W).
        """
        features, x, skips = self._encode(clip)
        normalised = torch.sigmoid(self.head(features))
        dark = None
        if self.config.variant == "v3":
            batch, frames, channels, height, width = clip.shape
            for up, decoder, skip in zip(self.ups, self.decoders, reversed(skips), strict=True):
                x = decoder(torch.cat([up(x), skip], dim=1))
            dark = self.to_image(x)[..., :height, :width].reshape(batch, frames, channels, height, width)
        return DENOutput(
            normalised=normalised,
            dark=dark,
            noise_model=self.config.noise_model,
            log_levels=self.config.log_levels,
            profile_version=self.config.profile_version,
        )

    def features(self, clip: torch.Tensor) -> torch.Tensor:
        """What the head reads of noisy clips (B, T, C, H, W): the pooled bottleneck beside the standardised
        noise statistics, (B, feature_size)."""
        return self._encode(clip)[0]

    def _encode(self, clip: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, list[torch.Tensor]]:
        if clip.dim() != 5 or clip.shape[2] != self.config.channels:
            raise ValueError(f"expected clips (B, T, {self.config.channels}, H, W), got shape {tuple(clip.shape)}")
        batch, frames, _channels, height, width = clip.shape
        statistics = (self.statistics(clip) - self.statistics_mean) / self.statistics_scale
        moving = clip - clip.mean(dim=1, keepdim=True)
        x = torch.cat([clip, moving], dim=2).flatten(0, 1)
        pad_h, pad_w = (-height) % self.multiple, (-width) % self.multiple
        x = self.stem(F.pad(x, (0, pad_w, 0, pad_h), mode="replicate"))
        skips = []
        for encoder, down in zip(self.encoders, self.downs, strict=True):
            x = encoder(x)
            skips.append(x)
            x = down(x)
        x = self.bottleneck(x)
        pooled = x.reshape(batch, frames, x.shape[1], -1).transpose(1, 2).flatten(2)
        # A bottleneck of a single position (a small frame through a deep network) has no spread, not a NaN one.
        spread = pooled.std(-1) if pooled.shape[-1] > 1 else torch.zeros_like(pooled[..., 0])
        features = torch.cat([self.pooled_norm(torch.cat([pooled.mean(-1), spread], -1)), statistics], dim=-1)
        return features, x, skips

    def normalise(self, vector: torch.Tensor) -> torch.Tensor:
        """v in the parameters' units -> the [0, 1] space this model's head predicts in (training targets)."""
        return normalise(vector, self.config.noise_model, self.config.log_levels, self.config.profile_version)

    def statistics(self, clip: torch.Tensor) -> torch.Tensor:
        """The fixed noise statistics this model's head reads, before standardisation."""
        statistics = model_statistics(self.config.noise_model, self.config.profile_version)
        return torch.cat([s.compute(clip) for s in statistics], dim=-1)
