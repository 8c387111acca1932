"""`darksynth evaluate`: every method on every real pair, metrics per pair, per camera and per set.

For each pair the real noise map is noisy - clean; each method makes a synthetic noisy image from the clean one
(8-bit, like the real one) and its noise map is synthetic - clean. Histogram KL divergences and the AKLD are computed
per pair and summarised by their mean and a 95% interval; the noise level per channel is pooled over a set's pairs
(and divided by the real one's) and the channel correlations averaged over them; the noise's power in five spatial
frequency bands (brightness and colour, :mod:`darksynth.evaluation.measures.structure`) is compared per pair with the
real one's and summarised by the median ratio per band and its RMS log error; FID and KID compare, per set, the
Inception features of crops of all real noise maps with those of all of a method's maps.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.evaluation.measures.metrics import (
    CHANNEL_PAIRS,
    average_kl_divergence,
    channel_correlations,
    channel_moments,
    frechet_distance,
    kernel_inception_distance,
    kl_divergence_naflow,
    kl_divergence_noise_flow,
    kl_divergence_srgb,
    mean_and_interval,
    pooled_std,
)
from darksynth.evaluation.measures.structure import (
    band_medians,
    band_powers,
    band_ratios,
    band_summary,
    prior_band_shares,
    prior_bands,
    relative_to_white,
)
from darksynth.evaluation.measures.texture_ratio import textured_flat_ratio
from darksynth.evaluation.methods.catalogue import build_methods
from darksynth.evaluation.methods.method import NoiseMethod
from darksynth.evaluation.pairs import LoadedPair, PairSet, list_pair_sets, load_pair
from darksynth.evaluation.report.html import ReportExample
from darksynth.evaluation.report.results_model import CHANNELS, INTERVAL_METRICS
from darksynth.evaluation.run.options import EvaluationOptions
from darksynth.seeding import derive_seed, seeded_generator

METRIC_DESCRIPTIONS = {
    "kld": "KL(real || synthetic) of noise histograms, Noise Flow recipe (Abdelhamed et al. 2019): [0, 1] scale, "
    "64 bins of width 0.2/64 over [-0.1, 0.1] plus an overflow bin each side, summed where both are non-zero",
    "kld_srgb": "KL(real || synthetic), sRGB recipe of Kousha et al. 2022: 8-bit units, bins of width 4 over "
    "[-260, 260], add-one smoothing",
    "kld_naflow": "KL(real || synthetic) of noise histograms, recipe reported on SIDD by NAFlow, NeCA and PNGAN: "
    "[0, 1] scale, 256 bins of width 2/256 over [-1, 1], 1e-10 added to every bin probability of both histograms "
    "(then renormalised), summed over all bins",
    "akld": "Average KL divergence (Yue et al. 2020, DANet): local noise variance = 7x7 Gaussian window (sigma 1.4) "
    "over the squared noise, per pixel and channel KL(N(0, var_real) || N(0, var_synthetic)) with the variance "
    "ratio clamped to [0.1, 10], averaged over pixels",
    "noise_std": "Per channel (r, g, b), the standard deviation of the noise pooled over all the set's pairs, "
    "[0, 1] scale; for a method, over the pairs it was evaluated on",
    "level_ratio": "Per channel (r, g, b), the method's pooled noise std divided by the real noise's over the same "
    "pairs: 1 is the right level, 2 twice too much noise",
    "channel_correlation": "Mean over pairs of the Pearson correlation of the noise between channels (rg, gb, rb); "
    "the set's real entry holds the real noise's",
    "channel_correlation_gap": "Absolute difference between the method's and the real noise's channel correlation, "
    "each averaged over rg, gb and rb, on the same pairs",
    "band_power": "Median over pairs of the noise's power in 5 spatial frequency bands, fine to coarse (periods "
    "1.4-4, 4-8, 8-16, 16-32, 32-64 px), for brightness (R+G+B)/sqrt3 and colour (mean of (R-B)/sqrt2 and "
    "(R-2G+B)/sqrt6): each component minus its mean, P = |FFT2|^2 / pixels, mean of P over the radial frequencies "
    "of the band; [0, 1] scale squared",
    "band_white_ratio": "The real noise's band powers over those of white noise of the same variance (the "
    "component's variance), median over pairs: 1 in every band for pixel-independent noise",
    "band_ratio": "Per band (fine to coarse) and component (brightness, colour), the median over pairs of the "
    "method's band power over the real noise's: 1 is the right power at that scale",
    "band_prior_share": "Per band and component, the share of pairs whose estimate took that band from its prior "
    "(the octaves its reference could not show: the finer octaves' spectrum continued) instead of reading it; only "
    "for methods that say what they read",
    "band_rms_log_error": "sqrt(mean over the 10 bands of ln(band_ratio)^2): 0 when every band has the real power, "
    "0.69 when every band is off by a factor of 2",
    "texture_ratio": "Median over pairs of the noise's std over the 30% most textured 32-px blocks of the clean image "
    "(RMS of its luminance minus a 1.5-px blur) over its std over the 30% least textured (each block's mean removed "
    "per channel): 1 when the noise ignores texture",
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


def _pair_metrics(real: torch.Tensor, synthetic: torch.Tensor) -> dict[str, float]:
    real_values, synthetic_values = real.numpy(), synthetic.numpy()
    return {
        "kld": kl_divergence_noise_flow(real_values, synthetic_values),
        "kld_srgb": kl_divergence_srgb(real_values, synthetic_values),
        "kld_naflow": kl_divergence_naflow(real_values, synthetic_values),
        "akld": average_kl_divergence(real, synthetic),
    }


def _finite_median(values: list[float]) -> float | None:
    """The median of the finite values; None (JSON null) without any."""
    finite = [v for v in values if np.isfinite(v)]
    return float(np.median(finite)) if finite else None


def _optional(value: float) -> float | None:
    """JSON has no NaN: a value that could not be computed is null."""
    return float(value) if np.isfinite(value) else None


def _mean_correlation(correlation: dict[str, float | None]) -> float:
    values = [value for value in correlation.values() if value is not None]
    return float(np.mean(values)) if values else float("nan")


class _ChannelStatistics:
    """Pooled per-channel moments and per-pair channel correlations of one noise source over a set."""

    def __init__(self) -> None:
        self.moments = np.zeros((len(CHANNELS), 3))
        self.correlations: list[dict[str, float]] = []

    def add(self, noise: torch.Tensor) -> None:
        if noise.shape[0] != len(CHANNELS):
            return
        self.moments += channel_moments(noise)
        self.correlations.append(channel_correlations(noise))

    def std(self) -> np.ndarray:
        return pooled_std(self.moments)

    def summary(self, reference: _ChannelStatistics | None = None) -> dict[str, Any]:
        """``noise_std`` and ``channel_correlation``; with a reference, also ``level_ratio`` (std / its std)."""
        if not self.correlations:
            return {}
        std = self.std()
        correlation = {}
        for pair in CHANNEL_PAIRS:
            values = np.array([row[pair] for row in self.correlations])
            finite = values[np.isfinite(values)]
            correlation[pair] = float(finite.mean()) if finite.size else None
        summary: dict[str, Any] = {
            "noise_std": {channel: _optional(value) for channel, value in zip(CHANNELS, std, strict=True)},
            "channel_correlation": correlation,
        }
        if reference is not None:
            gap = abs(_mean_correlation(correlation) - _mean_correlation(reference.summary()["channel_correlation"]))
            summary["channel_correlation_gap"] = _optional(gap)
            reference_std = reference.std()
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = std / reference_std
            summary["level_ratio"] = {channel: _optional(value) for channel, value in zip(CHANNELS, ratio, strict=True)}
        return summary


def _kl_summary(rows: list[dict[str, float]]) -> dict[str, Any]:
    summary: dict[str, Any] = {}
    for metric in INTERVAL_METRICS:
        mean, low, high = mean_and_interval([row[metric] for row in rows])
        summary[metric] = float(mean)
        summary[f"{metric}_ci95"] = [float(low), float(high)]
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
            from darksynth.evaluation.measures.inception import InceptionFeatures

            self.extractor = InceptionFeatures(device=device)
        except DarksynthError as error:
            problems.append(f"fid/kid: {error}")
        self.collected: dict[str, list[np.ndarray]] = {}

    def add(self, source: str, noise: torch.Tensor, crops: int) -> None:
        """Features of ``crops`` tiles spread evenly over the map (all of them if it has fewer)."""
        if self.extractor is None:
            return
        from darksynth.evaluation.measures.inception import noise_map_images

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


@dataclass
class _MethodRecord:
    """What one method left on a pair set: its metric rows per camera, the real noise of the pairs it was evaluated
    on beside its own (channel statistics), and its octave-band powers with their ratios to the real ones."""

    rows: list[tuple[str, dict[str, float]]] = field(default_factory=list)
    real_channels: _ChannelStatistics = field(default_factory=_ChannelStatistics)
    channels: _ChannelStatistics = field(default_factory=_ChannelStatistics)
    bands: list[dict[str, Any]] = field(default_factory=list)
    band_ratios: list[dict[str, Any]] = field(default_factory=list)
    texture_ratios: list[float] = field(default_factory=list)
    prior_bands: list[dict[str, list[bool]]] = field(default_factory=list)

    def add(
        self,
        camera: str,
        real: torch.Tensor,
        noise: torch.Tensor,
        real_bands: dict[str, Any] | None,
        clean: torch.Tensor,
        read_octaves: Mapping[str, int] | None = None,
    ) -> None:
        self.rows.append((camera, _pair_metrics(real, noise)))
        if read_octaves is not None:
            self.prior_bands.append(prior_bands(read_octaves))
        self.texture_ratios.append(textured_flat_ratio(noise, clean))
        self.real_channels.add(real)
        self.channels.add(noise)
        if real_bands is not None:
            synthetic_bands = band_powers(_noise_array(noise))
            self.bands.append(synthetic_bands)
            self.band_ratios.append(band_ratios(synthetic_bands, real_bands))

    def summary(self, oracle: bool, distances: dict[str, float | None]) -> dict[str, Any]:
        entry = _kl_summary([row for _, row in self.rows])
        entry.update(distances)
        entry.update(self.channels.summary(reference=self.real_channels))
        if self.bands:
            entry["band_power"] = band_medians(self.bands)
            entry.update(band_summary(self.band_ratios))
        if self.prior_bands:
            entry["band_prior_share"] = prior_band_shares(self.prior_bands)
        entry["texture_ratio"] = _finite_median(self.texture_ratios)
        entry["oracle"] = oracle
        cameras: dict[str, list[dict[str, float]]] = {}
        for camera, row in self.rows:
            cameras.setdefault(camera, []).append(row)
        entry["per_camera"] = {
            camera: {"pairs": len(camera_rows), **_kl_summary(camera_rows)} for camera, camera_rows in cameras.items()
        }
        return entry


@dataclass
class _SetRecord:
    """Everything one pair set's evaluation gathers, pair by pair, before it is summarised."""

    methods: dict[str, _MethodRecord]
    real_channels: _ChannelStatistics = field(default_factory=_ChannelStatistics)
    real_bands: list[dict[str, Any]] = field(default_factory=list)
    real_texture_ratios: list[float] = field(default_factory=list)
    examples: list[ReportExample] = field(default_factory=list)
    evaluated: int = 0

    def summary(self, methods: dict[str, NoiseMethod], features: _Features | None) -> dict[str, Any]:
        report: dict[str, Any] = {"pairs": self.evaluated, "real": self.real_channels.summary(), "methods": {}}
        if self.real_bands:
            report["real"]["band_power"] = band_medians(self.real_bands)
            report["real"]["band_white_ratio"] = band_medians([relative_to_white(row) for row in self.real_bands])
        if self.real_texture_ratios:
            report["real"]["texture_ratio"] = _finite_median(self.real_texture_ratios)
        for name, record in self.methods.items():
            if record.rows:
                distances: dict[str, float | None] = (
                    features.distances(name) if features is not None else dict.fromkeys(("fid", "kid", "kid_std"))
                )
                report["methods"][name] = record.summary(methods[name].oracle, distances)
        return report


def _evaluate_pair(
    pair_set: PairSet,
    loaded: LoadedPair,
    methods: dict[str, NoiseMethod],
    options: EvaluationOptions,
    record: _SetRecord,
    problems: list[str],
    features: _Features | None,
    crops_per_pair: int,
) -> None:
    pair = loaded.pair
    real = loaded.noise
    record.evaluated += 1
    record.real_channels.add(real)
    pair_bands = band_powers(_noise_array(real)) if real.shape[0] == len(CHANNELS) else None
    if pair_bands is not None:
        record.real_bands.append(pair_bands)
    record.real_texture_ratios.append(textured_flat_ratio(real, loaded.clean))
    if features is not None:
        features.add("real", real, crops_per_pair)
    keep_example = len(record.examples) < options.examples_per_set
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
        read_octaves = method.read_octaves() if method.read_octaves is not None else None
        record.methods[name].add(pair.camera, real, noise, pair_bands, loaded.clean, read_octaves)
        if features is not None:
            features.add(name, noise, crops_per_pair)
        if keep_example:
            noisy_crops[name] = _center_crop(synthetic, options.example_crop)
            noise_maps[name] = _noise_array(noise)
    if keep_example:
        clean_crop = _center_crop(loaded.clean, options.example_crop)
        record.examples.append(
            ReportExample(
                set_name=pair_set.name, pair_name=pair.name, clean=clean_crop, noisy=noisy_crops, noise=noise_maps
            )
        )


def _evaluate_set(
    pair_set: PairSet,
    methods: dict[str, NoiseMethod],
    options: EvaluationOptions,
    problems: list[str],
    features: _Features | None,
    progress: Progress,
) -> tuple[dict[str, Any], list[ReportExample]]:
    methods = {name: method.on_set(pair_set.name) for name, method in methods.items()}
    record = _SetRecord(methods={name: _MethodRecord() for name in methods})
    # Inception features cost ~0.1 s a tile on this CPU: a fixed budget per set keeps the run short.
    crops_per_pair = max(1, -(-options.fid_crops // max(len(pair_set.pairs), 1)))
    for index, pair in enumerate(pair_set.pairs):
        progress(f"{pair_set.name}: pair {index + 1}/{len(pair_set.pairs)} {pair.name}")
        try:
            loaded: LoadedPair = load_pair(pair)
        except DarksynthError as error:
            problems.append(str(error))
            continue
        _evaluate_pair(pair_set, loaded, methods, options, record, problems, features, crops_per_pair)
    summary = record.summary(methods, features)
    prior_sets = {name: list(m.details["prior_sets"]) for name, m in methods.items() if "prior_sets" in m.details}
    if prior_sets:
        summary["camera_prior_sets"] = prior_sets
    return summary, record.examples


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
        from darksynth.evaluation.measures.inception import INCEPTION_PROVENANCE

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
