"""`darksynth evaluate`: every method on every real pair, metrics per pair, per camera and per set.

For each pair the real noise map is noisy - clean; each method makes a synthetic noisy image from the clean
one (8-bit, like the real one) and its noise map is synthetic - clean. Histogram KL divergences are computed
per pair and summarised by their mean and a 95% interval; FID and KID compare, per set, the Inception
features of crops of all real noise maps with those of all of a method's maps.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.evaluation.methods import NoiseMethod, build_methods
from darksynth.evaluation.metrics import (
    frechet_distance,
    kernel_inception_distance,
    kl_divergence_noise_flow,
    kl_divergence_srgb,
    mean_and_interval,
)
from darksynth.evaluation.options import EvaluationOptions
from darksynth.evaluation.pairs import LoadedPair, PairSet, list_pair_sets, load_pair
from darksynth.evaluation.report import ReportExample
from darksynth.seeding import derive_seed, seeded_generator

METRIC_DESCRIPTIONS = {
    "kld": "KL(real || synthetic) of noise histograms, Noise Flow recipe (Abdelhamed et al. 2019): [0, 1] scale, "
    "64 bins of width 0.2/64 over [-0.1, 0.1] plus an overflow bin each side, summed where both are non-zero",
    "kld_srgb": "KL(real || synthetic), sRGB recipe of Kousha et al. 2022: 8-bit units, bins of width 4 over "
    "[-260, 260], add-one smoothing",
    "fid": "Frechet distance between InceptionV3 pool features of crops of the real and of the synthetic noise maps",
    "kid": "Kernel Inception distance (unbiased MMD^2, cubic polynomial kernel) on the same features",
}


FID_CROP = 128
"""Side of the noise-map tiles whose Inception features FID and KID compare."""


@dataclass
class EvaluationOutcome:
    results: dict[str, Any]
    examples: list[ReportExample]


Progress = Callable[[str], None]


def _summary(values: list[float]) -> tuple[float, list[float]]:
    mean, low, high = mean_and_interval(values)
    return float(mean), [float(low), float(high)]


def _kl_summary(rows: list[dict[str, float]]) -> dict[str, Any]:
    summary: dict[str, Any] = {}
    for metric in ("kld", "kld_srgb"):
        mean, interval = _summary([row[metric] for row in rows])
        summary[metric] = mean
        summary[f"{metric}_ci95"] = interval
    return summary


def _center_crop(image: torch.Tensor, side: int) -> np.ndarray:
    _, height, width = image.shape
    top, left = max(0, (height - side) // 2), max(0, (width - side) // 2)
    crop = image[:, top : top + side, left : left + side]
    return (crop.permute(1, 2, 0).numpy() * 255.0).round().clip(0, 255).astype(np.uint8)


def _noise_array(noise: torch.Tensor) -> np.ndarray:
    return noise.permute(1, 2, 0).numpy().astype(np.float32)


class _Features:
    """Inception features of noise maps, accumulated per set and per source (real or a method)."""

    def __init__(self, device: str, problems: list[str]) -> None:
        self.extractor: Any = None
        try:
            from darksynth.evaluation.inception import InceptionFeatures

            self.extractor = InceptionFeatures(device=device)
        except DarksynthError as error:
            problems.append(f"fid/kid: {error}")
        self.collected: dict[str, list[np.ndarray]] = {}

    def add(self, source: str, noise: torch.Tensor, crops: int) -> None:
        """Features of ``crops`` tiles spread evenly over the map (all of them if it has fewer)."""
        if self.extractor is None:
            return
        from darksynth.evaluation.inception import noise_map_images

        side = min(FID_CROP, noise.shape[-2], noise.shape[-1])
        images = noise_map_images(_noise_array(noise), crop=side)
        chosen = np.unique(np.linspace(0, len(images) - 1, min(crops, len(images))).round().astype(int))
        self.collected.setdefault(source, []).append(self.extractor.features(images[chosen]))

    def distances(self, method: str) -> dict[str, float | None]:
        if self.extractor is None or method not in self.collected or "real" not in self.collected:
            return {"fid": None, "kid": None, "kid_std": None}
        real = np.concatenate(self.collected["real"])
        synthetic = np.concatenate(self.collected[method])
        # Subsets of half the smaller set: the spread over subsets then says something (with subsets of
        # the whole set every round would see the same vectors).
        kid, kid_std = kernel_inception_distance(
            real, synthetic, subset_size=max(2, min(len(real), len(synthetic)) // 2)
        )
        return {"fid": float(frechet_distance(real, synthetic)), "kid": float(kid), "kid_std": float(kid_std)}


def _evaluate_set(
    pair_set: PairSet,
    methods: dict[str, NoiseMethod],
    options: EvaluationOptions,
    problems: list[str],
    features: _Features | None,
    progress: Progress,
) -> tuple[dict[str, Any], list[ReportExample]]:
    rows: dict[str, list[tuple[str, dict[str, float]]]] = {name: [] for name in methods}
    examples: list[ReportExample] = []
    evaluated = 0
    # Inception features cost ~0.1 s a tile on this CPU: a fixed budget per set keeps the run short.
    crops_per_pair = max(1, -(-options.fid_crops // max(len(pair_set.pairs), 1)))
    for index, pair in enumerate(pair_set.pairs):
        progress(f"{pair_set.name}: pair {index + 1}/{len(pair_set.pairs)} {pair.name}")
        try:
            loaded: LoadedPair = load_pair(pair)
        except DarksynthError as error:
            problems.append(str(error))
            continue
        evaluated += 1
        real = loaded.noise
        if features is not None:
            features.add("real", real, crops_per_pair)
        keep_example = len(examples) < options.examples_per_set
        noisy_crops = {"real": _center_crop(loaded.noisy, options.example_crop)}
        noise_maps = {"real": _noise_array(real)}
        for name, method in methods.items():
            generator = seeded_generator(derive_seed("darksynth", options.seed, f"{pair_set.name}/{pair.name}/{name}"))
            try:
                parameters = method.fit(loaded.noisy, loaded.clean)
                synthetic = method.synthesize(loaded.clean, parameters, generator)
            except DarksynthError as error:
                problems.append(f"{pair.noisy_path}: {name}: {error}")
                continue
            noise = synthetic - loaded.clean
            rows[name].append(
                (
                    pair.camera,
                    {
                        "kld": kl_divergence_noise_flow(real.numpy(), noise.numpy()),
                        "kld_srgb": kl_divergence_srgb(real.numpy(), noise.numpy()),
                    },
                )
            )
            if features is not None:
                features.add(name, noise, crops_per_pair)
            if keep_example:
                noisy_crops[name] = _center_crop(synthetic, options.example_crop)
                noise_maps[name] = _noise_array(noise)
        if keep_example:
            examples.append(
                ReportExample(
                    set_name=pair_set.name,
                    pair_name=pair.name,
                    clean=_center_crop(loaded.clean, options.example_crop),
                    noisy=noisy_crops,
                    noise=noise_maps,
                )
            )
    report: dict[str, Any] = {"pairs": evaluated, "methods": {}}
    for name, method_rows in rows.items():
        if not method_rows:
            continue
        entry = _kl_summary([row for _, row in method_rows])
        entry.update(features.distances(name) if features is not None else {"fid": None, "kid": None, "kid_std": None})
        entry["oracle"] = methods[name].oracle
        cameras: dict[str, list[dict[str, float]]] = {}
        for camera, row in method_rows:
            cameras.setdefault(camera, []).append(row)
        entry["per_camera"] = {
            camera: {"pairs": len(camera_rows), **_kl_summary(camera_rows)} for camera, camera_rows in cameras.items()
        }
        report["methods"][name] = entry
    return report, examples


def evaluate_pairs(
    pair_roots: Sequence[Path], options: EvaluationOptions, *, progress: Progress | None = None
) -> EvaluationOutcome:
    """Evaluate every available method on every set of pairs.

    Problems (a bad pair, an unavailable method, a failed fit) are recorded in ``results["problems"]`` and the
    rest goes on.

    Raises:
        DarksynthError: no set could be listed, or no method is available: nothing to evaluate.
    """
    progress = progress or (lambda message: None)
    started = time.perf_counter()
    methods, problems = build_methods(options.methods, weights=options.weights, device=options.device)
    try:
        pair_sets, listing_problems = list_pair_sets(pair_roots)
    except DarksynthError as error:
        raise DarksynthError(f"{error}; {'; '.join(problems)}" if problems else str(error)) from None
    problems.extend(listing_problems)
    results: dict[str, Any] = {
        "command": options.command,
        "seed": options.seed,
        "metrics": METRIC_DESCRIPTIONS,
        "methods": {name: {"oracle": m.oracle, "summary": m.summary, **m.details} for name, m in methods.items()},
        "provenance": {},
        "sets": {},
        "problems": problems,
        "downstream": None,
    }
    examples: list[ReportExample] = []
    features = _Features(options.device, problems) if options.inception else None
    if features is not None and features.extractor is not None:
        from darksynth.evaluation.inception import INCEPTION_PROVENANCE

        results["provenance"]["inception"] = INCEPTION_PROVENANCE
    for pair_set in pair_sets:
        problems.extend(pair_set.problems)
        if features is not None:
            features.collected = {}
        set_report, set_examples = _evaluate_set(pair_set, methods, options, problems, features, progress)
        results["sets"][pair_set.name] = set_report
        examples.extend(set_examples)
    results["seconds"] = round(time.perf_counter() - started, 1)
    return EvaluationOutcome(results=results, examples=examples)
