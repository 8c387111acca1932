"""The `slow` marker still selects the heavy tests, so that `pytest -m "not slow"` stays the quick subset.

`make test` (CI) runs everything, this file included; it collects the suite in a subprocess, as a developer's
`-m slow` run would, and names the heavy tests that must be selected. A renamed heavy test belongs here too.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent

HEAVY_TESTS: dict[str, tuple[str, ...]] = {
    "torchrun": (
        "training/test_distributed.py::test_rank_0_writes_the_files_once_and_both_ranks_hold_the_same_network",
        "training/test_distributed.py::test_resumed_two_process_run_equals_an_uninterrupted_one",
        "training/test_distributed.py::test_a_failure_on_rank_0_stops_the_other_rank_too",
    ),
    "Ray": (
        "datasets/test_ray_convert.py::test_ray_conversion_equals_a_local_one_and_resumes",
        "datasets/test_ray_convert.py::test_cli_ray_flag_converts_and_refuses_local_scheduling_options",
    ),
    "torch.compile": (
        "noise/test_fused_8bit.py::test_compiled_kernel_is_bit_identical_to_eager",
        "test_apply_cli.py::test_compiled_and_eager_runs_write_the_same_bytes",
    ),
    "GAN training": (
        "baselines/test_starlight_training.py::test_training_is_deterministic_changes_the_parameters_and_writes_weights_and_summary",
        "baselines/test_starlight_training.py::test_statistics_matching_alone_moves_the_read_noise_towards_the_target",
    ),
    "Chromium": (
        "evaluation/test_report.py::test_chromium_renders_every_image_and_section",
        "evaluation/test_report.py::test_chromium_screenshot_is_not_blank",
    ),
    "killed and sharded conversions in subprocesses": (
        "datasets/test_convert_resume.py::test_killed_run_resumes_to_the_same_bytes",
        "datasets/test_convert_resume.py::test_shards_partition_and_together_equal_a_full_run",
    ),
    "a folder apply with worker processes, killed": (
        "test_apply_workers.py::test_workers_end_soon_after_the_parent_is_killed",
    ),
    "fuzzing": (
        "test_fuzz.py::test_profile_parser_gives_a_profile_or_a_one_line_error",
        "test_fuzz.py::test_image_reader_gives_an_image_or_a_one_line_error",
        "test_fuzz.py::test_video_reader_gives_frames_or_a_one_line_error",
    ),
    "every evaluation method on every pair": (
        "evaluation/test_evaluate_cli.py::test_reports_check_den_against_every_blind_method_the_oracle_and_the_paper_model",
    ),
}


def _collect(*options: str) -> tuple[set[str], int]:
    """`pytest --collect-only OPTIONS tests/`: the selected test ids (parameters dropped, relative to tests/) and
    the number of tests the options left out."""
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", *options, str(TESTS)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=TESTS.parent,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    prefix = f"{TESTS.name}/"
    selected = {
        line.split("[", 1)[0].removeprefix(prefix) for line in done.stdout.splitlines() if line.startswith(prefix)
    }
    found = re.search(r"\((\d+) deselected\)", done.stdout)
    return selected, int(found.group(1)) if found else 0


@pytest.mark.slow  # collects the whole suite in a subprocess
def test_slow_selects_every_heavy_test_and_leaves_most_of_the_suite_out() -> None:
    slow, left_out = _collect("-m", "slow")
    missing = {kind: [t for t in tests if t not in slow] for kind, tests in HEAVY_TESTS.items()}
    assert not any(missing.values()), f"heavy tests not selected by -m slow (mark them, or rename them here): {missing}"
    assert "test_markers.py::test_slow_selects_every_heavy_test_and_leaves_most_of_the_suite_out" in slow
    # The quick subset is most of the suite: marking everything slow would also pass the check above.
    assert left_out > 10 * len(slow), (left_out, len(slow))
