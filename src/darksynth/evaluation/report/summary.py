"""Reports of ``darksynth evaluate``: a Markdown summary and one self-contained HTML page.

Both are Jinja2 templates (``templates/report.md.j2``, ``templates/report.html.j2``) filled from the typed results
(:mod:`darksynth.evaluation.report.results_model`) and their verdicts (:mod:`darksynth.evaluation.report.verdicts`).
This module holds what both reports say (the verdicts in words, the template environment and context) and writes the
Markdown summary; :mod:`darksynth.evaluation.report.tables` lays out the tables both show and
:mod:`darksynth.evaluation.report.html` assembles the HTML page.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jinja2

from darksynth.evaluation.report.results_model import EvaluationResults, parse_results
from darksynth.evaluation.report.tables import (
    BAND_LEGEND,
    CHANNEL_LEGEND,
    DOWNSTREAM_LEGEND,
    LEGEND,
    Layout,
    num,
    run_facts,
)
from darksynth.evaluation.report.verdicts import BeyondPaperCheck, beyond_paper_checks, headlines
from darksynth.io.atomic import write_text_atomic

__all__ = [
    "BEYOND_TITLE",
    "HEADLINE_TITLE",
    "beyond_paper_lines",
    "headline_lines",
    "render_markdown",
    "write_markdown",
]

HEADLINE_TITLE = "Headline: does den have a lower kld than awgn and pg?"
BEYOND_TITLE = "Beyond the paper: den against every blind method, the oracle and the paper's model"


def typed_results(results: EvaluationResults | Mapping[str, Any]) -> EvaluationResults:
    """``results`` as typed results, parsed from a results document unless they already are."""
    return results if isinstance(results, EvaluationResults) else parse_results(results)


# ----------------------------------------------------------------------------------------------------------------
# Verdicts in words


def headline_lines(results: EvaluationResults | Mapping[str, Any]) -> list[str]:
    """One plain sentence per set on the paper's headline claim (den's kld below awgn's and pg's)."""
    lines = []
    for verdict in headlines(typed_results(results)):
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
    return [_check_sentence(check) for check in beyond_paper_checks(typed_results(results))]


# ----------------------------------------------------------------------------------------------------------------
# Templates


def _md(text: str) -> str:
    """Escape Markdown's inline syntax (and table pipes) in free text; newlines become spaces."""
    return re.sub(r"([\\`*_\[\]<>|#])", r"\\\1", " ".join(text.split()))


@functools.cache
def template_environment(*, autoescape: bool) -> jinja2.Environment:
    """The Jinja2 environment of the HTML report (``autoescape``) or of the Markdown one (escaped by hand: ``| md``)."""
    environment = jinja2.Environment(
        loader=jinja2.PackageLoader("darksynth.evaluation.report", "templates"),
        autoescape=autoescape,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    environment.filters["md"] = _md
    environment.filters["num"] = num
    return environment


def template_context(results: EvaluationResults) -> dict[str, Any]:
    """What both templates show besides their tables: the results, the legends, the verdicts in words, the run."""
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
        "facts": run_facts(results),
    }


# ----------------------------------------------------------------------------------------------------------------
# Markdown


def render_markdown(results: EvaluationResults | Mapping[str, Any]) -> str:
    """The Markdown summary of a results document (see :func:`write_markdown`)."""
    typed = typed_results(results)
    layout = Layout(typed, typed.method_order)
    runs = re.findall(r"`+", typed.command)
    fence = "`" * max(3, max((len(run) for run in runs), default=0) + 1)
    template = template_environment(autoescape=False).get_template("report.md.j2")
    return template.render(
        **template_context(typed),
        sets=[layout.set_tables(name) for name in typed.sets],
        downstream_tables=layout.downstream_tables(),
        methods=[layout.method(name) for name in typed.methods],
        fence=fence,
    )


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
            :func:`darksynth.evaluation.report.results_model.parse_results`).
        path: The ``.md`` file to write; parent folders are created.
    """
    write_text_atomic(path, render_markdown(results))
