"""What the evaluation results say: the best method of each table column, and whether the paper's claims hold.

Pure functions from the typed results (:mod:`darksynth.evaluation.report.results_model`) to verdict data; the reports
only format them. Only finite values take part: a metric that was not computed, or came out NaN, decides nothing.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Literal

from darksynth.evaluation.report.results_model import CAMERA_METRICS, DOWNSTREAM_METRICS, SET_METRICS, EvaluationResults

__all__ = [
    "BLIND_METHODS",
    "BeyondPaperCheck",
    "Headline",
    "best_methods",
    "best_per_camera",
    "best_per_downstream_metric",
    "best_per_metric",
    "beyond_paper_checks",
    "headlines",
]

BLIND_METHODS = ("awgn", "awgn-blind", "pg", "pg-blind", "starlight")
"""The methods that see neither the clean image nor any real noise beyond the reference (den's peers)."""

ORACLE_FACTOR = 2.0
"""den's KLD should be at most this many times the oracle Poisson-Gaussian fit's (pg-oracle)."""

RANKED_DOWNSTREAM_METRICS = ("psnr", "ssim")


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def best_methods(
    values: Mapping[str, float | None], *, excluded: Collection[str] = (), higher_is_better: bool = False
) -> frozenset[str]:
    """The names whose finite value is the best one (all of them on a tie), the ``excluded`` names left out.

    Args:
        values: name -> value; None or non-finite values never win.
        excluded: Names that are shown but not ranked (oracles, reference rows).
        higher_is_better: The best value is the largest rather than the smallest.
    """
    ranked = {name: v for name, value in values.items() if name not in excluded and (v := _finite(value)) is not None}
    if not ranked:
        return frozenset()
    top = max(ranked.values()) if higher_is_better else min(ranked.values())
    return frozenset(name for name, value in ranked.items() if value == top)


def best_per_metric(results: EvaluationResults, set_name: str) -> dict[str, frozenset[str]]:
    """Per metric of a set (the KLDs, AKLD, FID, KID; lower is better), the best blind methods (oracles excluded)."""
    methods = results.sets[set_name].methods
    return {
        metric: best_methods({name: row.value(metric) for name, row in methods.items()}, excluded=results.oracles)
        for metric in SET_METRICS
    }


def best_per_camera(results: EvaluationResults, set_name: str, metric: str) -> dict[str, frozenset[str]]:
    """Per camera of a set, the best blind methods on ``metric`` (one of :data:`CAMERA_METRICS`)."""
    if metric not in CAMERA_METRICS:
        raise ValueError(f"per-camera metric must be one of {', '.join(CAMERA_METRICS)}, got {metric!r}")
    methods = results.sets[set_name].methods
    cameras = {camera: None for row in methods.values() for camera in row.per_camera}
    return {
        camera: best_methods(
            {name: row.per_camera[camera].value(metric) for name, row in methods.items() if camera in row.per_camera},
            excluded=results.oracles,
        )
        for camera in cameras
    }


def best_per_downstream_metric(results: EvaluationResults, set_name: str) -> dict[str, frozenset[str]]:
    """Per downstream metric (PSNR, SSIM; higher is better) of a set, the best blind methods (oracles and reference
    rows such as the noisy input excluded). The pair count is not ranked."""
    downstream = results.downstream
    if downstream is None:
        raise ValueError("the results have no downstream run")
    rows = downstream.sets[set_name]
    excluded = results.oracles | downstream.references
    best = {metric: frozenset[str]() for metric in DOWNSTREAM_METRICS}
    for metric in RANKED_DOWNSTREAM_METRICS:
        values = {name: row.value(metric) for name, row in rows.items()}
        best[metric] = best_methods(values, excluded=excluded, higher_is_better=True)
    return best


@dataclass(frozen=True)
class Headline:
    """The paper's headline claim on one set: den's KLD is below AWGN's and Poisson-Gaussian's."""

    set_name: str
    holds: bool
    den: float
    awgn: float
    pg: float


def headlines(results: EvaluationResults) -> list[Headline]:
    """One verdict per set where den, awgn and pg all have a finite KLD."""
    verdicts = []
    for set_name, entry in results.sets.items():
        kld = {name: _finite(entry.methods[name].kld) for name in ("den", "awgn", "pg") if name in entry.methods}
        den, awgn, pg = kld.get("den"), kld.get("awgn"), kld.get("pg")
        if den is None or awgn is None or pg is None:
            continue
        verdicts.append(Headline(set_name, den < min(awgn, pg), den, awgn, pg))
    return verdicts


@dataclass(frozen=True)
class BeyondPaperCheck:
    """One check beyond the paper's headline on one set.

    Attributes:
        set_name: The set.
        claim: ``"blind"``: den's KLD is below every blind method's (``rival`` is the best blind method);
            ``"oracle"``: den's KLD is at most :data:`ORACLE_FACTOR` times pg-oracle's (``bound`` is that multiple);
            ``"paper"``: den's ``metric`` (FID or KID) is below the paper-faithful model's (``rival`` is den-paper).
        metric: The metric compared.
        holds: Whether the claim holds.
        den: den's value.
        rival: The method compared with.
        bound: The value den must stay below (at most, for ``"oracle"``).
    """

    set_name: str
    claim: Literal["blind", "oracle", "paper"]
    metric: str
    holds: bool
    den: float
    rival: str
    bound: float


def beyond_paper_checks(results: EvaluationResults) -> list[BeyondPaperCheck]:
    """Per set with den results, in this order: den's KLD below every blind method present, den's KLD at most twice
    pg-oracle's, and den's FID and KID below den-paper's; each only where both sides have finite values."""
    checks = []
    for set_name, entry in results.sets.items():
        methods = entry.methods
        if "den" not in methods:
            continue
        den = methods["den"]
        kld = _finite(den.kld)
        blind = {name: v for name in BLIND_METHODS if name in methods and (v := _finite(methods[name].kld)) is not None}
        if kld is not None and blind:
            best = min(blind, key=lambda name: blind[name])
            checks.append(BeyondPaperCheck(set_name, "blind", "kld", kld < blind[best], kld, best, blind[best]))
        oracle = _finite(methods["pg-oracle"].kld) if "pg-oracle" in methods else None
        if kld is not None and oracle is not None:
            bound = ORACLE_FACTOR * oracle
            checks.append(BeyondPaperCheck(set_name, "oracle", "kld", kld <= bound, kld, "pg-oracle", bound))
        if "den-paper" in methods:
            for metric in ("fid", "kid"):
                ours, theirs = _finite(den.value(metric)), _finite(methods["den-paper"].value(metric))
                if ours is not None and theirs is not None:
                    checks.append(BeyondPaperCheck(set_name, "paper", metric, ours < theirs, ours, "den-paper", theirs))
    return checks
