"""`darksynth evaluate` as one call: its options, the run (every method on every set of real pairs, then the
optional downstream check) and its three files, ``results.json``, ``results.md`` and ``report.html``.

Importing this module stays cheap (no scipy): the command line reads the options' defaults at start-up.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from darksynth.errors import DarksynthError, error_reason
from darksynth.evaluation.report.html import write_html_report
from darksynth.evaluation.report.summary import write_markdown
from darksynth.evaluation.run.options import EvaluationOptions
from darksynth.io.atomic import write_text_atomic

Progress = Callable[[str], None]
"""Called with a one-line description of what the run is doing."""

RESULT_FILES: Final = ("results.json", "results.md", "report.html")
"""What a run writes into its output folder."""


@dataclass
class EvaluationRun:
    """What a run found and where it wrote it.

    Attributes:
        results: the document written to ``results.json`` (see :func:`darksynth.evaluation.run.runner.evaluate_pairs`;
            ``"downstream"`` filled in when the options ask for the check).
        files: the paths of :data:`RESULT_FILES`, in that order.
    """

    results: dict[str, Any]
    files: tuple[Path, ...]


def run_evaluation(
    pair_roots: Sequence[Path], out: Path, options: EvaluationOptions, *, progress: Progress | None = None
) -> EvaluationRun:
    """Evaluate every method on every set of real pairs, run the downstream check if asked, write the results.

    Problems that leave the rest of the run meaningful (a bad pair, an unavailable method, a failed fit) are
    listed in ``results["problems"]`` (and the downstream check's in ``results["downstream"]["problems"]``).

    Args:
        pair_roots: folders of real pairs (``noisy/NAME``, ``clean/NAME``), or folders of such folders.
        out: the folder to write :data:`RESULT_FILES` into (created).
        options: what to evaluate and how.
        progress: see :data:`Progress`.

    Raises:
        DarksynthError: nothing to evaluate (no set, no method), no usable clean image for the downstream check,
            or a file that cannot be read or written (one line naming it).
    """
    # The runner imports scipy (about 0.7 s): only a run pays for it, not the command line's start.
    from darksynth.evaluation.measures.downstream import run_downstream
    from darksynth.evaluation.run.runner import evaluate_pairs

    say = progress or (lambda message: None)
    try:
        outcome = evaluate_pairs(pair_roots, options, progress=say)
        if options.downstream:
            settings = options.downstream_settings()
            outcome.results["downstream"] = run_downstream(
                pair_roots,
                [name for name in options.methods if name in outcome.results["methods"]],
                options.downstream,
                settings,
                weights=options.weights,
                progress=lambda message: say(f"downstream: {message}"),
            )
        out.mkdir(parents=True, exist_ok=True)
        files = tuple(out / name for name in RESULT_FILES)
        results_json, results_md, report_html = files
        write_text_atomic(results_json, json.dumps(outcome.results, indent=2) + "\n")
        write_markdown(outcome.results, results_md)
        write_html_report(outcome.results, outcome.examples, report_html)
    except OSError as error:
        raise DarksynthError(f"{error.filename or out}: {error_reason(error)}") from None
    return EvaluationRun(outcome.results, files)


def rank_by_kld(results: dict[str, Any]) -> dict[str, list[tuple[str, float]]]:
    """Per set, the methods from the lowest (closest to real noise) to the highest mean KL divergence."""
    return {
        name: sorted(((method, entry["kld"]) for method, entry in report["methods"].items()), key=lambda m: m[1])
        for name, report in results["sets"].items()
    }
