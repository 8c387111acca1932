"""Downstream check: a small denoiser trained on each method's synthetic noise, tested on real pairs.

In the spirit of the paper's enhancement experiment, scaled to a CPU: for each set of real pairs and each
method, the method's parameters are fitted on every real pair of the set (zero-shot methods from the noisy
image, oracle methods from the pair); a small residual denoiser (DnCNN-like) is then trained on random crops
of clean training images made noisy by the method with those parameters, and tested on the set's real pairs
(PSNR and SSIM of its output against the clean image, the unprocessed noisy input as a reference row).

Every method gets the same budget (:mod:`darksynth.evaluation.measures.denoiser`: the same initial weights, clean
crops, parameter draws and steps); only the synthetic noise differs, so the same seed gives the same numbers.

LPIPS is not computed (see LPIPS_STATUS).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from darksynth.errors import DarksynthError
from darksynth.evaluation.measures.denoiser import (
    DownstreamSettings,
    ResidualDenoiser,
    denoise,
    train_denoiser,
    train_on_real_pairs,
    training_summary,
)
from darksynth.evaluation.methods.catalogue import build_methods
from darksynth.evaluation.methods.method import NoiseMethod
from darksynth.evaluation.pairs import LoadedPair, Pair, PairSet, list_pair_sets, load_pair

LPIPS_STATUS = (
    "not computed: the PyPI package lpips (0.1.4) ships only its small linear layers (lpips/weights/v0.1/"
    "alex.pth, vgg.pth, squeeze.pth) and takes its AlexNet/VGG/SqueezeNet backbone from torchvision with "
    "pretrained=True, i.e. ImageNet weights downloaded at run time; piq (0.8.0) also downloads both the "
    "torchvision VGG16 weights and its LPIPS layers at run time. Neither can work offline, and both also need "
    "torchvision, which is not installed (it is not a dependency of darksynth)"
)
"""Why the downstream check reports no LPIPS."""

NOISY_INPUT = "noisy input"
"""Row of the unprocessed real noisy image: the reference that a useful denoiser must beat."""

REAL_PAIRS = "real pairs (other folds)"
"""Row of the denoiser trained on the set's real pairs of the other folds: the ceiling (never ranked)."""

OTHER_IMAGES_METHODS = ("den",)
"""Methods that also get a row trained on parameters fitted on the other folds' noisy images only (the user's case:
a profile from a few photos of the camera, then a whole dataset), named ``"<method> (other images)"``."""

Progress = Callable[[str], None]


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
