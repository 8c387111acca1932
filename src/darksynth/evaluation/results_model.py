"""The results document of ``darksynth evaluate`` (results.json), parsed once into frozen dataclasses.

The runner (:mod:`darksynth.evaluation.runner`) writes the document and the downstream run
(:mod:`darksynth.evaluation.downstream`) adds its part. Any part of it may be missing or odd: a set where a method
failed, a metric that was not computed (``None``) or came out NaN, no downstream run, problems that are not plain
strings, methods with or without an ``oracle`` flag. :func:`parse_results` never fails on such a document: a number
that is not a number counts as not computed, a part that is not a mapping counts as empty, and a free-text field that
is not a string is shown as its JSON.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "CAMERA_METRICS",
    "DOWNSTREAM_METRICS",
    "NOISY_INPUT",
    "SET_METRICS",
    "CameraScores",
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

SET_METRICS = ("kld", "kld_srgb", "fid", "kid")
"""Per set and method, all lower-is-better."""
CAMERA_METRICS = ("kld", "kld_srgb")
"""Per camera and method."""
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


@dataclass(frozen=True)
class CameraScores:
    """One method's histogram KL divergences over the pairs of one camera."""

    pairs: int | None
    kld: float | None
    kld_ci95: Interval | None
    kld_srgb: float | None
    kld_srgb_ci95: Interval | None

    def value(self, metric: str) -> float | None:
        """``"kld"`` or ``"kld_srgb"``."""
        return {"kld": self.kld, "kld_srgb": self.kld_srgb}[metric]

    def interval(self, metric: str) -> Interval | None:
        return {"kld": self.kld_ci95, "kld_srgb": self.kld_srgb_ci95}[metric]

    @classmethod
    def parse(cls, document: object) -> CameraScores:
        entry = _mapping(document)
        return cls(
            pairs=_count(entry.get("pairs")),
            kld=_number(entry.get("kld")),
            kld_ci95=_interval(entry.get("kld_ci95")),
            kld_srgb=_number(entry.get("kld_srgb")),
            kld_srgb_ci95=_interval(entry.get("kld_srgb_ci95")),
        )


@dataclass(frozen=True)
class MethodScores:
    """One method's metrics on one set (lower is better for all of them); None: not computed.

    Attributes:
        kld, kld_srgb: Mean histogram KL divergence over the pairs (Noise Flow and sRGB recipes).
        kld_ci95, kld_srgb_ci95: Their 95% confidence intervals.
        fid, kid: Inception distances between the real and the synthetic noise maps; KID can be slightly negative.
        kid_std: KID's standard deviation over subsets.
        oracle: The runner's flag (the method uses the clean image), if it wrote one.
        per_camera: camera name -> the KL divergences over that camera's pairs.
    """

    kld: float | None = None
    kld_ci95: Interval | None = None
    kld_srgb: float | None = None
    kld_srgb_ci95: Interval | None = None
    fid: float | None = None
    kid: float | None = None
    kid_std: float | None = None
    oracle: bool | None = None
    per_camera: Mapping[str, CameraScores] = field(default_factory=dict)

    def value(self, metric: str) -> float | None:
        """One of :data:`SET_METRICS`."""
        return {"kld": self.kld, "kld_srgb": self.kld_srgb, "fid": self.fid, "kid": self.kid}[metric]

    def interval(self, metric: str) -> Interval | None:
        return {"kld": self.kld_ci95, "kld_srgb": self.kld_srgb_ci95}.get(metric)

    @classmethod
    def parse(cls, document: object) -> MethodScores:
        entry = _mapping(document)
        return cls(
            kld=_number(entry.get("kld")),
            kld_ci95=_interval(entry.get("kld_ci95")),
            kld_srgb=_number(entry.get("kld_srgb")),
            kld_srgb_ci95=_interval(entry.get("kld_srgb_ci95")),
            fid=_number(entry.get("fid")),
            kid=_number(entry.get("kid")),
            kid_std=_number(entry.get("kid_std")),
            oracle=_flag(entry),
            per_camera={name: CameraScores.parse(c) for name, c in _mapping(entry.get("per_camera")).items()},
        )


@dataclass(frozen=True)
class SetResults:
    """One set of real pairs: how many pairs were evaluated and each method's metrics."""

    pairs: int | None
    methods: Mapping[str, MethodScores]

    @classmethod
    def parse(cls, document: object) -> SetResults:
        entry = _mapping(document)
        methods = {name: MethodScores.parse(row) for name, row in _mapping(entry.get("methods")).items()}
        return cls(pairs=_count(entry.get("pairs")), methods=methods)


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
    """The downstream denoising run (see :func:`darksynth.evaluation.downstream.run_downstream`).

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
