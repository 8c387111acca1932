"""Figures of the evaluation report, drawn with matplotlib's Agg renderer into PNG bytes, and the numbers behind them.

Nothing here touches pyplot or the global backend: every figure is a :class:`matplotlib.figure.Figure` printed by
a :class:`~matplotlib.backends.backend_agg.FigureCanvasAgg`, so the report can be written from any thread and
never opens a window.
"""

from __future__ import annotations

import io
import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeGuard

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.projections.polar import PolarAxes

from darksynth.tensors import LUMINANCE_WEIGHTS

__all__ = [
    "HISTOGRAM_LEVELS",
    "REAL_COLOUR",
    "MethodStyle",
    "band_power_png",
    "histogram_png",
    "method_colours",
    "noise_histogram",
    "radar_png",
    "radar_scores",
    "radial_power_spectrum",
    "spectrum_png",
]

HISTOGRAM_LEVELS = 25
"""Histograms span ±25.5 8-bit levels (±0.1 on the [0, 1] scale) in bins one level wide, centred on whole levels,
so the noise of 8-bit pairs (multiples of 1/255) never straddles a bin edge."""

SPECTRUM_TILE = 256
SPECTRUM_MAX_TILES = 64
REAL_COLOUR = "#000000"
DPI = 110
_STD_SAMPLE = 4_000_000


def method_colours(methods: Sequence[str]) -> dict[str, str]:
    """One colour per method, in order, from matplotlib's tab10 (tab20 beyond ten methods); real noise is black."""
    from matplotlib import colormaps

    cmap = colormaps["tab10" if len(methods) <= 10 else "tab20"]
    return {name: to_hex(cmap(index % cmap.N)) for index, name in enumerate(methods)}


@dataclass(frozen=True)
class MethodStyle:
    """How every figure draws a method.

    Attributes:
        colours: method name -> colour (grey for a method without one).
        labels: method name -> legend label (its name for a method without one).
        dashed: the methods drawn with dashed lines (the oracles).
    """

    colours: Mapping[str, str]
    labels: Mapping[str, str]
    dashed: Collection[str] = ()

    def colour(self, name: str) -> str:
        return self.colours.get(name, "#555555")

    def label(self, name: str) -> str:
        return self.labels.get(name, name)

    def line(self, name: str) -> str:
        return "--" if name in self.dashed else "-"


def _png(figure: Figure) -> bytes:
    FigureCanvasAgg(figure)
    buffer = io.BytesIO()
    # No "Software" text chunk: it would carry matplotlib's web address into the report.
    figure.savefig(buffer, format="png", dpi=DPI, metadata={"Software": None})
    return buffer.getvalue()


def radar_scores(
    values: Mapping[str, Mapping[str, float | None]], metrics: Sequence[str]
) -> dict[str, list[float | None]]:
    """Normalise lower-is-better metric values so that better is outward: score = best / value, in (0, 1].

    Per metric, ``best`` is the smallest value over all methods given (oracle ones included). Values ≤ 0 (the
    unbiased KID can be slightly negative) cannot be divided by, and are indistinguishable from zero anyway, so they
    count as the smallest positive value of that metric (score 1); if no value is positive, every method scores 1.
    Missing or non-finite values give ``None``.

    Args:
        values: method name -> metric name -> value (missing metrics allowed).
        metrics: The metrics to score, in axis order.

    Returns:
        method name -> one score (or None) per metric.
    """
    scores: dict[str, list[float | None]] = {name: [] for name in values}
    for metric in metrics:
        present = {name: float(v) for name, row in values.items() if _finite(v := row.get(metric))}
        positive = [v for v in present.values() if v > 0]
        floor = min(positive) if positive else None
        for name in values:
            if name not in present:
                scores[name].append(None)
            elif floor is None:
                scores[name].append(1.0)
            else:
                scores[name].append(floor / max(present[name], floor))
    return scores


def _finite(value: object) -> TypeGuard[float]:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def radar_png(
    scores: Mapping[str, Sequence[float | None]],
    axis_labels: Sequence[str],
    style: MethodStyle,
    title: str = "",
) -> bytes:
    """A radar chart like Figure 1 of the DEN paper: one closed polygon per method over the normalised metrics.

    Args:
        scores: method name -> one score in [0, 1] per axis (see :func:`radar_scores`); None is drawn at the centre
            and the legend says which metric is missing.
        axis_labels: One label per axis.
        style: each method's colour, legend label and outline (dashed for the oracles).
        title: Title above the chart.

    Returns:
        PNG bytes.
    """
    figure = Figure(figsize=(7.6, 4.9), layout="constrained")
    ax = figure.add_subplot(projection="polar")
    assert isinstance(ax, PolarAxes)
    angles = np.linspace(0.0, 2.0 * np.pi, len(axis_labels), endpoint=False)
    closed = np.append(angles, angles[0])
    ax.set_theta_offset(np.pi / 2.0)
    ax.set_theta_direction(-1)
    ax.set_thetagrids(np.degrees(angles), list(axis_labels), fontsize=10)
    ax.tick_params(axis="x", pad=14)
    ax.set_ylim(0.0, 1.05)
    ax.set_yticks([0.25, 0.5, 0.75, 1.0], ["0.25", "0.5", "0.75", "1"], fontsize=7, color="#666666")
    ax.set_rlabel_position(22.5)
    for name, row in scores.items():
        radii = np.array([0.0 if s is None else s for s in row] + [0.0 if row[0] is None else row[0]])
        missing = [axis_labels[i] for i, s in enumerate(row) if s is None]
        label = style.label(name) + (f" (no {', '.join(missing)})" if missing else "")
        colour = style.colour(name)
        ax.plot(closed, radii, style.line(name), color=colour, linewidth=1.8, label=label, marker="o", markersize=3.5)
        ax.fill(closed, radii, color=colour, alpha=0.06)
    ax.legend(loc="upper left", bbox_to_anchor=(1.12, 1.02), fontsize=9, frameon=False)
    if title:
        ax.set_title(title, fontsize=11, pad=16)
    return _png(figure)


def noise_histogram(noise: np.ndarray, levels: int = HISTOGRAM_LEVELS) -> tuple[np.ndarray, np.ndarray]:
    """Histogram of a noise map's values, all channels pooled, in bins one 8-bit level wide.

    Args:
        noise: Noise map on the [0, 1] scale, any shape.
        levels: The bins cover ``-levels - 0.5`` to ``levels + 0.5`` 8-bit levels.

    Returns:
        ``(edges, fractions)``: ``2 * levels + 2`` bin edges on the [0, 1] scale, and per bin the fraction of *all*
        values (values outside the range are counted in the total, not re-normalised away).
    """
    half = (levels + 0.5) / 255.0
    values = np.asarray(noise).ravel()
    counts, edges = np.histogram(values, bins=2 * levels + 1, range=(-half, half))
    return edges, counts / max(values.size, 1)


def _std_levels(noise: np.ndarray) -> float:
    values = np.asarray(noise, dtype=np.float32).ravel()
    if values.size > _STD_SAMPLE:
        values = values[:: values.size // _STD_SAMPLE + 1]
    return float(np.std(values)) * 255.0


def radial_power_spectrum(
    noise: np.ndarray, tile: int = SPECTRUM_TILE, max_tiles: int = SPECTRUM_MAX_TILES
) -> tuple[np.ndarray, np.ndarray]:
    """Radially averaged 2-D power spectrum of a noise map's luminance, Welch-style.

    The luminance (Rec. 709 weights, in 8-bit levels) is cut into square tiles (at most ``max_tiles`` of them,
    spread evenly over the image); each tile loses its mean, is multiplied by a 2-D Hann window and Fourier
    transformed; the squared magnitudes, averaged over tiles and divided by the window's energy, are averaged over
    rings of equal spatial frequency. White noise of variance σ² gives a flat spectrum at σ² (levels²); spatially
    correlated noise loses power towards high frequencies.

    Args:
        noise: ``(H, W, 3)`` or ``(H, W)`` noise map on the [0, 1] scale.
        tile: Tile side, reduced to the image's smaller side if that is shorter.
        max_tiles: Most tiles used.

    Returns:
        ``(frequencies, power)``: ring frequencies in cycles per pixel, from ``1 / tile`` to 0.5, and the mean power
        on each ring in levels².

    Raises:
        ValueError: The map is not 2-D or 3-channel, or smaller than 8 pixels on a side.
    """
    array = np.asarray(noise)
    if array.ndim == 3 and array.shape[2] == 3:
        height, width = array.shape[:2]
    elif array.ndim == 2:
        height, width = array.shape
    else:
        raise ValueError(f"noise map of shape {array.shape}: expected (H, W, 3) or (H, W)")
    side = min(tile, height, width)
    if side < 8:
        raise ValueError(f"noise map of {height}x{width} pixels is too small for a power spectrum")
    rows, columns = height // side, width // side
    origins = [(r * side, c * side) for r in range(rows) for c in range(columns)]
    if len(origins) > max_tiles:
        picks = np.unique(np.linspace(0, len(origins) - 1, max_tiles).round().astype(int))
        origins = [origins[i] for i in picks]
    hann = np.hanning(side)
    window = np.outer(hann, hann)
    weights = np.asarray(LUMINANCE_WEIGHTS, dtype=np.float64)
    power = np.zeros((side, side // 2 + 1))
    for start in range(0, len(origins), 16):
        chunk = []
        for top, left in origins[start : start + 16]:
            patch = np.asarray(array[top : top + side, left : left + side], dtype=np.float64)
            chunk.append(patch @ weights if patch.ndim == 3 else patch)
        tiles = np.stack(chunk) * 255.0
        tiles -= tiles.mean(axis=(1, 2), keepdims=True)
        power += (np.abs(np.fft.rfft2(tiles * window)) ** 2).sum(axis=0)
    power /= len(origins) * float((window**2).sum())
    # rfft2 keeps half the plane: interior columns stand for two conjugate coefficients, the first and (for an even
    # side) the last column for one.
    column_weight = np.full(side // 2 + 1, 2.0)
    column_weight[0] = 1.0
    if side % 2 == 0:
        column_weight[-1] = 1.0
    ring_weight = np.broadcast_to(column_weight, power.shape)
    radius = np.rint(np.hypot(np.fft.fftfreq(side)[:, None], np.fft.rfftfreq(side)[None, :]) * side).astype(int)
    sums = np.bincount(radius.ravel(), weights=(power * ring_weight).ravel())
    counts = np.bincount(radius.ravel(), weights=ring_weight.ravel())
    rings = np.arange(1, side // 2 + 1)
    return rings / side, sums[rings] / counts[rings]


def _method_panels(noise: Mapping[str, np.ndarray], methods: Sequence[str]) -> tuple[Figure, list[tuple[Axes, str]]]:
    """Small multiples, one panel per method of ``methods`` that has a noise map (the real noise's panel alone when
    none has one), three to a row, and the figure that holds them."""
    shown = [m for m in methods if m in noise] or ["real"]
    columns = min(3, len(shown))
    rows = math.ceil(len(shown) / columns)
    figure = Figure(figsize=(3.3 * columns, 2.35 * rows + 0.2), layout="constrained")
    grid = figure.subplots(rows, columns, sharex=True, sharey=True, squeeze=False)
    axes = [ax for row in grid for ax in row]
    for ax in axes[len(shown) :]:
        ax.set_visible(False)
    return figure, list(zip(axes[: len(shown)], shown, strict=True))


def _method_title(ax: Axes, name: str, style: MethodStyle) -> str | None:
    """Title a panel with its method's label in the method's colour, and return that colour; None for the real
    noise's panel, titled in the default colour."""
    if name == "real":
        ax.set_title("real", fontsize=10)
        return None
    colour = style.colour(name)
    ax.set_title(style.label(name), fontsize=10, color=colour)
    return colour


def histogram_png(noise: Mapping[str, np.ndarray], methods: Sequence[str], style: MethodStyle) -> bytes:
    """Small multiples of noise histograms: per method, the real noise (grey, filled) under the method's (line).

    Log-scale counts over ±0.1 on the [0, 1] scale; the legend gives each map's standard deviation in 8-bit levels.

    Args:
        noise: ``"real"`` and method names -> noise maps on the [0, 1] scale.
        methods: The methods to draw, in order (those without a map are skipped).
        style: each method's colour and title.

    Returns:
        PNG bytes.
    """
    figure, panels = _method_panels(noise, methods)
    real = noise.get("real")
    real_hist = noise_histogram(real) if real is not None else None
    real_label = f"real σ={_std_levels(real):.2f}" if real is not None else ""
    floor = _hist_floor(real) if real is not None else 1.0
    for ax, name in panels:
        if real_hist is not None:
            edges, fractions = real_hist
            ax.stairs(fractions, edges, fill=True, color="#c4c4c4", label=real_label)
        colour = _method_title(ax, name, style)
        if colour is not None:
            edges, fractions = noise_histogram(noise[name])
            floor = min(floor, _hist_floor(noise[name]))
            ax.stairs(fractions, edges, color=colour, linewidth=1.5, label=f"σ={_std_levels(noise[name]):.2f}")
        ax.set_yscale("log")
        ax.legend(fontsize=7.5, loc="upper right", frameon=False, handlelength=1.2)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.25, linewidth=0.6)
    # The panels share their axes: setting the first's limits sets all.
    first, _ = panels[0]
    half = (HISTOGRAM_LEVELS + 0.5) / 255.0
    first.set_xlim(-half, half)
    first.set_xticks([-0.1, -0.05, 0.0, 0.05, 0.1], ["−0.1", "−0.05", "0", "0.05", "0.1"])
    first.set_ylim(bottom=floor)
    figure.supxlabel("noise, noisy − clean ([0, 1] scale; ±0.1 ≈ ±25 levels of 8 bits)", fontsize=9)
    figure.supylabel("fraction of values (log)", fontsize=9)
    return _png(figure)


def _hist_floor(noise: np.ndarray) -> float:
    # Half of one count: empty bins fall off the bottom of the log axis rather than squash the range.
    return 0.5 / max(int(np.asarray(noise).size), 1)


def spectrum_png(noise: Mapping[str, np.ndarray], methods: Sequence[str], style: MethodStyle) -> bytes:
    """Small multiples of radially averaged noise power spectra (luminance), log-log: real (black) vs each method.

    Takes the arguments of :func:`histogram_png` and returns PNG bytes.
    """
    figure, panels = _method_panels(noise, methods)
    real = _spectrum_or_none(noise.get("real"))
    for ax, name in panels:
        if real is not None:
            ax.loglog(*real, color=REAL_COLOUR, linewidth=1.6, label="real")
        colour = _method_title(ax, name, style)
        spectrum = _spectrum_or_none(noise[name]) if colour is not None else None
        if spectrum is not None:
            ax.loglog(*spectrum, color=colour, linewidth=1.5, label=style.label(name))
        if ax.lines:
            ax.legend(fontsize=7.5, loc="lower left", frameon=False, handlelength=1.2)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.25, linewidth=0.6, which="both")
    figure.supxlabel("spatial frequency (cycles per pixel)", fontsize=9)
    figure.supylabel("luminance noise power (levels²)", fontsize=9)
    return _png(figure)


def _spectrum_or_none(noise: np.ndarray | None) -> tuple[np.ndarray, np.ndarray] | None:
    if noise is None:
        return None
    try:
        return radial_power_spectrum(noise)
    except ValueError:
        return None


def band_power_png(
    real: Mapping[str, Sequence[float | None]],
    methods: Mapping[str, Mapping[str, Sequence[float | None]]],
    band_labels: Sequence[str],
    style: MethodStyle,
    title: str = "",
) -> bytes:
    """Two panels, brightness and colour: band power against band (fine to coarse), log y; real black, methods
    in their colours.

    Args:
        real: ``"brightness"`` and ``"colour"`` -> one band power per band (None: not computed), [0, 1] scale squared.
        methods: method name -> the same for its synthetic noise.
        band_labels: One label per band, in order.
        style: each method's colour, legend label and line (dashed for the oracles).
        title: Title above the panels.

    Returns:
        PNG bytes.
    """
    figure = Figure(figsize=(8.4, 3.3), layout="constrained")
    axes = figure.subplots(1, 2, sharey=True, squeeze=True)
    positions = np.arange(len(band_labels))
    for ax, component in zip(axes, ("brightness", "colour"), strict=True):
        curves = [("real", real, REAL_COLOUR, "-", 2.2)]
        curves += [(style.label(name), row, style.colour(name), style.line(name), 1.5) for name, row in methods.items()]
        for label, row, colour, line, width in curves:
            values = np.array([np.nan if v is None else v for v in row.get(component, ())], dtype=np.float64)
            if values.size != len(band_labels) or not np.isfinite(values).any():
                continue
            # 8-bit levels squared: the axis then reads like the spectra of the examples.
            ax.plot(
                positions,
                values * 255.0**2,
                line,
                color=colour,
                linewidth=width,
                marker="o",
                markersize=3.5,
                label=label,
            )
        ax.set_yscale("log")
        ax.set_xticks(positions, list(band_labels), fontsize=8)
        ax.set_title(component, fontsize=10)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.25, linewidth=0.6, which="both")
    axes[0].set_ylabel("band power (levels²)", fontsize=9)
    if axes[1].lines:
        axes[1].legend(fontsize=7.5, loc="best", frameon=False, handlelength=1.6)
    figure.supxlabel("band, fine → coarse (period in pixels)", fontsize=9)
    if title:
        figure.suptitle(title, fontsize=11)
    return _png(figure)
