"""Reports of ``darksynth evaluate``: a Markdown summary and one self-contained HTML page.

Both read the runner's JSON document (see :func:`write_markdown`). The HTML page opens offline: its figures
(matplotlib, Agg) and image crops are inline ``data:`` PNGs, its style sheet and its one tiny script are inline, and
a Content-Security-Policy forbids loading anything else.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np
from PIL import Image as PILImage

from darksynth.errors import DarksynthError
from darksynth.io.atomic import write_text_atomic

__all__ = ["ReportExample", "render_html", "render_markdown", "write_html_report", "write_markdown"]

NOISE_GAIN = 5
"""Noise crops are shown as ``128 + 5 × (noisy − clean)`` in 8-bit levels: ±25 levels span the full grey range,
the same range as the histograms."""

MIN_CROP_DISPLAY = 160
"""Crops narrower than this many CSS pixels are enlarged by a whole factor, pixelated, so the noise grain shows."""


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


@dataclass(frozen=True)
class _Column:
    key: str
    title: str
    ci: str | None = None
    std: str | None = None
    higher_is_better: bool = False
    ranked: bool = True


@dataclass(frozen=True)
class _Cell:
    value: str
    extra: str
    best: bool


SET_COLUMNS = (
    _Column("kld", "KLD", ci="kld_ci95"),
    _Column("kld_srgb", "KLD sRGB", ci="kld_srgb_ci95"),
    _Column("fid", "FID"),
    _Column("kid", "KID", std="kid_std"),
)
CAMERA_METRICS = (("kld", "KLD", "kld_ci95"), ("kld_srgb", "KLD sRGB", "kld_srgb_ci95"))
DOWNSTREAM_COLUMNS = (
    _Column("psnr", "PSNR (dB)", higher_is_better=True),
    _Column("ssim", "SSIM", higher_is_better=True),
    _Column("pairs", "pairs", ranked=False),
)
NOISY_INPUT = "noisy input"  # the downstream reference row: the unprocessed real noisy images
RADAR_METRICS = ("kld", "kld_srgb", "fid", "kid")
MISSING = "—"
DOWNSTREAM_LEGEND = (
    "PSNR and SSIM of a denoiser trained on each method's synthetic noise, on the real pairs; the noisy input row "
    "is the unprocessed noisy image. Higher is better. Bold: the best blind method in each column."
)

LEGEND = (
    "Lower is better for every metric. Bold: the best blind method in each column; oracle methods, which are "
    "given the clean image, are labelled (oracle) and never bold. Brackets: 95% confidence interval; KID ± its "
    f"standard deviation; {MISSING}: not computed."
)


# ----------------------------------------------------------------------------------------------------------------
# Reading the results document


def _finite(value: object) -> TypeGuard[float]:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _num(value: object, digits: int = 4) -> str:
    if value is None:
        return MISSING
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if isinstance(value, float):
        return f"{value:.{digits}g}" if math.isfinite(value) else str(value)
    return str(value)


def _interval(value: object) -> str:
    if isinstance(value, list | tuple) and len(value) == 2 and all(_finite(v) for v in value):
        return f"[{_num(value[0])}, {_num(value[1])}]"
    return ""


def _text(value: object) -> str:
    return value if isinstance(value, str) else json.dumps(value, indent=1, sort_keys=True, default=str)


def _dict(value: object) -> dict[str, Any]:
    return {str(k): v for k, v in value.items()} if isinstance(value, Mapping) else {}


def _sets(results: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    return {name: _dict(entry) for name, entry in _dict(results.get("sets")).items()}


def _set_methods(entry: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    return {name: _dict(row) for name, row in _dict(entry.get("methods")).items()}


def _method_order(results: Mapping[str, Any], examples: Sequence[ReportExample] = ()) -> list[str]:
    """Methods in the runner's order, then any only found in a set or an example."""
    order = list(_dict(results.get("methods")))
    extra: list[str] = []
    for entry in _sets(results).values():
        extra.extend(_set_methods(entry))
    for example in examples:
        extra.extend(example.noisy)
        extra.extend(example.noise)
    for name in extra:
        if name not in order and name != "real":
            order.append(name)
    return order


def _oracles(results: Mapping[str, Any]) -> set[str]:
    """Methods that use the clean image: flagged so by the runner, or, when it says nothing, named ``*-oracle``."""
    flags: dict[str, bool] = {}
    for name, info in _dict(results.get("methods")).items():
        if isinstance(info, Mapping) and "oracle" in info:
            flags[name] = bool(info["oracle"])
    for entry in _sets(results).values():
        for name, row in _set_methods(entry).items():
            if "oracle" in row:
                flags[name] = flags.get(name, False) or bool(row["oracle"])
    return {n for n in set(_method_order(results)) | set(flags) if flags.get(n, n.endswith("-oracle"))}


def _labeller(oracles: set[str]) -> Callable[[str], str]:
    return lambda name: f"{name} (oracle)" if name in oracles else name


def _cells(
    rows: Mapping[str, Mapping[str, Any]], columns: Sequence[_Column], unranked: set[str]
) -> dict[str, list[_Cell]]:
    """Formatted cells per method; ``best`` marks the best finite value of each ranked column among the rows not in
    ``unranked`` (the oracle methods, and reference rows such as the noisy input)."""
    best: list[float | None] = []
    for column in columns:
        blind = [
            float(row[column.key]) for n, row in rows.items() if n not in unranked and _finite(row.get(column.key))
        ]
        blind = blind if column.ranked else []
        best.append((max(blind) if column.higher_is_better else min(blind)) if blind else None)
    cells: dict[str, list[_Cell]] = {}
    for name, row in rows.items():
        cells[name] = []
        for column, top in zip(columns, best, strict=True):
            value = row.get(column.key)
            extra = _interval(row.get(column.ci)) if column.ci else ""
            if column.std and _finite(row.get(column.std)) and _finite(value):
                extra = f"± {_num(row[column.std], 2)}"
            is_best = name not in unranked and top is not None and _finite(value) and float(value) == top
            cells[name].append(_Cell(_num(value), extra, is_best))
    return cells


def _camera_table(
    methods: Mapping[str, Mapping[str, Any]], metric: str, ci: str, title: str
) -> tuple[list[_Column], dict[str, dict[str, Any]], dict[str, str]]:
    """Columns (one per camera), rows (method -> camera values) and header texts of one per-camera table."""
    cameras: dict[str, list[int]] = {}
    rows: dict[str, dict[str, Any]] = {}
    for name, entry in methods.items():
        per_camera = {camera: _dict(values) for camera, values in _dict(entry.get("per_camera")).items()}
        if not per_camera:
            continue
        rows[name] = {}
        for camera, values in per_camera.items():
            if _finite(values.get("pairs")):
                cameras.setdefault(camera, []).append(int(values["pairs"]))
            else:
                cameras.setdefault(camera, [])
            rows[name][camera] = values.get(metric)
            rows[name][f"{camera}\0ci"] = values.get(ci)
    headers: dict[str, str] = {}
    for camera, counts in cameras.items():
        if not counts:
            headers[camera] = camera
        elif min(counts) == max(counts):
            headers[camera] = f"{camera} ({counts[0]} pairs)"
        else:
            headers[camera] = f"{camera} ({min(counts)}–{max(counts)} pairs)"
    columns = [_Column(camera, f"{title}: {camera}", ci=f"{camera}\0ci") for camera in cameras]
    return columns, rows, headers


def _ordered(rows: Mapping[str, Any], order: Sequence[str]) -> list[str]:
    return [n for n in order if n in rows] + [n for n in rows if n not in order]


@dataclass(frozen=True)
class _DownstreamReport:
    sets: dict[str, dict[str, dict[str, Any]]]
    settings: dict[str, Any]
    notes: dict[str, Any]
    problems: list[str]
    references: set[str]


def _downstream(results: Mapping[str, Any]) -> _DownstreamReport | None:
    """The downstream denoising results: per-set tables (set -> method -> psnr, ssim, pairs), the settings, other
    notes (LPIPS status, clean images...), its own problems, and the reference rows (the noisy input, and any row
    that is not a method) that are shown but never bold."""
    downstream = results.get("downstream")
    if not isinstance(downstream, Mapping):
        return None
    data = _dict(downstream)
    settings = _dict(data.pop("settings", None))
    problems = [_text(p) for p in data.pop("problems", None) or []]
    known = set(_dict(data.pop("methods", None))) | set(_method_order(results))
    sets: dict[str, dict[str, dict[str, Any]]] = {}
    notes: dict[str, Any] = {}
    for key, value in data.items():
        rows = {name: _dict(row) for name, row in _dict(value).items()}
        if rows and all(rows.values()) and any("psnr" in row or "ssim" in row for row in rows.values()):
            sets[key] = rows
        else:
            notes[key] = value
    references = {
        name for rows in sets.values() for name in rows if name == NOISY_INPUT or (known and name not in known)
    }
    return _DownstreamReport(sets, settings, notes, problems, references)


def _downstream_order(rows: Mapping[str, Any], order: Sequence[str], references: set[str]) -> list[str]:
    """Methods first, in the usual order, then the reference rows."""
    names = _ordered(rows, order)
    return [n for n in names if n not in references] + [n for n in names if n in references]


def _not_evaluated(results: Mapping[str, Any], entry: Mapping[str, Any]) -> list[str]:
    present = _set_methods(entry)
    return [name for name in _dict(results.get("methods")) if name not in present]


def _run_facts(results: Mapping[str, Any]) -> str:
    facts = []
    if "seed" in results:
        facts.append(f"seed {_text(results['seed'])}")
    if _finite(results.get("seconds")):
        facts.append(f"{_num(results['seconds'])} s")
    return ", ".join(facts)


# ----------------------------------------------------------------------------------------------------------------
# Markdown


def _md(text: object) -> str:
    """Escape Markdown's inline syntax (and table pipes) in free text; newlines become spaces."""
    flat = " ".join(_text(text).split())
    return re.sub(r"([\\`*_\[\]<>|#])", r"\\\1", flat)


def _md_cell(cell: _Cell) -> str:
    value = f"**{cell.value}**" if cell.best else cell.value
    return f"{value} {cell.extra}" if cell.extra else value


def _md_table(
    headers: Sequence[str], order: Sequence[str], cells: Mapping[str, Sequence[_Cell]], label: Callable[[str], str]
) -> list[str]:
    lines = ["| " + " | ".join(["method", *headers]) + " |", "| :-- |" + " --: |" * len(headers)]
    for name in order:
        lines.append("| " + " | ".join([_md(label(name)), *(_md_cell(c) for c in cells[name])]) + " |")
    return lines


HEADLINE_TITLE = "Headline: does den have a lower kld than awgn and pg?"


def headline_lines(results: Mapping[str, Any]) -> list[str]:
    """One plain sentence per set on the paper's headline claim (den's kld below awgn's and pg's)."""
    lines = []
    for set_name, entry in _sets(results).items():
        methods = _set_methods(entry)
        if not all(name in methods for name in ("den", "awgn", "pg")):
            continue
        values = {name: methods[name].get("kld") for name in ("den", "awgn", "pg")}
        kld = {name: float(v) for name, v in values.items() if isinstance(v, (int, float))}
        if len(kld) < len(values):
            continue
        holds = kld["den"] < min(kld["awgn"], kld["pg"])
        verdict = "yes" if holds else "NO, the headline does not hold here"
        lines.append(f"{set_name}: {verdict} (den {kld['den']:.3f}, awgn {kld['awgn']:.3f}, pg {kld['pg']:.3f})")
    return lines


BEYOND_TITLE = "Beyond the paper: den against every blind method, the oracle and the paper's model"

BLIND_METHODS = ("awgn", "awgn-blind", "pg", "pg-blind", "starlight")
"""The methods that see neither the clean image nor any real noise beyond the reference (den's peers)."""


def _number_or_none(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def beyond_paper_lines(results: Mapping[str, Any]) -> list[str]:
    """One sentence per set and check: den's kld below every blind method present, at most twice pg-oracle's,
    and den's FID and KID below the paper-faithful model's (den-paper)."""
    lines = []
    for set_name, entry in _sets(results).items():
        methods = _set_methods(entry)
        den = methods.get("den")
        if den is None:
            continue
        kld = _number_or_none(den.get("kld"))
        checks = []
        blind = {
            name: value
            for name in BLIND_METHODS
            if name in methods and (value := _number_or_none(methods[name].get("kld"))) is not None
        }
        if kld is not None and blind:
            best = min(blind, key=lambda name: blind[name])
            verdict = "yes" if kld < blind[best] else "NO"
            checks.append(
                f"kld below every blind method: {verdict} (den {kld:.3f}, best blind {best} {blind[best]:.3f})"
            )
        oracle = _number_or_none(methods.get("pg-oracle", {}).get("kld"))
        if kld is not None and oracle is not None:
            verdict = "yes" if kld <= 2 * oracle else "NO"
            checks.append(f"kld at most 2x pg-oracle: {verdict} (den {kld:.3f}, 2x pg-oracle {2 * oracle:.3f})")
        paper = methods.get("den-paper")
        if paper is not None:
            for metric in ("fid", "kid"):
                ours, theirs = _number_or_none(den.get(metric)), _number_or_none(paper.get(metric))
                if ours is not None and theirs is not None:
                    verdict = "yes" if ours < theirs else "NO"
                    checks.append(f"{metric} below den-paper: {verdict} (den {ours:.3f}, den-paper {theirs:.3f})")
        lines += [f"{set_name}: {check}" for check in checks]
    return lines


def render_markdown(results: Mapping[str, Any]) -> str:
    """The Markdown summary of a results document (see :func:`write_markdown`)."""
    order = _method_order(results)
    oracles = _oracles(results)
    label = _labeller(oracles)
    lines = ["# darksynth evaluate: real vs synthetic noise", "", LEGEND]
    headline = headline_lines(results)
    if headline:
        lines += ["", f"## {HEADLINE_TITLE}", ""] + [f"- {_md(line)}" for line in headline]
    beyond = beyond_paper_lines(results)
    if beyond:
        lines += ["", f"## {BEYOND_TITLE}", ""] + [f"- {_md(line)}" for line in beyond]
    headers = [f"{c.title} [95% CI]" if c.ci else f"{c.title} ± std" if c.std else c.title for c in SET_COLUMNS]
    for set_name, entry in _sets(results).items():
        methods = _set_methods(entry)
        lines += ["", f"## {_md(set_name)} ({_num(entry.get('pairs'))} pairs)", ""]
        if methods:
            rows = _ordered(methods, order)
            lines += _md_table(headers, rows, _cells(methods, SET_COLUMNS, oracles), label)
        else:
            lines.append("No method was evaluated on this set.")
        missing = _not_evaluated(results, entry)
        if missing:
            lines += ["", f"Not evaluated on this set: {_md(', '.join(missing))} (see Problems)."]
        for metric, title, ci in CAMERA_METRICS:
            columns, camera_rows, camera_headers = _camera_table(methods, metric, ci, title)
            if not columns:
                continue
            lines += ["", f"### {_md(set_name)} per camera: {title} [95% CI]", ""]
            cells = _cells(camera_rows, columns, oracles)
            lines += _md_table(
                [_md(camera_headers[c.key]) for c in columns], _ordered(camera_rows, order), cells, label
            )
    downstream = _downstream(results)
    if downstream is not None:
        lines += ["", "## Downstream denoising", "", DOWNSTREAM_LEGEND]
        for title, info in (("Settings", downstream.settings), ("Notes", downstream.notes)):
            if info:
                lines += ["", f"{title}: " + "; ".join(f"{_md(k)} = {_md(v)}" for k, v in info.items()) + "."]
        headers = [c.title for c in DOWNSTREAM_COLUMNS]
        for set_name, downstream_rows in downstream.sets.items():
            lines += ["", f"### {_md(set_name)}: denoising", ""]
            cells = _cells(downstream_rows, DOWNSTREAM_COLUMNS, oracles | downstream.references)
            names = _downstream_order(downstream_rows, order, downstream.references)
            lines += _md_table(headers, names, cells, label)
        if downstream.problems:
            lines += ["", "Problems of the downstream run:", ""] + [f"- {_md(p)}" for p in downstream.problems]
    problems = results.get("problems") or []
    lines += ["", "## Problems", ""]
    lines += [f"- {_md(problem)}" for problem in problems] if problems else ["None."]
    method_info = _dict(results.get("methods"))
    if method_info:
        lines += ["", "## Methods", ""]
        for name in order:
            if name in method_info:
                summary = _dict(method_info[name]).get("summary", "")
                lines.append(f"- **{_md(label(name))}**: {_md(summary)}")
    for title, key in (("Metrics", "metrics"), ("Provenance", "provenance")):
        info = _dict(results.get(key))
        if info:
            lines += ["", f"## {title}", ""] + [f"- **{_md(k)}**: {_md(v)}" for k, v in info.items()]
    command = _text(results.get("command", ""))
    fence = "`" * max(3, max((len(run) for run in re.findall(r"`+", command)), default=0) + 1)
    lines += ["", "## Command", "", fence, command, fence]
    facts = _run_facts(results)
    if facts:
        lines += ["", facts[0].upper() + facts[1:] + "."]
    return "\n".join(lines) + "\n"


def write_markdown(results: dict[str, Any], path: Path) -> None:
    """Write the Markdown summary of ``darksynth evaluate``, atomically.

    Per set: a table of the methods (oracle ones labelled) with KLD and sRGB KLD and their 95% intervals, FID and
    KID ± std, the best blind value of each column in bold; per-camera KLD tables; then the downstream denoising
    table if any, the problems, the methods, metric recipes, provenance and the command.

    Args:
        results: The runner's document: ``command``, ``provenance``, ``metrics``, ``methods``, ``problems``,
            ``sets`` and ``downstream`` (missing parts are left out of the report).
        path: The ``.md`` file to write; parent folders are created.
    """
    write_text_atomic(path, render_markdown(results))


# ----------------------------------------------------------------------------------------------------------------
# HTML

CSS = """
:root { color-scheme: light; --ink: #1d1d1f; --muted: #5f6368; --rule: #e2e2e6; --band: #f4f4f7; }
* { box-sizing: border-box; }
body { margin: 0 auto; max-width: 1180px; padding: 1.2rem 1.5rem 3rem; color: var(--ink); background: #fff;
  font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", "Liberation Sans", sans-serif; }
h1 { font-size: 1.7rem; margin: .4rem 0 .6rem; }
h2 { font-size: 1.35rem; margin: 2.4rem 0 .8rem; padding-bottom: .25rem; border-bottom: 2px solid var(--rule); }
h3 { font-size: 1.1rem; margin: 1.6rem 0 .5rem; }
h2 .count { font-size: .9rem; font-weight: normal; color: var(--muted); margin-left: .5rem; }
p.legend, p.note, figcaption, caption { color: var(--muted); font-size: .88rem; }
pre { background: var(--band); padding: .6rem .8rem; border-radius: 6px; white-space: pre-wrap;
  overflow-wrap: anywhere; font-size: .85rem; margin: .3rem 0; }
nav.toc { margin: .8rem 0; font-size: .92rem; }
nav.toc a { margin-right: 1rem; }
a { color: #1a5fb4; }
dl { display: grid; grid-template-columns: max-content 1fr; gap: .25rem 1rem; margin: .5rem 0; }
dt { font-weight: 600; }
dd { margin: 0; }
dd pre { margin: 0; }
table { border-collapse: collapse; margin: .4rem 0 1rem; font-variant-numeric: tabular-nums; font-size: .92rem; }
caption { caption-side: top; text-align: left; padding-bottom: .3rem; }
th, td { padding: .32rem .75rem; border-bottom: 1px solid var(--rule); text-align: right; white-space: nowrap; }
th:first-child, td:first-child { text-align: left; }
th.text, td.text, td.summary { text-align: left; }
td.summary { white-space: normal; }
thead th { background: var(--band); border-bottom: 2px solid #cfcfd6; }
td.best { background: #e8f5e9; }
td .ci { color: var(--muted); font-size: .85em; margin-left: .3em; }
tr.oracle td { background: #fff7e0; font-style: italic; }
tr.reference th, tr.reference td { color: var(--muted); font-style: italic; }
.oracle-label { font-style: normal; font-size: .75rem; color: #8a5a00; background: #ffe8b0; border-radius: 4px;
  padding: 0 .35rem; margin-left: .35rem; }
.swatch { display: inline-block; width: .8rem; height: .8rem; border-radius: 2px; margin-right: .4rem;
  vertical-align: -1px; }
figure { margin: .6rem 0 1.2rem; }
figure.chart img { max-width: 100%; height: auto; display: block; }
.crops { display: flex; flex-wrap: wrap; gap: .8rem .6rem; margin: .6rem 0 1rem; }
.crops figure { margin: 0; }
.crops img { display: block; image-rendering: pixelated; max-width: 100%; }
.crops img + img { margin-top: 3px; }
.crops figcaption { font-size: .85rem; color: var(--ink); margin-top: .2rem; }
article.example { border-top: 1px dashed var(--rule); margin-top: 1.5rem; }
ul.problems li { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: .85rem; }
"""

SCRIPT = """
window.addEventListener("load", function () {
  var images = Array.prototype.slice.call(document.images);
  var loaded = images.filter(function (image) { return image.complete && image.naturalWidth > 0; });
  document.body.dataset.imagesLoaded = String(loaded.length);
  document.body.dataset.imagesTotal = String(images.length);
});
"""

CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


def _e(text: object) -> str:
    return html.escape(_text(text), quote=True)


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


class _Html:
    def __init__(self, results: Mapping[str, Any], examples: Sequence[ReportExample]) -> None:
        try:
            from darksynth.evaluation import figures
        except ImportError as error:  # matplotlib is in the "eval" extra
            raise DarksynthError(
                f"the HTML report needs matplotlib ({error}); install it with: pip install 'darksynth[eval]'"
            ) from error
        self.figures = figures
        self.results = results
        self.examples = examples
        self.order = _method_order(results, examples)
        self.oracles = _oracles(results)
        self.label = _labeller(self.oracles)
        self.colours = figures.method_colours(self.order)
        self.ids = _Ids()
        self.metric_text = {k: _text(v) for k, v in _dict(results.get("metrics")).items()}
        self.set_ids = {name: self.ids("set", name) for name in _sets(results)}
        self.downstream = _downstream(results)
        self.references = self.downstream.references if self.downstream is not None else set()

    # -- small pieces

    def method_name(self, name: str) -> str:
        if name in self.references:
            return f'<span class="name">{_e(name)}</span>'
        swatch = f'<span class="swatch" style="background:{self.colours.get(name, "#888888")}"></span>'
        oracle = '<span class="oracle-label">oracle</span>' if name in self.oracles else ""
        return f'{swatch}<span class="name">{_e(name)}</span>{oracle}'

    def row_attrs(self, name: str) -> str:
        classes = "reference" if name in self.references else "method oracle" if name in self.oracles else "method"
        return f'class="{classes}" data-method="{_e(name)}"'

    def table(
        self,
        css_class: str,
        caption: str,
        columns: Sequence[_Column],
        headers: Sequence[str],
        rows: Mapping[str, Mapping[str, Any]],
        attrs: str = "",
        excluded: set[str] | None = None,
        names: Sequence[str] | None = None,
    ) -> list[str]:
        """A table with one row per method (``names``, by default in the usual order); ``excluded`` rows (by default
        the oracles) are never bold."""
        cells = _cells(rows, columns, self.oracles if excluded is None else excluded)
        out = [f'<table class="{css_class}"{attrs}>', f"<caption>{_e(caption)}</caption>", "<thead><tr>"]
        out.append('<th scope="col">method</th>')
        for column, header in zip(columns, headers, strict=True):
            title = self.metric_text.get(column.key)
            tip = f' title="{_e(title)}"' if title else ""
            out.append(f'<th scope="col" data-metric="{_e(column.key)}"{tip}>{_e(header)}</th>')
        out.append("</tr></thead><tbody>")
        for name in _ordered(rows, self.order) if names is None else names:
            out.append(f'<tr {self.row_attrs(name)}><th scope="row">{self.method_name(name)}</th>')
            for column, cell in zip(columns, cells[name], strict=True):
                value = f"<strong>{_e(cell.value)}</strong>" if cell.best else _e(cell.value)
                extra = f'<span class="ci">{_e(cell.extra)}</span>' if cell.extra else ""
                best = ' class="best"' if cell.best else ""
                out.append(f'<td data-metric="{_e(column.key)}"{best}><span class="value">{value}</span>{extra}</td>')
            out.append("</tr>")
        out.append("</tbody></table>")
        return out

    def chart(self, css_class: str, png: bytes, alt: str, caption: str) -> list[str]:
        return [
            f'<figure class="chart {css_class}">',
            f'<img src="{_data_uri(png)}" alt="{_e(alt)}">',
            f"<figcaption>{caption}</figcaption>",
            "</figure>",
        ]

    # -- sections

    def header(self) -> list[str]:
        sets = list(_sets(self.results))
        out = ["<header>", "<h1>darksynth evaluate: real vs synthetic noise</h1>"]
        out.append(f'<pre class="command" id="command"><code>{_e(self.results.get("command", ""))}</code></pre>')
        facts = _run_facts(self.results)
        if facts:
            out.append(f'<p class="note">{_e(facts)}</p>')
        provenance = _dict(self.results.get("provenance"))
        if provenance:
            out.append('<dl class="provenance">')
            for key, value in provenance.items():
                out.append(f"<dt>{_e(key)}</dt><dd><pre>{_e(value)}</pre></dd>")
            out.append("</dl>")
        links = [('<a href="#methods">methods</a>')]
        links += [f'<a href="#{self.set_ids[name]}">{_e(name)}</a>' for name in sets]
        if _downstream(self.results) is not None:
            links.append('<a href="#downstream">downstream</a>')
        links += ['<a href="#problems">problems</a>', '<a href="#metric-recipes">metrics</a>']
        out += ['<nav class="toc">' + "".join(links) + "</nav>", "</header>"]
        return out

    def methods_section(self) -> list[str]:
        info = _dict(self.results.get("methods"))
        out = ['<section id="methods">', "<h2>Methods</h2>"]
        if not info:
            return [*out, '<p class="note">The results list no methods.</p>', "</section>"]
        out.append('<table class="methods"><thead><tr><th scope="col">method</th>')
        out.append('<th scope="col" class="text">uses the clean image</th><th scope="col" class="text">summary</th>')
        out.append("</tr></thead><tbody>")
        for name in _ordered(info, self.order):
            details = _dict(info[name])
            oracle = "yes (oracle)" if name in self.oracles else "no"
            out.append(f'<tr {self.row_attrs(name)}><th scope="row">{self.method_name(name)}</th>')
            out.append(f'<td class="text">{oracle}</td><td class="summary">{_e(details.get("summary", ""))}</td></tr>')
        out.append("</tbody></table>")
        return [*out, "</section>"]

    def set_section(self, name: str, entry: Mapping[str, Any]) -> list[str]:
        methods = _set_methods(entry)
        out = [f'<section id="{self.set_ids[name]}" class="set" data-set="{_e(name)}">']
        out.append(f'<h2>{_e(name)}<span class="count">{_e(_num(entry.get("pairs")))} pairs</span></h2>')
        if methods:
            headers = [f"{c.title} [95% CI]" if c.ci else f"{c.title} ± std" if c.std else c.title for c in SET_COLUMNS]
            out += self.table("metrics", f"{name}: real vs synthetic noise. {LEGEND}", SET_COLUMNS, headers, methods)
        else:
            out.append('<p class="note">No method was evaluated on this set.</p>')
        missing = _not_evaluated(self.results, entry)
        if missing:
            out.append(
                f'<p class="note missing">Not evaluated on this set: {_e(", ".join(missing))} (see problems).</p>'
            )
        out += self.radar(name, methods)
        camera_parts: list[str] = []
        for metric, title, ci in CAMERA_METRICS:
            columns, camera_rows, camera_headers = _camera_table(methods, metric, ci, title)
            if columns:
                caption = f"{name}, per camera: {title} [95% CI]. Lower is better; bold: best blind method."
                titles = [camera_headers[c.key] for c in columns]
                camera_parts += self.table(
                    "per-camera", caption, columns, titles, camera_rows, f' data-metric="{metric}"'
                )
        if camera_parts:
            out += ["<h3>Per camera</h3>", *camera_parts]
        set_examples = [example for example in self.examples if example.set_name == name]
        if set_examples:
            out.append("<h3>Examples</h3>")
            for example in set_examples:
                out += self.example(example)
        return [*out, "</section>"]

    def radar(self, set_name: str, methods: Mapping[str, Mapping[str, Any]]) -> list[str]:
        metrics = [m for m in RADAR_METRICS if any(_finite(row.get(m)) for row in methods.values())]
        if len(metrics) < 3:
            shown = ", ".join(metrics) or "none"
            return [f'<p class="note radar-missing">No radar chart: it needs three metrics, this set has {shown}.</p>']
        titles = {c.key: c.title for c in SET_COLUMNS}
        order = _ordered(methods, self.order)
        scores = self.figures.radar_scores({n: methods[n] for n in order}, metrics)
        png = self.figures.radar_png(
            scores,
            [titles[m] for m in metrics],
            self.colours,
            {n: self.label(n) for n in order},
            dashed=self.oracles,
            title=f"{set_name}: normalised metrics (outward is better)",
        )
        axis_list = ", ".join(titles[m] for m in metrics)
        alt = f"Radar chart for {set_name}: {axis_list} of each method, normalised so that outward is better."
        caption = (
            f"Each axis ({_e(axis_list)}) is normalised so that better is outward: score = best / value, where best "
            "is the lowest value of that metric among the methods shown (oracles included, dashed), so the best "
            "method on an axis reaches the outer ring and a method twice as far from the real noise sits halfway. "
            "Values ≤ 0 (possible for the unbiased KID) count as the smallest positive value."
        )
        return self.chart("radar", png, alt, caption)

    def example(self, example: ReportExample) -> list[str]:
        where = f"{example.set_name}/{example.pair_name}"
        article_id = self.ids("example", f"{example.set_name}-{example.pair_name}")
        out = [
            f'<article class="example" id="{article_id}" data-set="{_e(example.set_name)}" '
            f'data-pair="{_e(example.pair_name)}">',
            f"<h4>{_e(where)}</h4>",
        ]
        clean = np.asarray(example.clean)
        width = clean.shape[1] if clean.ndim >= 2 else 1
        scale = max(1, math.ceil(MIN_CROP_DISPLAY / max(width, 1)))
        size = f'width="{width * scale}" height="{clean.shape[0] * scale}"' if clean.ndim >= 2 else ""
        out.append('<div class="crops">')
        out += self.crop_figure("clean", "clean", [(clean, f"{where}: clean crop")], size, where)
        shown = ["real", *[m for m in self.order if m in example.noisy]]
        for name in shown:
            if name not in example.noisy:
                continue
            noisy = np.asarray(example.noisy[name])
            label = self.label(name)
            images = [(noisy, f"{where}: {label} noisy crop")]
            noise = _noise_crop(noisy, clean)
            if noise is not None:
                images.append((noise, f"{where}: {label} noise (noisy − clean) ×{NOISE_GAIN}, mid-grey is zero"))
            out += self.crop_figure(name, label, images, size, where)
        out.append("</div>")
        out.append(
            f'<p class="note">Each column: the noisy crop, and under it the noise (noisy − clean) ×{NOISE_GAIN} '
            "around mid-grey. Real is the camera's noisy image; the others are synthesised from the clean image.</p>"
        )
        methods = [m for m in self.order if m in example.noise]
        labels = {n: self.label(n) for n in methods}
        if example.noise:
            histogram = self.figures.histogram_png(example.noise, methods, self.colours, labels)
            out += self.chart(
                "histogram",
                histogram,
                f"Noise histograms of {where}: real versus each method, log scale.",
                "Noise histograms of the whole image (all channels pooled), real (grey) vs each method (line): "
                "fraction of values per 8-bit level over [−0.1, 0.1] on the [0, 1] scale (±25 levels), log scale; "
                "σ is the standard deviation in 8-bit levels.",
            )
            spectrum = self.figures.spectrum_png(example.noise, methods, self.colours, labels)
            out += self.chart(
                "spectrum",
                spectrum,
                f"Noise power spectra of {where}: real versus each method, log-log.",
                "Radially averaged power spectrum of the noise's luminance (Rec. 709), whole image, averaged over "
                "Hann-windowed square tiles (256 pixels, or the image side if smaller); log-log. Flat means white "
                "(pixel-independent) noise; power falling towards high frequencies means spatially correlated noise "
                "(demosaicing, denoising, compression).",
            )
        return [*out, "</article>"]

    def crop_figure(
        self, name: str, label: str, images: Sequence[tuple[np.ndarray, str]], size: str, where: str
    ) -> list[str]:
        out = [f'<figure class="crop" data-method="{_e(name)}">']
        for pixels, alt in images:
            png = _crop_png(pixels, f"{where}: {label}")
            out.append(f'<img src="{_data_uri(png)}" {size} alt="{_e(alt)}">')
        caption = self.method_name(name) if name not in ("clean", "real") else _e(name)
        return [*out, f"<figcaption>{caption}</figcaption>", "</figure>"]

    def orphan_examples(self) -> list[str]:
        sets = _sets(self.results)
        orphans = [example for example in self.examples if example.set_name not in sets]
        if not orphans:
            return []
        out = ['<section id="other-examples">', "<h2>Other examples</h2>"]
        for example in orphans:
            out += self.example(example)
        return [*out, "</section>"]

    def downstream_section(self) -> list[str]:
        downstream = self.downstream
        if downstream is None:
            return []
        out = [
            '<section id="downstream">',
            "<h2>Downstream denoising</h2>",
            f'<p class="legend">{_e(DOWNSTREAM_LEGEND)}</p>',
        ]
        for css_class, info in (("settings", downstream.settings), ("notes", downstream.notes)):
            if info:
                out.append(f'<dl class="{css_class}">')
                out += [f"<dt>{_e(k)}</dt><dd>{_e(v)}</dd>" for k, v in info.items()]
                out.append("</dl>")
        headers = [c.title for c in DOWNSTREAM_COLUMNS]
        excluded = self.oracles | downstream.references
        for name, rows in downstream.sets.items():
            names = _downstream_order(rows, self.order, downstream.references)
            caption = f"{name}: denoising the real pairs."
            attrs = f' data-set="{_e(name)}"'
            out += self.table("downstream", caption, DOWNSTREAM_COLUMNS, headers, rows, attrs, excluded, names)
        if downstream.problems:
            out.append("<h3>Problems of the downstream run</h3>")
            out += ['<ul class="problems">', *(f"<li>{_e(p)}</li>" for p in downstream.problems), "</ul>"]
        return [*out, "</section>"]

    def problems_section(self) -> list[str]:
        problems = self.results.get("problems") or []
        out = ['<section id="problems">', f"<h2>Problems <span class='count'>{len(problems)}</span></h2>"]
        if not problems:
            return [*out, '<p class="note">None.</p>', "</section>"]
        return [*out, '<ul class="problems">', *(f"<li>{_e(p)}</li>" for p in problems), "</ul>", "</section>"]

    def metrics_section(self) -> list[str]:
        out = ['<section id="metric-recipes">', "<h2>Metrics</h2>"]
        if not self.metric_text:
            return [*out, '<p class="note">No metric descriptions.</p>', "</section>"]
        out.append('<dl class="metric-recipes">')
        out += [f"<dt>{_e(k)}</dt><dd>{_e(v)}</dd>" for k, v in self.metric_text.items()]
        return [*out, "</dl>", "</section>"]

    def headline_section(self) -> list[str]:
        lines = headline_lines(self.results)
        section = []
        if lines:
            items = "".join(f"<li>{_e(line)}</li>" for line in lines)
            section.append(f'<section id="headline"><h2>{_e(HEADLINE_TITLE)}</h2><ul>{items}</ul></section>')
        beyond = beyond_paper_lines(self.results)
        if beyond:
            items = "".join(f"<li>{_e(line)}</li>" for line in beyond)
            section.append(f'<section id="beyond-paper"><h2>{_e(BEYOND_TITLE)}</h2><ul>{items}</ul></section>')
        return section

    def page(self) -> str:
        sets = _sets(self.results)
        title = "darksynth evaluate" + (": " + ", ".join(sets) if sets else "")
        body = [*self.header(), "<main>", *self.headline_section(), *self.methods_section()]
        for name, entry in sets.items():
            body += self.set_section(name, entry)
        body += [
            *self.orphan_examples(),
            *self.downstream_section(),
            *self.problems_section(),
            *self.metrics_section(),
            "</main>",
        ]
        head = [
            "<!DOCTYPE html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f'<meta http-equiv="Content-Security-Policy" content="{CSP}">',
            f"<title>{_e(title)}</title>",
            f"<style>{CSS}</style>",
            "</head>",
            "<body>",
        ]
        return "\n".join([*head, *body, f"<script>{SCRIPT}</script>", "</body>", "</html>"]) + "\n"


def render_html(results: Mapping[str, Any], examples: Sequence[ReportExample]) -> str:
    """The self-contained HTML report (see :func:`write_html_report`)."""
    return _Html(results, examples).page()


def write_html_report(results: dict[str, Any], examples: Sequence[ReportExample], path: Path) -> None:
    """Write one self-contained HTML page of ``darksynth evaluate`` results, atomically.

    The page shows the command and provenance; the methods; per set the metrics table (oracle methods labelled,
    best blind values bold), a radar chart of the normalised metrics, per-camera KLD tables and the examples (for
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
