"""Reports of ``darksynth evaluate``: a Markdown summary and one self-contained HTML page.

Both are Jinja2 templates (``templates/report.md.j2``, ``templates/report.html.j2``) filled from the typed results
(:mod:`darksynth.evaluation.results_model`) and their verdicts (:mod:`darksynth.evaluation.verdicts`); this module
only formats numbers, lays out the tables and draws the images. The HTML page opens offline: its figures
(matplotlib, Agg) and image crops are inline ``data:`` PNGs, its style sheet and its one tiny script are inline, and
a Content-Security-Policy forbids loading anything else.
"""

from __future__ import annotations

import base64
import functools
import io
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jinja2
import numpy as np
from PIL import Image as PILImage

from darksynth.errors import DarksynthError
from darksynth.evaluation.results_model import (
    BAND_COMPONENTS,
    CAMERA_METRICS,
    CHANNEL_PAIRS,
    CHANNELS,
    SET_METRICS,
    ChannelStatistics,
    EvaluationResults,
    Interval,
    parse_results,
)
from darksynth.evaluation.structure import BAND_LABELS
from darksynth.evaluation.verdicts import (
    BeyondPaperCheck,
    best_per_camera,
    best_per_downstream_metric,
    best_per_metric,
    beyond_paper_checks,
    headlines,
)
from darksynth.io.atomic import write_text_atomic

__all__ = [
    "BEYOND_TITLE",
    "HEADLINE_TITLE",
    "ReportExample",
    "beyond_paper_lines",
    "headline_lines",
    "render_html",
    "render_markdown",
    "write_html_report",
    "write_markdown",
]

NOISE_GAIN = 5
"""Noise crops are shown as ``128 + 5 × (noisy − clean)`` in 8-bit levels: ±25 levels span the full grey range,
the same range as the histograms."""

MIN_CROP_DISPLAY = 160
"""Crops narrower than this many CSS pixels are enlarged by a whole factor, pixelated, so the noise grain shows."""

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
RADAR_METRICS = ("kld_naflow", "akld", "band_rms_log_error", "kld_srgb", "kld", "fid", "kid")
CHANNEL_HEADERS = {
    **{f"level_ratio_{c}": f"level ratio {c.upper()}" for c in CHANNELS},
    **{f"correlation_{p}": f"correlation {p[0].upper()}-{p[1].upper()}" for p in CHANNEL_PAIRS},
}
BAND_HEADERS = {
    f"{component}_{index}": f"{component[0].upper()} {label}"
    for component in BAND_COMPONENTS
    for index, label in enumerate(BAND_LABELS)
}
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
    "pixel-independent noise)."
)
HEADLINE_TITLE = "Headline: does den have a lower kld than awgn and pg?"
BEYOND_TITLE = "Beyond the paper: den against every blind method, the oracle and the paper's model"

CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


@dataclass(frozen=True)
class ReportExample:
    """One pair shown in the HTML report: crops to look at and whole-image noise maps to measure.

    Attributes:
        set_name: The set the pair belongs to (a key of ``results["sets"]``).
        pair_name: The pair's name within the set.
        clean: ``(h, w, 3)`` uint8 crop of the clean image.
        noisy: ``"real"`` and each method name -> ``(h, w, 3)`` uint8 crop of the noisy image, same crop as ``clean``.
        noise: ``"real"`` and each method name -> float32 ``(H, W, 3)`` noise map (noisy − clean) of the whole image,
            on the [0, 1] scale.
    """

    set_name: str
    pair_name: str
    clean: np.ndarray
    noisy: dict[str, np.ndarray]
    noise: dict[str, np.ndarray]


def _typed(results: EvaluationResults | Mapping[str, Any]) -> EvaluationResults:
    return results if isinstance(results, EvaluationResults) else parse_results(results)


# ----------------------------------------------------------------------------------------------------------------
# Verdicts in words


def headline_lines(results: EvaluationResults | Mapping[str, Any]) -> list[str]:
    """One plain sentence per set on the paper's headline claim (den's kld below awgn's and pg's)."""
    lines = []
    for verdict in headlines(_typed(results)):
        answer = "yes" if verdict.holds else "NO, the headline does not hold here"
        values = f"den {verdict.den:.3f}, awgn {verdict.awgn:.3f}, pg {verdict.pg:.3f}"
        lines.append(f"{verdict.set_name}: {answer} ({values})")
    return lines


def _check_sentence(check: BeyondPaperCheck) -> str:
    answer = "yes" if check.holds else "NO"
    if check.claim == "blind":
        claim, rival = "kld below every blind method", f"best blind {check.rival}"
    elif check.claim == "oracle":
        claim, rival = f"kld at most 2x {check.rival}", f"2x {check.rival}"
    else:
        claim, rival = f"{check.metric} below {check.rival}", check.rival
    return f"{check.set_name}: {claim}: {answer} (den {check.den:.3f}, {rival} {check.bound:.3f})"


def beyond_paper_lines(results: EvaluationResults | Mapping[str, Any]) -> list[str]:
    """One sentence per set and check: den's kld below every blind method present, at most twice pg-oracle's,
    and den's FID and KID below the paper-faithful model's (den-paper)."""
    return [_check_sentence(check) for check in beyond_paper_checks(_typed(results))]


# ----------------------------------------------------------------------------------------------------------------
# Tables, shared by both reports


def _num(value: float | int | None, digits: int = 4) -> str:
    if value is None:
        return MISSING
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}g}" if math.isfinite(value) else str(value)


def _is_finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


def _interval(interval: Interval | None) -> str:
    return "" if interval is None else f"[{_num(interval[0])}, {_num(interval[1])}]"


@dataclass(frozen=True)
class _Method:
    """How one row name is shown: oracle methods are labelled, reference rows (the noisy input) are no method."""

    name: str
    oracle: bool
    reference: bool
    colour: str

    @property
    def label(self) -> str:
        return f"{self.name} (oracle)" if self.oracle else self.name


@dataclass(frozen=True)
class _Header:
    key: str
    title: str
    literal: bool = True
    """The title is this module's own text, not a name from the results: Markdown shows it unescaped."""


@dataclass(frozen=True)
class _Cell:
    key: str
    value: str
    extra: str
    best: bool


@dataclass(frozen=True)
class _Row:
    method: _Method
    cells: list[_Cell]


@dataclass(frozen=True)
class _Table:
    css_class: str
    caption: str
    headers: list[_Header]
    rows: list[_Row]
    data: dict[str, str]
    """Extra ``data-*`` attributes of the HTML table."""
    title: str = ""


def _ordered(names: Sequence[str] | Mapping[str, Any], order: Sequence[str]) -> list[str]:
    return [n for n in order if n in names] + [n for n in names if n not in order]


class _Layout:
    """The tables of both reports: which rows, in which order, with which values formatted how."""

    def __init__(
        self, results: EvaluationResults, order: Sequence[str], colours: Mapping[str, str] | None = None
    ) -> None:
        self.results = results
        self.order = order
        self.colours = colours or {}
        downstream = results.downstream
        self.references = downstream.references if downstream is not None else frozenset()

    def method(self, name: str) -> _Method:
        oracle = name in self.results.oracles
        return _Method(name, oracle, name in self.references, self.colours.get(name, "#888888"))

    def set_table(self, set_name: str) -> _Table | None:
        methods = self.results.sets[set_name].methods
        if not methods:
            return None
        best = best_per_metric(self.results, set_name)
        rows = []
        for name in _ordered(methods, self.order):
            row = methods[name]
            cells = []
            for metric in SET_METRICS:
                value = row.value(metric)
                extra = _interval(row.interval(metric))
                if metric == "kid" and _is_finite(row.kid_std) and _is_finite(value):
                    extra = f"± {_num(row.kid_std, 2)}"
                cells.append(_Cell(metric, _num(value), extra, name in best[metric]))
            rows.append(_Row(self.method(name), cells))
        headers = [_Header(metric, SET_HEADERS[metric]) for metric in SET_METRICS]
        caption = f"{set_name}: real vs synthetic noise. {LEGEND}"
        return _Table("metrics", caption, headers, rows, {})

    def channel_table(self, set_name: str) -> _Table | None:
        """Per channel level ratio (σ in 8-bit levels beside it) and channel correlations: the real row, then the
        methods. None when nothing has channel statistics."""
        entry = self.results.sets[set_name]
        sources: list[tuple[_Method, ChannelStatistics, bool]] = []
        if entry.real is not None:
            sources.append((_Method(REAL, False, True, "#888888"), entry.real, True))
        for name in _ordered(entry.methods, self.order):
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
                extra = f"(σ {_num(std * 255.0, 3)})" if std is not None and math.isfinite(std) else ""
                cells.append(_Cell(f"level_ratio_{channel}", _num(ratio, 3), extra, False))
            for pair in CHANNEL_PAIRS:
                cells.append(_Cell(f"correlation_{pair}", _num(statistics.correlation.get(pair), 3), "", False))
            rows.append(_Row(method, cells))
        headers = [_Header(key, title) for key, title in CHANNEL_HEADERS.items()]
        caption = f"{set_name}: noise level and channel correlation. {CHANNEL_LEGEND}"
        return _Table("channels", caption, headers, rows, {"set": set_name}, set_name)

    def band_table(self, set_name: str) -> _Table | None:
        """Per band and component, each method's median band power ratio to the real noise; the real row holds the
        real noise's power relative to white noise. None when nothing has band statistics."""
        entry = self.results.sets[set_name]
        sources = []
        if entry.real_bands is not None and entry.real_bands.white_ratio:
            sources.append((_Method(f"{REAL} (× white)", False, True, "#888888"), entry.real_bands.white_ratio))
        for name in _ordered(entry.methods, self.order):
            bands = entry.methods[name].bands
            if bands is not None and bands.ratio:
                sources.append((self.method(name), bands.ratio))
        if not sources:
            return None
        rows = []
        for method, values in sources:
            cells = []
            for component in BAND_COMPONENTS:
                row = values.get(component, (None,) * len(BAND_LABELS))
                cells += [_Cell(f"{component}_{i}", _num(value, 3), "", False) for i, value in enumerate(row)]
            rows.append(_Row(method, cells))
        headers = [_Header(key, title) for key, title in BAND_HEADERS.items()]
        caption = f"{set_name}: noise power per spatial frequency band. {BAND_LEGEND}"
        return _Table("bands", caption, headers, rows, {"set": set_name}, set_name)

    def camera_tables(self, set_name: str) -> list[_Table]:
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
            headers.append(_Header(camera, title, literal=False))
        tables = []
        for metric in CAMERA_METRICS:
            if not any(
                scores.value(metric) is not None for row in methods.values() for scores in row.per_camera.values()
            ):
                continue  # results written before the metric existed
            best = best_per_camera(self.results, set_name, metric)
            rows = []
            for name in _ordered(methods, self.order):
                cells = []
                for camera in counts:
                    camera_scores = methods[name].per_camera.get(camera)
                    if camera_scores is None:
                        cells.append(_Cell(camera, MISSING, "", False))
                        continue
                    value, extra = _num(camera_scores.value(metric)), _interval(camera_scores.interval(metric))
                    cells.append(_Cell(camera, value, extra, name in best[camera]))
                rows.append(_Row(self.method(name), cells))
            title = SET_TITLES[metric]
            caption = f"{set_name}, per camera: {title} [95% CI]. Lower is better; bold: best blind method."
            tables.append(_Table("per-camera", caption, headers, rows, {"metric": metric}, title))
        return tables

    def downstream_tables(self) -> list[_Table]:
        downstream = self.results.downstream
        if downstream is None:
            return []
        tables = []
        for set_name, scores in downstream.sets.items():
            best = best_per_downstream_metric(self.results, set_name)
            names = _ordered(scores, self.order)
            # Methods first, in the usual order, then the reference rows.
            names = [n for n in names if n not in self.references] + [n for n in names if n in self.references]
            rows = []
            for name in names:
                row = scores[name]
                values = {"psnr": _num(row.psnr), "ssim": _num(row.ssim), "pairs": _num(row.pairs)}
                cells = [_Cell(key, values[key], "", name in best[key]) for key in DOWNSTREAM_HEADERS]
                rows.append(_Row(self.method(name), cells))
            headers = [_Header(key, title) for key, title in DOWNSTREAM_HEADERS.items()]
            caption = f"{set_name}: denoising the real pairs."
            tables.append(_Table("downstream", caption, headers, rows, {"set": set_name}, set_name))
        return tables


def _run_facts(results: EvaluationResults) -> str:
    facts = []
    if results.seed is not None:
        facts.append(f"seed {results.seed}")
    if results.seconds is not None:
        facts.append(f"{_num(results.seconds)} s")
    return ", ".join(facts)


# ----------------------------------------------------------------------------------------------------------------
# Templates


def _md(text: str) -> str:
    """Escape Markdown's inline syntax (and table pipes) in free text; newlines become spaces."""
    return re.sub(r"([\\`*_\[\]<>|#])", r"\\\1", " ".join(text.split()))


@functools.cache
def _environment(*, autoescape: bool) -> jinja2.Environment:
    """The Jinja2 environment of the HTML report (``autoescape``) or of the Markdown one (escaped by hand: ``| md``)."""
    environment = jinja2.Environment(
        loader=jinja2.PackageLoader("darksynth.evaluation", "templates"),
        autoescape=autoescape,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    environment.filters["md"] = _md
    environment.filters["num"] = _num
    return environment


def _common(results: EvaluationResults) -> dict[str, Any]:
    return {
        "results": results,
        "legend": LEGEND,
        "downstream_legend": DOWNSTREAM_LEGEND,
        "channel_legend": CHANNEL_LEGEND,
        "band_legend": BAND_LEGEND,
        "headline_title": HEADLINE_TITLE,
        "beyond_title": BEYOND_TITLE,
        "headlines": headline_lines(results),
        "beyond": beyond_paper_lines(results),
        "facts": _run_facts(results),
    }


# ----------------------------------------------------------------------------------------------------------------
# Markdown


def render_markdown(results: EvaluationResults | Mapping[str, Any]) -> str:
    """The Markdown summary of a results document (see :func:`write_markdown`)."""
    typed = _typed(results)
    layout = _Layout(typed, typed.method_order)
    sets = [
        {
            "name": name,
            "entry": entry,
            "table": layout.set_table(name),
            "channels": layout.channel_table(name),
            "bands": layout.band_table(name),
            "missing": typed.not_evaluated(name),
            "cameras": layout.camera_tables(name),
        }
        for name, entry in typed.sets.items()
    ]
    runs = re.findall(r"`+", typed.command)
    fence = "`" * max(3, max((len(run) for run in runs), default=0) + 1)
    methods = [layout.method(name) for name in typed.method_order if name in typed.methods]
    template = _environment(autoescape=False).get_template("report.md.j2")
    downstream = layout.downstream_tables()
    return template.render(**_common(typed), sets=sets, downstream_tables=downstream, methods=methods, fence=fence)


def write_markdown(results: Mapping[str, Any], path: Path) -> None:
    """Write the Markdown summary of ``darksynth evaluate``, atomically.

    Per set: a table of the methods (oracle ones labelled) with the KLD NAFlow and AKLD first, the band RMS log
    error and the channel correlation gap, the KLD sRGB and the paper's KLD (Noise Flow recipe), all with 95%
    intervals where per pair, FID and KID ± std, the best blind value of each column in bold; a table of the noise
    level ratio per channel and the channel correlations, real row first; a table of the band power ratios, real
    row (relative to white noise) first; per-camera tables; then the
    downstream denoising table if any, the problems, the methods, metric recipes, provenance and the command.

    Args:
        results: The runner's document: ``command``, ``provenance``, ``metrics``, ``methods``, ``problems``,
            ``sets`` and ``downstream`` (missing parts are left out of the report; see
            :func:`darksynth.evaluation.results_model.parse_results`).
        path: The ``.md`` file to write; parent folders are created.
    """
    write_text_atomic(path, render_markdown(results))


# ----------------------------------------------------------------------------------------------------------------
# HTML


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _crop_png(pixels: np.ndarray, what: str) -> bytes:
    array = np.asarray(pixels)
    if array.dtype != np.uint8 or array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[2] not in (1, 3)):
        raise ValueError(f"{what}: expected an (h, w, 3) uint8 crop, got {array.dtype} of shape {array.shape}")
    buffer = io.BytesIO()
    PILImage.fromarray(array[:, :, 0] if array.ndim == 3 and array.shape[2] == 1 else array).save(buffer, "PNG")
    return buffer.getvalue()


def _noise_crop(noisy: np.ndarray, clean: np.ndarray) -> np.ndarray | None:
    if noisy.shape != clean.shape:
        return None
    difference = noisy.astype(np.int16) - clean.astype(np.int16)
    return np.clip(128 + NOISE_GAIN * difference, 0, 255).astype(np.uint8)


class _Ids:
    """Stable, unique, readable element ids: ``set-polyu``, ``example-polyu-0001``."""

    def __init__(self) -> None:
        self.used: set[str] = set()

    def __call__(self, prefix: str, name: str) -> str:
        slug = re.sub(r"[^a-z0-9_-]+", "-", name.lower()).strip("-") or "x"
        candidate, index = f"{prefix}-{slug}", 2
        while candidate in self.used:
            candidate, index = f"{prefix}-{slug}-{index}", index + 1
        self.used.add(candidate)
        return candidate


@dataclass(frozen=True)
class _Image:
    uri: str
    alt: str


@dataclass(frozen=True)
class _Crop:
    """One column of an example: ``name`` is ``"clean"``, ``"real"`` or a method (then ``method`` is set)."""

    name: str
    method: _Method | None
    images: list[_Image]


@dataclass(frozen=True)
class _Example:
    id: str
    set_name: str
    pair_name: str
    where: str
    size: tuple[int, int] | None
    """Displayed ``(width, height)`` of the crops in CSS pixels."""
    crops: list[_Crop]
    histogram: _Image | None
    spectrum: _Image | None


@dataclass(frozen=True)
class _Radar:
    image: _Image | None
    axes: str
    """The axes drawn, or (without a chart) the metrics this set has."""


class _HtmlPage:
    """Draws every image of the page and gathers what the HTML template shows."""

    def __init__(self, results: EvaluationResults, examples: Sequence[ReportExample]) -> None:
        try:
            from darksynth.evaluation import figures
        except ImportError as error:  # matplotlib is in the "eval" extra
            raise DarksynthError(
                f"the HTML report needs matplotlib ({error}); install it with: pip install 'darksynth[eval]'"
            ) from error
        self.figures = figures
        self.results = results
        self.examples = examples
        order = list(results.method_order)
        for example in examples:
            order += [n for n in (*example.noisy, *example.noise) if n not in order and n != "real"]
        self.order = order
        self.layout = _Layout(results, order, figures.method_colours(order))
        self.ids = _Ids()
        self.set_ids = {name: self.ids("set", name) for name in results.sets}

    def label(self, name: str) -> str:
        return self.layout.method(name).label

    def radar(self, set_name: str) -> _Radar:
        methods = self.results.sets[set_name].methods
        present = [metric for metric in RADAR_METRICS if any(_is_finite(row.value(metric)) for row in methods.values())]
        if len(present) < 3:
            return _Radar(None, ", ".join(present) or "none")
        order = _ordered(methods, self.order)
        scores = self.figures.radar_scores({n: {m: methods[n].value(m) for m in present} for n in order}, present)
        png = self.figures.radar_png(
            scores,
            [SET_TITLES[m] for m in present],
            self.layout.colours,
            {n: self.label(n) for n in order},
            dashed=self.results.oracles,
            title=f"{set_name}: normalised metrics (outward is better)",
        )
        axes = ", ".join(SET_TITLES[m] for m in present)
        alt = f"Radar chart for {set_name}: {axes} of each method, normalised so that outward is better."
        return _Radar(_Image(_data_uri(png), alt), axes)

    def band_figure(self, set_name: str) -> _Image | None:
        """Band power of the real noise and of each method's, brightness and colour; None without band powers."""
        entry = self.results.sets[set_name]
        real = entry.real_bands.power if entry.real_bands is not None else {}
        methods = {
            name: bands.power
            for name in _ordered(entry.methods, self.order)
            if (bands := entry.methods[name].bands) is not None and bands.power
        }
        if not real and not methods:
            return None
        labels = {name: self.label(name) for name in methods}
        png = self.figures.band_power_png(
            real, methods, BAND_LABELS, self.layout.colours, labels, dashed=self.results.oracles, title=set_name
        )
        alt = f"Noise power per spatial frequency band in {set_name}: real versus each method, brightness and colour."
        return _Image(_data_uri(png), alt)

    def example(self, example: ReportExample) -> _Example:
        where = f"{example.set_name}/{example.pair_name}"
        clean = np.asarray(example.clean)
        size = None
        if clean.ndim >= 2:
            width = clean.shape[1]
            scale = max(1, math.ceil(MIN_CROP_DISPLAY / max(width, 1)))
            size = (width * scale, clean.shape[0] * scale)
        crops = [_Crop("clean", None, [_Image(_data_uri(_crop_png(clean, f"{where}: clean")), f"{where}: clean crop")])]
        for name in ["real", *[m for m in self.order if m in example.noisy]]:
            if name not in example.noisy:
                continue
            noisy = np.asarray(example.noisy[name])
            label = self.label(name)
            images = [(noisy, f"{where}: {label} noisy crop")]
            noise = _noise_crop(noisy, clean)
            if noise is not None:
                images.append((noise, f"{where}: {label} noise (noisy − clean) ×{NOISE_GAIN}, mid-grey is zero"))
            pngs = [_Image(_data_uri(_crop_png(pixels, f"{where}: {label}")), alt) for pixels, alt in images]
            crops.append(_Crop(name, None if name == "real" else self.layout.method(name), pngs))
        histogram = spectrum = None
        if example.noise:
            methods = [m for m in self.order if m in example.noise]
            labels = {n: self.label(n) for n in methods}
            colours = self.layout.colours
            png = self.figures.histogram_png(example.noise, methods, colours, labels)
            histogram = _Image(_data_uri(png), f"Noise histograms of {where}: real versus each method, log scale.")
            png = self.figures.spectrum_png(example.noise, methods, colours, labels)
            spectrum = _Image(_data_uri(png), f"Noise power spectra of {where}: real versus each method, log-log.")
        article_id = self.ids("example", f"{example.set_name}-{example.pair_name}")
        return _Example(article_id, example.set_name, example.pair_name, where, size, crops, histogram, spectrum)

    def render(self) -> str:
        results = self.results
        sets = []
        for name, entry in results.sets.items():
            sets.append(
                {
                    "name": name,
                    "id": self.set_ids[name],
                    "entry": entry,
                    "table": self.layout.set_table(name),
                    "channels": self.layout.channel_table(name),
                    "bands": self.layout.band_table(name),
                    "band_figure": self.band_figure(name),
                    "missing": results.not_evaluated(name),
                    "radar": self.radar(name),
                    "cameras": self.layout.camera_tables(name),
                    "examples": [self.example(e) for e in self.examples if e.set_name == name],
                }
            )
        orphans = [self.example(e) for e in self.examples if e.set_name not in results.sets]
        title = "darksynth evaluate" + (": " + ", ".join(results.sets) if results.sets else "")
        methods = [self.layout.method(name) for name in _ordered(results.methods, self.order)]
        template = _environment(autoescape=True).get_template("report.html.j2")
        return template.render(
            **_common(results),
            title=title,
            csp=CSP,
            sets=sets,
            orphans=orphans,
            methods=methods,
            downstream_tables=self.layout.downstream_tables(),
            noise_gain=NOISE_GAIN,
        )


def render_html(results: EvaluationResults | Mapping[str, Any], examples: Sequence[ReportExample]) -> str:
    """The self-contained HTML report (see :func:`write_html_report`)."""
    return _HtmlPage(_typed(results), examples).render()


def write_html_report(results: Mapping[str, Any], examples: Sequence[ReportExample], path: Path) -> None:
    """Write one self-contained HTML page of ``darksynth evaluate`` results, atomically.

    The page shows the command and provenance; the methods; per set the metrics table (oracle methods labelled,
    best blind values bold), the channel table (level ratio, channel correlations, real row first), the band table
    and a figure of the band powers (real vs each method, brightness and colour), a radar chart
    of the normalised metrics, per-camera tables and the examples (for
    each: clean, real noisy and synthetic noisy crops with their amplified noise, noise histograms and noise power
    spectra, real vs each method); the downstream denoising tables if any; the problems; the metric recipes.
    Everything is inline: it opens offline and its Content-Security-Policy forbids fetching anything.

    Args:
        results: The runner's document (see :func:`write_markdown`).
        examples: The pairs to show, each placed under its set.
        path: The ``.html`` file to write; parent folders are created.

    Raises:
        DarksynthError: matplotlib is not installed.
        ValueError: A crop is not an ``(h, w, 3)`` uint8 array.
    """
    write_text_atomic(path, render_html(results, examples))
