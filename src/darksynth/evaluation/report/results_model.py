"""The results document of ``darksynth evaluate`` (results.json), parsed once into frozen dataclasses.

The runner (:mod:`darksynth.evaluation.run.runner`) writes the document and the downstream run
(:mod:`darksynth.evaluation.measures.downstream`) adds its part. Any part of it may be missing or odd: a set where a
method failed, a metric that was not computed (``None``) or came out NaN, no downstream run, problems that are not
plain strings, methods with or without an ``oracle`` flag. :func:`parse_results` never fails on such a document: a
number that is not a number counts as not computed, a part that is not a mapping counts as empty, and a free-text
field that is not a string is shown as its JSON.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

__all__ = [
    "BAND_COMPONENTS",
    "CAMERA_METRICS",
    "CHANNELS",
    "CHANNEL_PAIRS",
    "DOWNSTREAM_METRICS",
    "NOISY_INPUT",
    "SET_METRICS",
    "BandStatistics",
    "CameraScores",
    "ChannelStatistics",
    "Downstream",
    "DownstreamScores",
    "EvaluationResults",
    "Interval",
    "MethodInfo",
    "MethodScores",
    "SetResults",
    "parse_results",
]

Interval = tuple[float, float]
"""A 95% confidence interval ``(low, high)``; only kept when both ends are finite numbers."""

NOISY_INPUT = "noisy input"
"""The downstream reference row: the unprocessed real noisy images."""

SET_METRICS = (
    "kld_naflow",
    "akld",
    "band_rms_log_error",
    "channel_correlation_gap",
    "kld_srgb",
    "kld",
    "fid",
    "kid",
)
"""Per set and method, all lower-is-better, in the tables' order: the NAFlow KLD and the AKLD (the measures most
recent work reports) lead, the noise structure follows, the Noise Flow KLD is kept to compare with the paper."""
INTERVAL_METRICS = ("kld_naflow", "akld", "kld_srgb", "kld")
"""The per-pair metrics: each has a 95% interval."""
CAMERA_METRICS = INTERVAL_METRICS
"""Per camera and method."""
CHANNELS = ("r", "g", "b")
CHANNEL_PAIRS = ("rg", "gb", "rb")
BAND_COMPONENTS = ("brightness", "colour")
BAND_COUNT = 5
DOWNSTREAM_METRICS = ("psnr", "ssim", "pairs")
"""Per set and downstream row: PSNR and SSIM are higher-is-better, pairs is a count."""


def _number(value: object) -> float | None:
    """A number as a float (NaN and infinities kept: the report shows them); anything else is None."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    return None


def _finite(value: object) -> float | None:
    number = _number(value)
    return number if number is not None and math.isfinite(number) else None


def _count(value: object) -> int | None:
    number = _finite(value)
    return int(number) if number is not None and number == int(number) else None


def _interval(value: object) -> Interval | None:
    if isinstance(value, list | tuple) and len(value) == 2:
        low, high = _finite(value[0]), _finite(value[1])
        if low is not None and high is not None:
            return (low, high)
    return None


def _text(value: object) -> str:
    return value if isinstance(value, str) else json.dumps(value, indent=1, sort_keys=True, default=str)


def _mapping(value: object) -> dict[str, Any]:
    return {str(k): v for k, v in value.items()} if isinstance(value, Mapping) else {}


def _texts(value: object) -> dict[str, str]:
    return {key: _text(item) for key, item in _mapping(value).items()}


def _problems(value: object) -> tuple[str, ...]:
    return tuple(_text(problem) for problem in value) if isinstance(value, list | tuple) else ()


def _flag(value: Mapping[str, Any]) -> bool | None:
    return bool(value["oracle"]) if "oracle" in value else None


def _divergences(entry: Mapping[str, Any]) -> dict[str, Any]:
    """Each of :data:`INTERVAL_METRICS` and its ``_ci95`` interval, as the keyword arguments of a scores class."""
    parsed: dict[str, Any] = {}
    for metric in INTERVAL_METRICS:
        parsed[metric] = _number(entry.get(metric))
        parsed[f"{metric}_ci95"] = _interval(entry.get(f"{metric}_ci95"))
    return parsed


def _numbers(value: object, keys: tuple[str, ...]) -> dict[str, float | None]:
    entry = _mapping(value)
    return {key: _number(entry.get(key)) for key in keys}


class _ScoresByMetric:
    """A scores record whose fields are named after its class's ``metrics``."""

    metrics: ClassVar[tuple[str, ...]]

    def value(self, metric: str) -> float | None:
        """One of the class's ``metrics``."""
        if metric not in self.metrics:
            raise KeyError(metric)
        return getattr(self, metric)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class CameraScores(_ScoresByMetric):
    """One method's per-pair divergences over the pairs of one camera (see :data:`CAMERA_METRICS`)."""

    metrics: ClassVar[tuple[str, ...]] = CAMERA_METRICS

    pairs: int | None
    kld: float | None
    kld_ci95: Interval | None
    kld_srgb: float | None
    kld_srgb_ci95: Interval | None
    kld_naflow: float | None = None
    kld_naflow_ci95: Interval | None = None
    akld: float | None = None
    akld_ci95: Interval | None = None

    def interval(self, metric: str) -> Interval | None:
        if metric not in CAMERA_METRICS:
            raise KeyError(metric)
        return getattr(self, f"{metric}_ci95")  # type: ignore[no-any-return]

    @classmethod
    def parse(cls, document: object) -> CameraScores:
        entry = _mapping(document)
        return cls(pairs=_count(entry.get("pairs")), **_divergences(entry))


@dataclass(frozen=True)
class ChannelStatistics:
    """Per channel level and cross-channel correlation of one noise source over a set; None: not computed.

    Attributes:
        noise_std: ``"r"``, ``"g"``, ``"b"`` -> the noise's standard deviation pooled over the pairs, [0, 1] scale.
        level_ratio: ``"r"``, ``"g"``, ``"b"`` -> a method's pooled std over the real one's on the same pairs (1:
            the right level); empty for the real noise itself.
        correlation: ``"rg"``, ``"gb"``, ``"rb"`` -> the mean over pairs of the noise's correlation coefficient
            between the two channels.
    """

    noise_std: Mapping[str, float | None]
    level_ratio: Mapping[str, float | None]
    correlation: Mapping[str, float | None]

    @classmethod
    def parse(cls, document: Mapping[str, Any]) -> ChannelStatistics | None:
        """None when ``document`` (a set's ``real`` entry, or a method's) holds none of the three."""
        if not any(key in document for key in ("noise_std", "level_ratio", "channel_correlation")):
            return None
        ratio = document.get("level_ratio")
        return cls(
            noise_std=_numbers(document.get("noise_std"), CHANNELS),
            level_ratio=_numbers(ratio, CHANNELS) if isinstance(ratio, Mapping) else {},
            correlation=_numbers(document.get("channel_correlation"), CHANNEL_PAIRS),
        )


def _bands(value: object) -> dict[str, tuple[float | None, ...]]:
    """``{"brightness": [5], "colour": [5]}`` as tuples of :data:`BAND_COUNT` numbers; a malformed part is left out."""
    entry = _mapping(value)
    parsed = {}
    for component in BAND_COMPONENTS:
        values = entry.get(component)
        if isinstance(values, list | tuple) and len(values) == BAND_COUNT:
            parsed[component] = tuple(_number(v) for v in values)
    return parsed


@dataclass(frozen=True)
class BandStatistics:
    """Noise power in five spatial frequency bands, fine to coarse (see :mod:`darksynth.evaluation.measures.structure`).

    Each attribute maps ``"brightness"`` and ``"colour"`` to 5 values (None: not computed); a component missing from
    the document is missing here.

    Attributes:
        power: Median over pairs of the band power, [0, 1] scale squared.
        white_ratio: The real noise's band power over white noise of the same variance (empty for a method).
        ratio: A method's median over pairs of its band power over the real one's (empty for the real noise).
        texture_ratio: Median over pairs of the noise's std on the most textured blocks over that on the flattest
            (:mod:`darksynth.evaluation.measures.texture_ratio`); None: not computed.
    """

    power: Mapping[str, tuple[float | None, ...]]
    white_ratio: Mapping[str, tuple[float | None, ...]]
    ratio: Mapping[str, tuple[float | None, ...]]
    texture_ratio: float | None = None

    @classmethod
    def parse(cls, document: Mapping[str, Any]) -> BandStatistics | None:
        """None when ``document`` (a set's ``real`` entry, or a method's) holds none of the three."""
        parsed = cls(
            power=_bands(document.get("band_power")),
            white_ratio=_bands(document.get("band_white_ratio")),
            ratio=_bands(document.get("band_ratio")),
            texture_ratio=_number(document.get("texture_ratio")),
        )
        found = parsed.power or parsed.white_ratio or parsed.ratio or parsed.texture_ratio is not None
        return parsed if found else None


@dataclass(frozen=True)
class MethodScores(_ScoresByMetric):
    """One method's metrics (:data:`SET_METRICS`) on one set (lower is better for all of them); None: not computed.

    Attributes:
        kld, kld_srgb, kld_naflow: Mean histogram KL divergence over the pairs (Noise Flow, sRGB and NAFlow recipes).
        akld: Mean average KL divergence of local Gaussians over the pairs (DANet).
        kld_ci95, kld_srgb_ci95, kld_naflow_ci95, akld_ci95: Their 95% confidence intervals.
        band_rms_log_error: RMS over the 10 bands (brightness, colour) of the log of the median band power ratio.
        channel_correlation_gap: The absolute gap of the mean channel correlation to the real noise's.
        fid, kid: Inception distances between the real and the synthetic noise maps; KID can be slightly negative.
        kid_std: KID's standard deviation over subsets.
        oracle: The runner's flag (the method uses the clean image), if it wrote one.
        per_camera: camera name -> the per-pair divergences over that camera's pairs.
        channels: The synthetic noise's level per channel, its ratio to the real one's, and its channel correlations.
        bands: The synthetic noise's band powers and their ratios to the real ones.
    """

    kld: float | None = None
    kld_ci95: Interval | None = None
    kld_srgb: float | None = None
    kld_srgb_ci95: Interval | None = None
    kld_naflow: float | None = None
    kld_naflow_ci95: Interval | None = None
    akld: float | None = None
    akld_ci95: Interval | None = None
    band_rms_log_error: float | None = None
    channel_correlation_gap: float | None = None
    fid: float | None = None
    kid: float | None = None
    kid_std: float | None = None
    oracle: bool | None = None
    per_camera: Mapping[str, CameraScores] = field(default_factory=dict)
    channels: ChannelStatistics | None = None
    bands: BandStatistics | None = None
    metrics: ClassVar[tuple[str, ...]] = SET_METRICS

    def interval(self, metric: str) -> Interval | None:
        """The interval of one of :data:`INTERVAL_METRICS`; None for the others (FID, KID)."""
        return getattr(self, f"{metric}_ci95") if metric in INTERVAL_METRICS else None

    @classmethod
    def parse(cls, document: object) -> MethodScores:
        entry = _mapping(document)
        return cls(
            **_divergences(entry),
            band_rms_log_error=_number(entry.get("band_rms_log_error")),
            channel_correlation_gap=_number(entry.get("channel_correlation_gap")),
            fid=_number(entry.get("fid")),
            kid=_number(entry.get("kid")),
            kid_std=_number(entry.get("kid_std")),
            oracle=_flag(entry),
            per_camera={name: CameraScores.parse(c) for name, c in _mapping(entry.get("per_camera")).items()},
            channels=ChannelStatistics.parse(entry),
            bands=BandStatistics.parse(entry),
        )


@dataclass(frozen=True)
class SetResults:
    """One set of real pairs: how many pairs were evaluated, each method's metrics, the real noise's channels and
    band powers."""

    pairs: int | None
    methods: Mapping[str, MethodScores]
    real: ChannelStatistics | None = None
    real_bands: BandStatistics | None = None

    @classmethod
    def parse(cls, document: object) -> SetResults:
        entry = _mapping(document)
        methods = {name: MethodScores.parse(row) for name, row in _mapping(entry.get("methods")).items()}
        real = _mapping(entry.get("real"))
        return cls(
            pairs=_count(entry.get("pairs")),
            methods=methods,
            real=ChannelStatistics.parse(real),
            real_bands=BandStatistics.parse(real),
        )


@dataclass(frozen=True)
class MethodInfo:
    """What the runner says about a method: whether it uses the clean image (if it says), and a summary."""

    oracle: bool | None
    summary: str

    @classmethod
    def parse(cls, document: object) -> MethodInfo:
        entry = _mapping(document)
        return cls(oracle=_flag(entry), summary=_text(entry.get("summary", "")))


@dataclass(frozen=True)
class DownstreamScores:
    """A denoiser's scores on the real pairs of one set (higher is better)."""

    psnr: float | None
    ssim: float | None
    pairs: int | None

    def value(self, metric: str) -> float | None:
        """One of :data:`DOWNSTREAM_METRICS`."""
        pairs = None if self.pairs is None else float(self.pairs)
        return {"psnr": self.psnr, "ssim": self.ssim, "pairs": pairs}[metric]

    @classmethod
    def parse(cls, document: object) -> DownstreamScores:
        entry = _mapping(document)
        return cls(psnr=_number(entry.get("psnr")), ssim=_number(entry.get("ssim")), pairs=_count(entry.get("pairs")))


@dataclass(frozen=True)
class Downstream:
    """The downstream denoising run (see :func:`darksynth.evaluation.measures.downstream.run_downstream`).

    Attributes:
        sets: set name -> row name (a method, or a reference row such as the noisy input) -> scores.
        settings: The training settings, as text.
        notes: Every other entry of the document (LPIPS status, clean images...), as text.
        problems: The downstream run's own problems.
        references: The rows that are not methods (the noisy input, and any name that is no method): shown, never
            ranked.
    """

    sets: Mapping[str, Mapping[str, DownstreamScores]]
    settings: Mapping[str, str]
    notes: Mapping[str, str]
    problems: tuple[str, ...]
    references: frozenset[str]

    @classmethod
    def parse(cls, document: object, methods: tuple[str, ...]) -> Downstream | None:
        """None when ``document`` is not a mapping (no downstream run); ``methods`` are the run's method names."""
        if not isinstance(document, Mapping):
            return None
        data = _mapping(document)
        settings = _texts(data.pop("settings", None))
        problems = _problems(data.pop("problems", None))
        known = set(_mapping(data.pop("methods", None))) | set(methods)
        sets: dict[str, dict[str, DownstreamScores]] = {}
        notes: dict[str, str] = {}
        for key, value in data.items():
            # A set is a mapping of non-empty rows with scores; anything else is a note about the run.
            rows = {name: _mapping(row) for name, row in _mapping(value).items()}
            if rows and all(rows.values()) and any("psnr" in row or "ssim" in row for row in rows.values()):
                sets[key] = {name: DownstreamScores.parse(row) for name, row in rows.items()}
            else:
                notes[key] = _text(value)
        references = frozenset(
            name for rows in sets.values() for name in rows if name == NOISY_INPUT or (known and name not in known)
        )
        return cls(sets, settings, notes, problems, references)


@dataclass(frozen=True)
class EvaluationResults:
    """The whole document.

    Attributes:
        command: The command line that produced it.
        seed: The seed of the synthetic noise, if recorded.
        seconds: The run's duration, if recorded and finite.
        metrics: metric name -> how it is computed.
        provenance: what -> where it comes from (the Inception weights...).
        methods: The methods the runner built, in its order.
        problems: Everything that went wrong and was skipped.
        sets: set name -> its results.
        downstream: The downstream denoising run, if any.
        method_order: The runner's methods, then any only found in a set.
        oracles: The methods that use the clean image: flagged so (in ``methods`` or in any set), or, where nothing
            says, named ``*-oracle``.
    """

    command: str
    seed: int | None
    seconds: float | None
    metrics: Mapping[str, str]
    provenance: Mapping[str, str]
    methods: Mapping[str, MethodInfo]
    problems: tuple[str, ...]
    sets: Mapping[str, SetResults]
    downstream: Downstream | None
    method_order: tuple[str, ...]
    oracles: frozenset[str]

    def not_evaluated(self, set_name: str) -> list[str]:
        """The runner's methods with no results on that set."""
        present = self.sets[set_name].methods
        return [name for name in self.methods if name not in present]


def parse_results(document: Mapping[str, Any]) -> EvaluationResults:
    """Parse the runner's document (see the module docstring for what may be missing).

    Args:
        document: ``command``, ``seed``, ``seconds``, ``metrics``, ``provenance``, ``methods``, ``problems``,
            ``sets`` and ``downstream``, as in results.json.
    """
    methods = {name: MethodInfo.parse(info) for name, info in _mapping(document.get("methods")).items()}
    sets = {name: SetResults.parse(entry) for name, entry in _mapping(document.get("sets")).items()}
    order = list(methods)
    for entry in sets.values():
        order += [name for name in entry.methods if name not in order and name != "real"]
    flags = {name: info.oracle for name, info in methods.items() if info.oracle is not None}
    for entry in sets.values():
        for name, scores in entry.methods.items():
            if scores.oracle is not None:
                flags[name] = bool(flags.get(name)) or scores.oracle
    oracles = frozenset(name for name in {*order, *flags} if flags.get(name, name.endswith("-oracle")))
    seed = document.get("seed")
    return EvaluationResults(
        command=_text(document.get("command", "")),
        seed=seed if isinstance(seed, int) and not isinstance(seed, bool) else None,
        seconds=_finite(document.get("seconds")),
        metrics=_texts(document.get("metrics")),
        provenance=_texts(document.get("provenance")),
        methods=methods,
        problems=_problems(document.get("problems")),
        sets=sets,
        downstream=Downstream.parse(document.get("downstream"), tuple(order)),
        method_order=tuple(order),
        oracles=oracles,
    )
