"""Downstream check: a small denoiser trained on each method's synthetic noise, tested on real pairs.

In the spirit of the paper's enhancement experiment, scaled to a CPU: for each set of real pairs and each
method, the method's parameters are fitted on every real pair of the set (zero-shot methods from the noisy
image, oracle methods from the pair); a small residual denoiser (DnCNN-like) is then trained on random crops
of clean training images made noisy by the method with those parameters, and tested on the set's real pairs
(PSNR and SSIM of its output against the clean image, the unprocessed noisy input as a reference row).

Every method gets the same budget: the same initial weights, the same clean crops in the same order, the same
parameter draws and the same number of steps; only the synthetic noise differs. Everything derives from
``DownstreamSettings.seed``, so the same seed gives the same numbers (on one device and thread count).

LPIPS is not computed (see LPIPS_STATUS).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from darksynth.errors import DarksynthError
from darksynth.evaluation.methods.catalogue import NoiseMethod, build_methods
from darksynth.evaluation.pairs import LoadedPair, Pair, PairSet, list_pair_sets, load_pair
from darksynth.seeding import derive_seed, seeded_generator
from darksynth.training.scaffold import Report, StepPlan, run_steps

LPIPS_STATUS = (
    "not computed: the PyPI package lpips (0.1.4) ships only its small linear layers (lpips/weights/v0.1/"
    "alex.pth, vgg.pth, squeeze.pth) and takes its AlexNet/VGG/SqueezeNet backbone from torchvision with "
    "pretrained=True, i.e. ImageNet weights downloaded at run time; piq (0.8.0) also downloads both the "
    "torchvision VGG16 weights and its LPIPS layers at run time. Neither can work offline, and both also need "
    "torchvision, which is not installed (it is not a dependency of darksynth)"
)
"""Why the downstream check reports no LPIPS."""

LEAK = 0.1
"""Slope of the denoiser's activations below zero."""

NOISY_INPUT = "noisy input"
"""Row of the unprocessed real noisy image: the reference that a useful denoiser must beat."""

DENOISER_SIZES = {"small": (16, 5), "dncnn": (64, 17)}
"""The downstream denoiser's (width, depth) by name: ``small``, the default, trains in about 25 s per method on a CPU;
``dncnn`` is DnCNN's (Zhang et al. 2017), for a GPU and tens of thousands of steps."""

REAL_PAIRS = "real pairs (other folds)"
"""Row of the denoiser trained on the set's real pairs of the other folds: the ceiling (never ranked)."""

OTHER_IMAGES_METHODS = ("den",)
"""Methods that also get a row trained on parameters fitted on the other folds' noisy images only (the user's case:
a profile from a few photos of the camera, then a whole dataset), named ``"<method> (other images)"``."""

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


def fit_reference_parameters(
    method: NoiseMethod, loaded_pairs: Iterable[LoadedPair], problems: list[str] | None = None
) -> list[Any]:
    """The method's parameters fitted on each real pair (zero-shot methods read only the noisy image).

    Args:
        problems: where a failed fit is recorded (the pair is then skipped); without it the error propagates.

    Raises:
        DarksynthError: a failed fit, when ``problems`` is None.
    """
    fitted = []
    for loaded in loaded_pairs:
        try:
            fitted.append(method.fit(loaded.noisy, loaded.clean))
        except DarksynthError as error:
            if problems is None:
                raise
            problems.append(f"{loaded.pair.noisy_path}: {method.name}: {error}")
    return fitted


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


def _clean_crops(images: Sequence[np.ndarray], batch: int, crop: int, generator: torch.Generator) -> torch.Tensor:
    """(batch, 3, crop, crop) float64 crops on 8-bit levels, with random flips."""

    def integer(high: int) -> int:
        return int(torch.randint(0, high, (), generator=generator))

    out = torch.empty(batch, 3, crop, crop, dtype=torch.float64)
    for index in range(batch):
        image = images[integer(len(images))]
        top = integer(image.shape[0] - crop + 1)
        left = integer(image.shape[1] - crop + 1)
        patch = torch.from_numpy(np.ascontiguousarray(image[top : top + crop, left : left + crop]))
        patch = patch.permute(2, 0, 1).to(torch.float64) / 255.0
        flips = integer(4)
        if flips & 1:
            patch = patch.flip(-1)
        if flips & 2:
            patch = patch.flip(-2)
        out[index] = patch
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

    def integer(high: int) -> int:
        return int(torch.randint(0, high, (), generator=crops))

    usable = [pair for pair in pairs if min(pair.clean.shape[-2:]) >= settings.crop]
    if not usable:
        raise DarksynthError(f"no real pair has both sides of at least {settings.crop} pixels")

    def batch() -> tuple[torch.Tensor, torch.Tensor]:
        noisy, clean = [], []
        for _ in range(settings.batch):
            pair = usable[integer(len(usable))]
            top = integer(pair.clean.shape[-2] - settings.crop + 1)
            left = integer(pair.clean.shape[-1] - settings.crop + 1)
            both = torch.stack([pair.noisy, pair.clean])[..., top : top + settings.crop, left : left + settings.crop]
            flips = integer(4)
            if flips & 1:
                both = both.flip(-1)
            if flips & 2:
                both = both.flip(-2)
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
    return _trained(_DenoiserSteps(REAL_PAIRS, _real_batches(pairs, settings), settings, progress))


def denoise(model: nn.Module, noisy: torch.Tensor) -> torch.Tensor:
    """The model's output for one image (3, H, W) in one pass, clipped to [0, 1], float64 on the CPU."""
    device = next(model.parameters()).device
    was_training = model.training
    model.eval()
    with torch.no_grad():
        output: torch.Tensor = model(noisy.to(device=device, dtype=torch.float32)[None])[0]
    model.train(was_training)
    return output.clamp(0.0, 1.0).to(device="cpu", dtype=torch.float64)


def image_scores(image: torch.Tensor, clean: torch.Tensor) -> dict[str, float]:
    """PSNR (dB, peak 1) and SSIM (scikit-image, channel_axis, data_range 1) of an image (3, H, W)."""
    from skimage.metrics import structural_similarity

    mse = float((image - clean).square().mean())
    psnr = 10.0 * math.log10(1.0 / max(mse, 1e-12))
    ssim = structural_similarity(  # type: ignore[no-untyped-call]
        image.numpy(), clean.numpy(), channel_axis=0, data_range=1.0
    )
    return {"psnr": psnr, "ssim": float(ssim)}


def _mean_scores(rows: list[dict[str, float]]) -> dict[str, Any]:
    if not rows:
        return {"psnr": None, "ssim": None, "pairs": 0}
    return {
        "psnr": float(np.mean([r["psnr"] for r in rows])),
        "ssim": float(np.mean([r["ssim"] for r in rows])),
        "pairs": len(rows),
    }


def test_denoiser(model: nn.Module, loaded_pairs: Iterable[LoadedPair], *, reference: bool = True) -> dict[str, Any]:
    """Mean PSNR and SSIM of the model's output against the clean image over real pairs (whole images).

    Returns:
        ``{"psnr", "ssim", "pairs"}``, plus under NOISY_INPUT the same for the unprocessed noisy images when
        ``reference``. ``loaded_pairs`` may be a lazy iterable: each pair is used once.
    """
    denoised: list[dict[str, float]] = []
    unprocessed: list[dict[str, float]] = []
    for loaded in loaded_pairs:
        denoised.append(image_scores(denoise(model, loaded.noisy), loaded.clean))
        if reference:
            unprocessed.append(image_scores(loaded.noisy, loaded.clean))
    result = _mean_scores(denoised)
    if reference:
        result[NOISY_INPUT] = _mean_scores(unprocessed)
    return result


test_denoiser.__test__ = False  # type: ignore[attr-defined]  # not a pytest test despite its name


def _loaded(pairs: Sequence[Pair], problems: list[str] | None) -> Iterator[LoadedPair]:
    """The pairs read one at a time; unreadable ones are recorded (when ``problems`` is given) and skipped."""
    for pair in pairs:
        try:
            yield load_pair(pair)
        except DarksynthError as error:
            if problems is not None:
                problems.append(str(error))


def training_summary(model: ResidualDenoiser) -> dict[str, float]:
    """Mean training loss over the last tenth of the steps, and that of the noisy inputs over the same steps:
    how much the denoiser learned on its own synthetic data (equal losses: it stayed an identity)."""
    tail = max(1, len(model.training_losses) // 10)
    return {
        "loss": float(np.mean(model.training_losses[-tail:])),
        "input_loss": float(np.mean(model.input_losses[-tail:])),
    }


def _prefixed(progress: Progress, prefix: str) -> Progress:
    return lambda message: progress(f"{prefix}: {message}")


def _constant(parameters: Sequence[Any]) -> bool:
    """Whether every entry equals the first (fixed methods): their training does not depend on the set."""
    try:
        return all(bool(entry == parameters[0]) for entry in parameters[1:])
    except (RuntimeError, TypeError, ValueError):  # e.g. dicts of tensors: compared element-wise, not as a whole
        return False


def _fit_on_set(
    pair_set: PairSet, built: dict[str, NoiseMethod], problems: list[str], say: Progress
) -> dict[str, dict[str, Any]]:
    """Every method's parameters fitted on every readable pair of a set (zero-shot methods on the noisy image), by
    pair name."""
    say(f"{pair_set.name}: fitting {len(built)} methods on {len(pair_set.pairs)} pairs")
    fitted: dict[str, dict[str, Any]] = {name: {} for name in built}
    for index, loaded in enumerate(_loaded(pair_set.pairs, problems)):
        if index % 25 == 24:
            say(f"{pair_set.name}: fitted on {index + 1} pairs")
        for name, method in built.items():
            for parameters in fit_reference_parameters(method, [loaded], problems):
                fitted[name][loaded.pair.name] = parameters
    return fitted


def camera_folds(pairs: Sequence[Pair], folds: int) -> list[int]:
    """Each pair's fold: the pairs ordered by camera, then name, go to the folds in turn, so that every fold holds
    pairs of every camera that has as many pairs as folds (and no fold is empty while there are as many pairs)."""
    order = sorted(range(len(pairs)), key=lambda index: (pairs[index].camera, pairs[index].name))
    fold_of = [0] * len(pairs)
    for position, index in enumerate(order):
        fold_of[index] = position % folds
    return fold_of


def _scores_on(model: nn.Module, pairs: Iterable[LoadedPair]) -> list[dict[str, float]]:
    return [image_scores(denoise(model, loaded.noisy), loaded.clean) for loaded in pairs]


def _cross_fold_rows(
    pair_set: PairSet,
    built: dict[str, NoiseMethod],
    fitted: dict[str, dict[str, Any]],
    images: Sequence[np.ndarray],
    settings: DownstreamSettings,
    problems: list[str],
    say: Progress,
) -> dict[str, Any]:
    """The rows whose denoisers are tested on the folds their training never saw (:data:`REAL_PAIRS`, the methods of
    :data:`OTHER_IMAGES_METHODS`): per fold, trained on the other folds' pairs, tested on its own; the scores are
    the mean over every pair so tested."""
    fold_of = dict(
        zip((pair.name for pair in pair_set.pairs), camera_folds(pair_set.pairs, settings.folds), strict=True)
    )
    others = [name for name in OTHER_IMAGES_METHODS if name in built]
    rows: dict[str, list[dict[str, float]]] = {
        name: [] for name in (REAL_PAIRS, *(f"{n} (other images)" for n in others))
    }
    for fold in range(settings.folds):
        training = [pair for pair in pair_set.pairs if fold_of[pair.name] != fold]
        tested = [pair for pair in pair_set.pairs if fold_of[pair.name] == fold]
        if not training or not tested:
            continue
        say(f"{pair_set.name}: fold {fold + 1}/{settings.folds}: training on {len(training)} real pairs")
        try:
            model = train_on_real_pairs(
                list(_loaded(training, problems)), settings, progress=_prefixed(say, pair_set.name)
            )
            rows[REAL_PAIRS] += _scores_on(model, _loaded(tested, None))
        except DarksynthError as error:
            problems.append(f"{pair_set.name}: {REAL_PAIRS}: fold {fold + 1}: {error}")
        for name in others:
            parameters = [fitted[name][pair.name] for pair in training if pair.name in fitted[name]]
            if not parameters:
                continue
            say(f"{pair_set.name}: fold {fold + 1}/{settings.folds}: {name} on the other folds' noisy images")
            model = train_denoiser(built[name], parameters, images, settings, progress=_prefixed(say, pair_set.name))
            rows[f"{name} (other images)"] += _scores_on(model, _loaded(tested, None))
    return {name: _mean_scores(scores) | {"folds": settings.folds} for name, scores in rows.items() if scores}


def _denoiser_for(
    name: str,
    method: NoiseMethod,
    parameters: list[Any],
    trained_constant: dict[str, tuple[Any, ResidualDenoiser]],
    images: Sequence[np.ndarray],
    settings: DownstreamSettings,
    pair_set: PairSet,
    say: Progress,
) -> ResidualDenoiser:
    """The denoiser trained on a method's noise with the parameters fitted on a set; a method whose parameters are
    the same fixed ones on every pair (of this set and one before) reuses the one trained for them."""
    cached = trained_constant.get(name)
    if cached is not None and _constant(parameters) and _constant([cached[0], parameters[0]]):
        say(f"{pair_set.name}: {name}: same fixed parameters as before, denoiser reused")
        return cached[1]
    say(f"{pair_set.name}: training on {name}'s noise")
    model = train_denoiser(
        method,
        parameters[:1] if _constant(parameters) else parameters,
        images,
        settings,
        progress=_prefixed(say, pair_set.name),
    )
    if _constant(parameters):
        trained_constant[name] = (parameters[0], model)
    return model


def run_downstream(
    pair_roots: Sequence[Path],
    methods: Sequence[str],
    clean_roots: Sequence[Path],
    settings: DownstreamSettings,
    *,
    weights: dict[str, Path] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Train and test one denoiser per set and method; report PSNR and SSIM per set.

    Returns:
        ``{"settings": {...}, "lpips": "not computed: ...", "clean_images": {...}, "methods": {name: summary},
        "<set>": {"noisy input": {"psnr", "ssim", "pairs"}, "<method>": {"psnr", "ssim", "pairs", "training":
        {"loss", "input_loss"}}}, "problems": [...],
        "seconds": ...}``. Unavailable methods, unreadable pairs and failed fits are listed under "problems".

    Raises:
        DarksynthError: no method can run, no set can be read, or no clean training image is usable.
    """
    from darksynth.training.corpus import load_corpus

    say = progress or (lambda message: None)
    started = time.perf_counter()
    built, problems = build_methods(methods, weights=weights, device=settings.device)
    pair_sets, listing_problems = list_pair_sets(pair_roots)
    problems.extend(listing_problems)
    corpus = load_corpus(list(clean_roots), minimum_side=settings.crop)
    if not corpus.images:
        raise DarksynthError(f"no clean still image of at least {settings.crop} pixels in {list(clean_roots)}")
    results: dict[str, Any] = {
        "settings": asdict(settings),
        "lpips": LPIPS_STATUS,
        "clean_images": {"roots": [str(r) for r in clean_roots], "count": len(corpus.images)},
        "methods": {name: {"oracle": m.oracle, "summary": m.summary} for name, m in built.items()},
    }
    # Fixed methods fit the same parameters on every pair of every set: their denoiser is trained once.
    trained_constant: dict[str, tuple[Any, ResidualDenoiser]] = {}
    for pair_set in pair_sets:
        problems.extend(pair_set.problems)
        fitted = _fit_on_set(pair_set, built, problems, say)
        set_results: dict[str, Any] = {}
        reference_done = False
        for name, method in built.items():
            parameters = list(fitted[name].values())
            if not parameters:
                problems.append(f"{pair_set.name}: {name}: no pair could be fitted; not trained")
                continue
            model = _denoiser_for(name, method, parameters, trained_constant, corpus.images, settings, pair_set, say)
            say(f"{pair_set.name}: testing {name}'s denoiser on the real pairs")
            scores = test_denoiser(model, _loaded(pair_set.pairs, None), reference=not reference_done)
            if not reference_done:
                set_results[NOISY_INPUT] = scores.pop(NOISY_INPUT)
                reference_done = True
            scores["training"] = training_summary(model)
            set_results[name] = scores
        if settings.folds >= 2:
            set_results |= _cross_fold_rows(pair_set, built, fitted, corpus.images, settings, problems, say)
        results[pair_set.name] = set_results
    results["problems"] = problems
    results["seconds"] = round(time.perf_counter() - started, 1)
    return results
