"""The HTML report of ``darksynth evaluate``: one self-contained page.

The page opens offline: its figures (matplotlib, Agg) and image crops are inline ``data:`` PNGs, its style sheet and
its one tiny script are inline, and a Content-Security-Policy forbids loading anything else.
"""

from __future__ import annotations

import base64
import io
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image as PILImage

from darksynth.errors import DarksynthError
from darksynth.evaluation.measures.structure import BAND_LABELS
from darksynth.evaluation.report.results_model import EvaluationResults
from darksynth.evaluation.report.summary import template_context, template_environment, typed_results
from darksynth.evaluation.report.tables import SET_TITLES, Layout, Method, is_finite, ordered
from darksynth.io.atomic import write_text_atomic

__all__ = ["ReportExample", "render_html", "write_html_report"]

NOISE_GAIN = 5
"""Noise crops are shown as ``128 + 5 × (noisy − clean)`` in 8-bit levels: ±25 levels span the full grey range,
the same range as the histograms."""

MIN_CROP_DISPLAY = 160
"""Crops narrower than this many CSS pixels are enlarged by a whole factor, pixelated, so the noise grain shows."""

RADAR_METRICS = ("kld_naflow", "akld", "band_rms_log_error", "kld_srgb", "kld", "fid", "kid")

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
    method: Method | None
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
            from darksynth.evaluation.report import figures
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
        self.layout = Layout(results, order, figures.method_colours(order))
        labels = {name: self.label(name) for name in order}
        self.style = figures.MethodStyle(self.layout.colours, labels, dashed=results.oracles)
        self.ids = _Ids()
        self.set_ids = {name: self.ids("set", name) for name in results.sets}

    def label(self, name: str) -> str:
        return self.layout.method(name).label

    def radar(self, set_name: str) -> _Radar:
        methods = self.results.sets[set_name].methods
        present = [metric for metric in RADAR_METRICS if any(is_finite(row.value(metric)) for row in methods.values())]
        if len(present) < 3:
            return _Radar(None, ", ".join(present) or "none")
        order = ordered(methods, self.order)
        scores = self.figures.radar_scores({n: {m: methods[n].value(m) for m in present} for n in order}, present)
        png = self.figures.radar_png(
            scores,
            [SET_TITLES[m] for m in present],
            self.style,
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
            for name in ordered(entry.methods, self.order)
            if (bands := entry.methods[name].bands) is not None and bands.power
        }
        if not real and not methods:
            return None
        png = self.figures.band_power_png(real, methods, BAND_LABELS, self.style, title=set_name)
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
        for name in [m for m in ("real", *self.order) if m in example.noisy]:
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
            png = self.figures.histogram_png(example.noise, methods, self.style)
            histogram = _Image(_data_uri(png), f"Noise histograms of {where}: real versus each method, log scale.")
            png = self.figures.spectrum_png(example.noise, methods, self.style)
            spectrum = _Image(_data_uri(png), f"Noise power spectra of {where}: real versus each method, log-log.")
        article_id = self.ids("example", f"{example.set_name}-{example.pair_name}")
        return _Example(article_id, example.set_name, example.pair_name, where, size, crops, histogram, spectrum)

    def render(self) -> str:
        results = self.results
        sets = [
            self.layout.set_tables(name)
            | {
                "id": self.set_ids[name],
                "band_figure": self.band_figure(name),
                "radar": self.radar(name),
                "examples": [self.example(e) for e in self.examples if e.set_name == name],
            }
            for name in results.sets
        ]
        orphans = [self.example(e) for e in self.examples if e.set_name not in results.sets]
        title = "darksynth evaluate" + (": " + ", ".join(results.sets) if results.sets else "")
        template = template_environment(autoescape=True).get_template("report.html.j2")
        return template.render(
            **template_context(results),
            title=title,
            csp=CSP,
            sets=sets,
            orphans=orphans,
            methods=[self.layout.method(name) for name in results.methods],
            downstream_tables=self.layout.downstream_tables(),
            noise_gain=NOISE_GAIN,
        )


def render_html(results: EvaluationResults | Mapping[str, Any], examples: Sequence[ReportExample]) -> str:
    """The self-contained HTML report (see :func:`write_html_report`)."""
    return _HtmlPage(typed_results(results), examples).render()


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
        results: The runner's document (see :func:`darksynth.evaluation.report.summary.write_markdown`).
        examples: The pairs to show, each placed under its set.
        path: The ``.html`` file to write; parent folders are created.

    Raises:
        DarksynthError: matplotlib is not installed.
        ValueError: A crop is not an ``(h, w, 3)`` uint8 array.
    """
    write_text_atomic(path, render_html(results, examples))
