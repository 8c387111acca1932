"""The tables of both reports of ``darksynth evaluate``: which rows, in which order, with which values formatted
how, the best blind value of each column marked; their headers and legends.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from darksynth.evaluation.measures.structure import BAND_LABELS
from darksynth.evaluation.report.results_model import (
    BAND_COMPONENTS,
    CAMERA_METRICS,
    CHANNEL_PAIRS,
    CHANNELS,
    SET_METRICS,
    ChannelStatistics,
    EvaluationResults,
    Interval,
    MethodScores,
)
from darksynth.evaluation.report.verdicts import best_per_camera, best_per_downstream_metric, best_per_metric

MISSING = "—"

SET_TITLES = {
    "kld_naflow": "KLD NAFlow",
    "akld": "AKLD",
    "band_rms_log_error": "band RMS log error",
    "channel_correlation_gap": "channel correlation gap",
    "kld_srgb": "KLD sRGB",
    "kld": "KLD (paper)",
    "fid": "FID",
    "kid": "KID",
}
SET_HEADERS = {
    "kld_naflow": "KLD NAFlow [95% CI]",
    "akld": "AKLD [95% CI]",
    "band_rms_log_error": "band RMS log error",
    "channel_correlation_gap": "channel correlation gap",
    "kld_srgb": "KLD sRGB [95% CI]",
    "kld": "KLD (paper) [95% CI]",
    "fid": "FID",
    "kid": "KID ± std",
}
DOWNSTREAM_HEADERS = {"psnr": "PSNR (dB)", "ssim": "SSIM", "pairs": "pairs"}
CHANNEL_HEADERS = {
    **{f"level_ratio_{c}": f"level ratio {c.upper()}" for c in CHANNELS},
    **{f"correlation_{p}": f"correlation {p[0].upper()}-{p[1].upper()}" for p in CHANNEL_PAIRS},
}
BAND_HEADERS = {
    f"{component}_{index}": f"{component[0].upper()} {label}"
    for component in BAND_COMPONENTS
    for index, label in enumerate(BAND_LABELS)
} | {"texture_ratio": "textured / flat std"}
REAL = "real"
"""The reference row of the channel tables: the real noise."""

LEGEND = (
    "Lower is better for every metric. KLD NAFlow and AKLD are the measures recent work reports; the band RMS log "
    "error and the channel correlation gap measure the noise's structure (scales, colour); KLD (paper) is the Noise "
    "Flow recipe, kept for comparison with the paper. Bold: the best blind method in each column; oracle methods, "
    "which are given the clean image, are labelled (oracle) and never bold. Brackets: 95% confidence interval; KID "
    f"± its standard deviation; {MISSING}: not computed."
)
DOWNSTREAM_LEGEND = (
    "PSNR and SSIM of a denoiser trained on each method's synthetic noise, on the real pairs; the noisy input row "
    "is the unprocessed noisy image. Higher is better. Bold: the best blind method in each column."
)
CHANNEL_LEGEND = (
    "Level ratio: the method's noise standard deviation per channel, pooled over the set's pairs, divided by the "
    "real noise's on the same pairs (1 is the right level; σ: the std in 8-bit levels). Correlation: the mean over "
    "pairs of the correlation coefficient of the noise between two channels. The real row is the reference."
)
BAND_LEGEND = (
    "Noise power per band of spatial frequency, fine to coarse (period in pixels), for brightness (B) and colour (C). "
    "Method rows: the median over pairs of the method's band power over the real noise's (1 is right, 2 twice too "
    "much). The real row: the real noise's band power over that of white noise of the same variance (1 for "
    "pixel-independent noise). Textured / flat std: the median over pairs of the noise's std on the 30% most "
    "textured 32-px blocks of the clean image over its std on the 30% least textured, for the real noise and each "
    "method (1: the noise ignores texture)."
)


def num(value: float | int | None, digits: int = 4) -> str:
    """A value as the reports print it: ``digits`` significant digits, an integer as is, None as missing."""
    if value is None:
        return MISSING
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}g}" if math.isfinite(value) else str(value)


def is_finite(value: float | None) -> bool:
    """Whether a metric has a finite value."""
    return value is not None and math.isfinite(value)


def _interval(interval: Interval | None) -> str:
    return "" if interval is None else f"[{num(interval[0])}, {num(interval[1])}]"


@dataclass(frozen=True)
class Method:
    """How one row name is shown: oracle methods are labelled, reference rows (the noisy input) are no method."""

    name: str
    oracle: bool
    reference: bool
    colour: str

    @property
    def label(self) -> str:
        return f"{self.name} (oracle)" if self.oracle else self.name


@dataclass(frozen=True)
class Header:
    key: str
    title: str
    literal: bool = True
    """The title is this module's own text, not a name from the results: Markdown shows it unescaped."""


@dataclass(frozen=True)
class Cell:
    key: str
    value: str
    extra: str
    best: bool


@dataclass(frozen=True)
class Row:
    method: Method
    cells: list[Cell]


@dataclass(frozen=True)
class Table:
    css_class: str
    caption: str
    headers: list[Header]
    rows: list[Row]
    data: dict[str, str]
    """Extra ``data-*`` attributes of the HTML table."""
    title: str = ""


def ordered(names: Sequence[str] | Mapping[str, Any], order: Sequence[str]) -> list[str]:
    """``names`` in ``order``, then those ``order`` does not list."""
    return [n for n in order if n in names] + [n for n in names if n not in order]


def _set_cell(row: MethodScores, metric: str, best: bool) -> Cell:
    """A method's cell of a metric in a set's table: the value with its interval (KID: its spread)."""
    value = row.value(metric)
    extra = _interval(row.interval(metric))
    if metric == "kid" and is_finite(row.kid_std) and is_finite(value):
        extra = f"± {num(row.kid_std, 2)}"
    return Cell(metric, num(value), extra, best)


class Layout:
    """The tables of both reports: which rows, in which order, with which values formatted how."""

    def __init__(
        self, results: EvaluationResults, order: Sequence[str], colours: Mapping[str, str] | None = None
    ) -> None:
        self.results, self.order, self.colours = results, order, colours or {}
        downstream = results.downstream
        self.references = downstream.references if downstream is not None else frozenset()

    def method(self, name: str) -> Method:
        oracle = name in self.results.oracles
        return Method(name, oracle, name in self.references, self.colours.get(name, "#888888"))

    def set_tables(self, set_name: str) -> dict[str, Any]:
        """What both reports show of a set besides the HTML page's figures: its tables, its results and the methods
        not evaluated on it, as the templates read them."""
        return {
            "name": set_name,
            "entry": self.results.sets[set_name],
            "table": self.set_table(set_name),
            "channels": self.channel_table(set_name),
            "bands": self.band_table(set_name),
            "missing": self.results.not_evaluated(set_name),
            "cameras": self.camera_tables(set_name),
        }

    def set_table(self, set_name: str) -> Table | None:
        methods = self.results.sets[set_name].methods
        if not methods:
            return None
        best = best_per_metric(self.results, set_name)
        rows = []
        for name in ordered(methods, self.order):
            cells = [_set_cell(methods[name], metric, name in best[metric]) for metric in SET_METRICS]
            rows.append(Row(self.method(name), cells))
        headers = [Header(metric, SET_HEADERS[metric]) for metric in SET_METRICS]
        caption = f"{set_name}: real vs synthetic noise. {LEGEND}"
        return Table("metrics", caption, headers, rows, {})

    def channel_table(self, set_name: str) -> Table | None:
        """Per channel level ratio (σ in 8-bit levels beside it) and channel correlations: the real row, then the
        methods. None when nothing has channel statistics."""
        entry = self.results.sets[set_name]
        sources: list[tuple[Method, ChannelStatistics, bool]] = []
        if entry.real is not None:
            sources.append((Method(REAL, False, True, "#888888"), entry.real, True))
        for name in ordered(entry.methods, self.order):
            channels = entry.methods[name].channels
            if channels is not None:
                sources.append((self.method(name), channels, False))
        if not sources:
            return None
        rows = []
        for method, statistics, is_real in sources:
            cells = []
            for channel in CHANNELS:
                ratio = 1.0 if is_real else statistics.level_ratio.get(channel)
                std = statistics.noise_std.get(channel)
                extra = f"(σ {num(std * 255.0, 3)})" if std is not None and math.isfinite(std) else ""
                cells.append(Cell(f"level_ratio_{channel}", num(ratio, 3), extra, False))
            for pair in CHANNEL_PAIRS:
                cells.append(Cell(f"correlation_{pair}", num(statistics.correlation.get(pair), 3), "", False))
            rows.append(Row(method, cells))
        headers = [Header(key, title) for key, title in CHANNEL_HEADERS.items()]
        caption = f"{set_name}: noise level and channel correlation. {CHANNEL_LEGEND}"
        return Table("channels", caption, headers, rows, {"set": set_name}, set_name)

    def band_table(self, set_name: str) -> Table | None:
        """Per band and component, each method's median band power ratio to the real noise; the real row holds the
        real noise's power relative to white noise. None when nothing has band statistics."""
        entry = self.results.sets[set_name]
        sources = []
        real = entry.real_bands
        if real is not None and (real.white_ratio or real.texture_ratio is not None):
            sources.append((Method(f"{REAL} (× white)", False, True, "#888888"), real.white_ratio, real.texture_ratio))
        for name in ordered(entry.methods, self.order):
            bands = entry.methods[name].bands
            if bands is not None and (bands.ratio or bands.texture_ratio is not None):
                sources.append((self.method(name), bands.ratio, bands.texture_ratio))
        if not sources:
            return None
        rows = []
        for method, values, texture in sources:
            cells = []
            for component in BAND_COMPONENTS:
                row = values.get(component, (None,) * len(BAND_LABELS))
                cells += [Cell(f"{component}_{i}", num(value, 3), "", False) for i, value in enumerate(row)]
            cells.append(Cell("texture_ratio", num(texture, 3), "", False))
            rows.append(Row(method, cells))
        headers = [Header(key, title) for key, title in BAND_HEADERS.items()]
        caption = f"{set_name}: noise power per spatial frequency band. {BAND_LEGEND}"
        return Table("bands", caption, headers, rows, {"set": set_name}, set_name)

    def camera_tables(self, set_name: str) -> list[Table]:
        """One table per per-pair metric that has values: a column per camera (its pair count in the header), a row
        per method."""
        methods = {name: row for name, row in self.results.sets[set_name].methods.items() if row.per_camera}
        counts: dict[str, list[int]] = {}
        for row in methods.values():
            for camera, scores in row.per_camera.items():
                counts.setdefault(camera, [])
                if scores.pairs is not None:
                    counts[camera].append(scores.pairs)
        if not counts:
            return []
        headers = []
        for camera, pairs in counts.items():
            if not pairs:
                title = camera
            elif min(pairs) == max(pairs):
                title = f"{camera} ({pairs[0]} pairs)"
            else:
                title = f"{camera} ({min(pairs)}–{max(pairs)} pairs)"
            headers.append(Header(camera, title, literal=False))
        tables = []
        for metric in CAMERA_METRICS:
            if not any(
                scores.value(metric) is not None for row in methods.values() for scores in row.per_camera.values()
            ):
                continue  # results written before the metric existed
            best = best_per_camera(self.results, set_name, metric)
            rows = []
            for name in ordered(methods, self.order):
                cells = []
                for camera in counts:
                    camera_scores = methods[name].per_camera.get(camera)
                    if camera_scores is None:
                        cells.append(Cell(camera, MISSING, "", False))
                        continue
                    value, extra = num(camera_scores.value(metric)), _interval(camera_scores.interval(metric))
                    cells.append(Cell(camera, value, extra, name in best[camera]))
                rows.append(Row(self.method(name), cells))
            title = SET_TITLES[metric]
            caption = f"{set_name}, per camera: {title} [95% CI]. Lower is better; bold: best blind method."
            tables.append(Table("per-camera", caption, headers, rows, {"metric": metric}, title))
        return tables

    def downstream_tables(self) -> list[Table]:
        downstream = self.results.downstream
        if downstream is None:
            return []
        tables = []
        for set_name, scores in downstream.sets.items():
            best = best_per_downstream_metric(self.results, set_name)
            names = ordered(scores, self.order)
            # Methods first, in the usual order, then the reference rows.
            names = [n for n in names if n not in self.references] + [n for n in names if n in self.references]
            rows = []
            for name in names:
                row = scores[name]
                values = {"psnr": num(row.psnr), "ssim": num(row.ssim), "pairs": num(row.pairs)}
                cells = [Cell(key, values[key], "", name in best[key]) for key in DOWNSTREAM_HEADERS]
                rows.append(Row(self.method(name), cells))
            headers = [Header(key, title) for key, title in DOWNSTREAM_HEADERS.items()]
            caption = f"{set_name}: denoising the real pairs."
            tables.append(Table("downstream", caption, headers, rows, {"set": set_name}, set_name))
        return tables


def run_facts(results: EvaluationResults) -> str:
    """The run's seed and duration, as one phrase."""
    facts = []
    if results.seed is not None:
        facts.append(f"seed {results.seed}")
    if results.seconds is not None:
        facts.append(f"{num(results.seconds)} s")
    return ", ".join(facts)
