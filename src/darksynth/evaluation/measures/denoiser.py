"""The downstream check's denoiser and its training: a small residual denoiser (DnCNN-like), trained on crops made
noisy by a method's synthetic noise or cut from real pairs.

Every training of a seed starts from the same initial weights and, on synthetic noise, sees the same clean crops in
the same order with the same parameter draws: only the noise differs between methods. Everything derives from
``DownstreamSettings.seed``, so the same seed gives the same denoiser (on one device and thread count).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any, Literal

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from darksynth.errors import DarksynthError
from darksynth.evaluation.methods.method import NoiseMethod
from darksynth.evaluation.pairs import LoadedPair
from darksynth.seeding import derive_seed, seeded_generator
from darksynth.training.scaffold import Report, StepPlan, run_steps

LEAK = 0.1
"""Slope of the denoiser's activations below zero."""

DENOISER_SIZES = {"small": (16, 5), "dncnn": (64, 17)}
"""The downstream denoiser's (width, depth) by name: ``small``, the default, trains in about 25 s per method on a CPU;
``dncnn`` is DnCNN's (Zhang et al. 2017), for a GPU and tens of thousands of steps."""

Progress = Callable[[str], None]


@dataclass(frozen=True)
class DownstreamSettings:
    """Training budget and denoiser of the downstream check; identical for every method.

    The defaults suit a shared 2-core CPU: a 5-layer, 16-channel denoiser trained on 6000 crops of 64
    pixels, about 25 s with one thread. Many small steps learn far more than few large ones at the same
    number of crops (on synthetic Poisson-Gaussian noise of 2-6/255: +3.4 dB with 3000 steps of 2 crops,
    +0.4 dB with 250 steps of 16), hence the small batch. With a GPU, a wider and deeper denoiser (e.g.
    width 64, depth 17 as DnCNN), larger batches and more steps give a sharper comparison.

    Attributes:
        steps: optimiser steps per training.
        batch: crops per step.
        crop: side of the square training crops (clean images smaller than this are left out).
        learning_rate: Adam's initial rate, decayed to zero along a cosine over the steps.
        seed: source of every random choice (weights, crops, parameter draws, noise).
        device: where the denoiser trains and runs; synthesis stays on the CPU.
        width: feature channels of the denoiser.
        depth: convolution layers of the denoiser (at least 2).
        loss: "l1" or "mse" between the denoised crop and the clean one.
        folds: the set's pairs split so, each camera's in turn (:func:`camera_folds`), for the rows tested on pairs
            their training never saw: :data:`REAL_PAIRS` and the methods of :data:`OTHER_IMAGES_METHODS` (fewer than
            2: no such rows).
    """

    steps: int = 3000
    batch: int = 2
    crop: int = 64
    learning_rate: float = 1e-3
    seed: int = 0
    device: str = "cpu"
    width: int = 16
    depth: int = 5
    loss: Literal["l1", "mse"] = "l1"
    folds: int = 2

    def __post_init__(self) -> None:
        if self.steps < 1 or self.batch < 1 or self.crop < 8:
            raise ValueError("steps and batch must be at least 1 and crop at least 8")
        if self.depth < 2 or self.width < 1:
            raise ValueError("the denoiser needs a depth of at least 2 and a width of at least 1")
        if self.loss not in ("l1", "mse"):
            raise ValueError(f"unknown loss {self.loss!r}: l1 or mse")
        if self.folds < 0:
            raise ValueError("folds must be at least 0 (under 2: no rows tested on unseen folds)")


class ResidualDenoiser(nn.Module):
    """DnCNN-like: 3x3 convolutions with leaky ReLUs predict the noise, the output is the input minus it.

    Two departures from DnCNN, both measured on this budget: the convolutions see the input centred on
    mid-grey (x - 0.5), which learns about three times the PSNR gain of the uncentred input in the same
    steps; and the ReLUs leak (slope LEAK below zero): with plain ReLUs, training on the mixed noise levels
    fitted on polyu's pairs killed the last layer's units and left the denoiser an exact identity.
    Fully convolutional (reflect padding), so it takes images of any size (N, 3, H, W); no batch
    normalisation, so training and testing behave alike. ``training_losses`` holds the loss of every step
    of :func:`train_denoiser`, ``input_losses`` the same loss of the step's noisy input (an identity's).
    """

    def __init__(self, width: int = 16, depth: int = 5, *, seed: int = 0) -> None:
        super().__init__()
        channels = [3] + [width] * (depth - 1) + [3]
        layers: list[nn.Module] = []
        for index, (inputs, outputs) in enumerate(pairwise(channels)):
            layers.append(nn.Conv2d(inputs, outputs, 3, padding=1, padding_mode="reflect"))
            if index < depth - 1:
                layers.append(nn.LeakyReLU(LEAK, inplace=True))
        self.body = nn.Sequential(*layers)
        self.training_losses: list[float] = []
        self.input_losses: list[float] = []
        self._initialise(seed)

    def _initialise(self, seed: int) -> None:
        # Own generator: the same seed gives the same weights whatever the global RNG went through.
        generator = seeded_generator(derive_seed("darksynth", seed, "downstream/weights"))
        convolutions = [m for m in self.body if isinstance(m, nn.Conv2d)]
        with torch.no_grad():
            for index, convolution in enumerate(convolutions):
                nn.init.kaiming_normal_(convolution.weight, nonlinearity="relu", generator=generator)
                if index == len(convolutions) - 1:
                    convolution.weight.mul_(0.1)  # start near the identity: a small predicted noise
                if convolution.bias is not None:
                    nn.init.zeros_(convolution.bias)

    def forward(self, noisy: torch.Tensor) -> torch.Tensor:
        predicted_noise: torch.Tensor = self.body(noisy - 0.5)
        return noisy - predicted_noise


def build_denoiser(settings: DownstreamSettings) -> ResidualDenoiser:
    """The untrained denoiser of the settings, on their device (same initial weights on every device)."""
    return ResidualDenoiser(settings.width, settings.depth, seed=settings.seed).to(settings.device)


def _usable_images(clean_images: Sequence[np.ndarray], crop: int) -> list[np.ndarray]:
    usable = []
    for image in clean_images:
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"clean training images must be uint8 (H, W, 3), got {image.dtype} {image.shape}")
        if min(image.shape[:2]) >= crop:
            usable.append(image)
    if not usable:
        raise DarksynthError(f"no clean training image has both sides of at least {crop} pixels")
    return usable


def _integer(high: int, generator: torch.Generator) -> int:
    return int(torch.randint(0, high, (), generator=generator))


def _randomly_flipped(image: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """The image (..., H, W) as it is, mirrored left to right, upside down or both, at random."""
    flips = _integer(4, generator)
    if flips & 1:
        image = image.flip(-1)
    if flips & 2:
        image = image.flip(-2)
    return image


def _clean_crops(images: Sequence[np.ndarray], batch: int, crop: int, generator: torch.Generator) -> torch.Tensor:
    """(batch, 3, crop, crop) float64 crops on 8-bit levels, with random flips."""
    out = torch.empty(batch, 3, crop, crop, dtype=torch.float64)
    for index in range(batch):
        image = images[_integer(len(images), generator)]
        top = _integer(image.shape[0] - crop + 1, generator)
        left = _integer(image.shape[1] - crop + 1, generator)
        patch = torch.from_numpy(np.ascontiguousarray(image[top : top + crop, left : left + crop]))
        out[index] = _randomly_flipped(patch.permute(2, 0, 1).to(torch.float64) / 255.0, generator)
    return out


Batch = Callable[[], tuple[torch.Tensor, torch.Tensor]]
"""Makes one training batch: (noisy, clean), each (batch, 3, crop, crop) on 8-bit levels."""


def _synthetic_batches(
    method: NoiseMethod, parameters_list: Sequence[Any], images: Sequence[np.ndarray], settings: DownstreamSettings
) -> Batch:
    """Random crops of the clean images (the same for every method of a seed), each made noisy by the method with a
    random entry of ``parameters_list``."""
    crops = seeded_generator(derive_seed("darksynth", settings.seed, "downstream/crops"))
    draws = seeded_generator(derive_seed("darksynth", settings.seed, "downstream/parameters"))
    noise = seeded_generator(derive_seed("darksynth", settings.seed, "downstream/noise"))

    def batch() -> tuple[torch.Tensor, torch.Tensor]:
        clean = _clean_crops(images, settings.batch, settings.crop, crops)
        choices = torch.randint(0, len(parameters_list), (settings.batch,), generator=draws).tolist()
        noisy = torch.stack(
            [
                method.synthesize(crop, parameters_list[choice], noise)
                for crop, choice in zip(clean, choices, strict=True)
            ]
        )
        return noisy, clean

    return batch


def _real_batches(pairs: Sequence[LoadedPair], settings: DownstreamSettings) -> Batch:
    """Random crops of real pairs, the same place in the noisy and the clean image, with the same random flips."""
    crops = seeded_generator(derive_seed("darksynth", settings.seed, "downstream/real-crops"))
    usable = [pair for pair in pairs if min(pair.clean.shape[-2:]) >= settings.crop]
    if not usable:
        raise DarksynthError(f"no real pair has both sides of at least {settings.crop} pixels")

    def batch() -> tuple[torch.Tensor, torch.Tensor]:
        noisy, clean = [], []
        for _ in range(settings.batch):
            pair = usable[_integer(len(usable), crops)]
            top = _integer(pair.clean.shape[-2] - settings.crop + 1, crops)
            left = _integer(pair.clean.shape[-1] - settings.crop + 1, crops)
            both = torch.stack([pair.noisy, pair.clean])[..., top : top + settings.crop, left : left + settings.crop]
            both = _randomly_flipped(both, crops)
            noisy.append(both[0])
            clean.append(both[1])
        return torch.stack(noisy), torch.stack(clean)

    return batch


class _DenoiserSteps:
    """The denoiser's part of :func:`~darksynth.training.scaffold.run_steps`: an Adam step on a training batch
    (cosine learning rate), and at a report a progress line."""

    def __init__(self, label: str, batch: Batch, settings: DownstreamSettings, progress: Progress | None) -> None:
        self.label, self.batch, self.settings, self.progress = label, batch, settings, progress
        self.model = build_denoiser(settings)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=settings.learning_rate)
        self.loss_function = F.l1_loss if settings.loss == "l1" else F.mse_loss

    def train_step(self, step: int) -> dict[str, float]:
        settings, model = self.settings, self.model
        for group in self.optimizer.param_groups:
            group["lr"] = settings.learning_rate * 0.5 * (1.0 + math.cos(math.pi * (step - 1) / settings.steps))
        noisy, clean = self.batch()
        clean_batch = clean.to(device=settings.device, dtype=torch.float32)
        noisy_batch = noisy.to(device=settings.device, dtype=torch.float32)
        loss = self.loss_function(model(noisy_batch), clean_batch)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]
        self.optimizer.step()
        model.training_losses.append(float(loss.detach()))
        model.input_losses.append(float(self.loss_function(noisy_batch, clean_batch)))
        return {"loss": model.training_losses[-1]}

    def report(self, report: Report) -> dict[str, Any]:
        loss = report.mean_losses["loss"]
        if self.progress is not None:
            self.progress(
                f"{self.label}: step {report.step}/{self.settings.steps}, loss {loss:.5f}, {report.seconds:.0f} s"
            )
        return {"step": report.step, "loss": loss}


def _trained(steps: _DenoiserSteps) -> ResidualDenoiser:
    steps.model.train()
    run_steps(steps, StepPlan(steps.settings.steps, max(1, steps.settings.steps // 10)))
    steps.model.eval()
    return steps.model


def train_denoiser(
    method: NoiseMethod,
    parameters_list: Sequence[Any],
    clean_images: Sequence[np.ndarray],
    settings: DownstreamSettings,
    *,
    progress: Progress | None = None,
) -> ResidualDenoiser:
    """Train the settings' denoiser on the method's synthetic noise.

    Each step draws ``batch`` random crops of the clean images (uint8 (H, W, 3)), the same crops for every
    method, and for each crop a random entry of ``parameters_list``, with which ``method.synthesize`` makes
    its noisy version; the denoiser learns to map it back to the clean crop. ``progress`` gets a line ten times
    over the run (the mean loss since the previous line).

    Raises:
        DarksynthError: no parameters, or no clean image as large as the crop.
    """
    if not parameters_list:
        raise DarksynthError(f"{method.name}: no fitted parameters to synthesise training noise with")
    batch = _synthetic_batches(method, parameters_list, _usable_images(clean_images, settings.crop), settings)
    return _trained(_DenoiserSteps(method.name, batch, settings, progress))


def train_on_real_pairs(
    pairs: Sequence[LoadedPair], settings: DownstreamSettings, *, progress: Progress | None = None
) -> ResidualDenoiser:
    """The settings' denoiser trained on random crops of real pairs (noisy in, clean out): what real data of the
    camera gives, the ceiling a synthetic method is measured against.

    Raises:
        DarksynthError: no pair as large as the crop.
    """
    return _trained(_DenoiserSteps("real pairs", _real_batches(pairs, settings), settings, progress))


def denoise(model: nn.Module, noisy: torch.Tensor) -> torch.Tensor:
    """The model's output for one image (3, H, W) in one pass, clipped to [0, 1], float64 on the CPU."""
    device = next(model.parameters()).device
    was_training = model.training
    model.eval()
    with torch.no_grad():
        output: torch.Tensor = model(noisy.to(device=device, dtype=torch.float32)[None])[0]
    model.train(was_training)
    return output.clamp(0.0, 1.0).to(device="cpu", dtype=torch.float64)


def training_summary(model: ResidualDenoiser) -> dict[str, float]:
    """Mean training loss over the last tenth of the steps, and that of the noisy inputs over the same steps:
    how much the denoiser learned on its own synthetic data (equal losses: it stayed an identity)."""
    tail = max(1, len(model.training_losses) // 10)
    return {
        "loss": float(np.mean(model.training_losses[-tail:])),
        "input_loss": float(np.mean(model.input_losses[-tail:])),
    }
