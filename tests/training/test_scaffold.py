"""The shared training loop: report steps, window means, resumption, the time limit; the shared conventions."""

from __future__ import annotations

from typing import Any

import pytest
import torch
from torch import nn

from darksynth.training.scaffold import (
    Report,
    StepPlan,
    draw_validation_batches,
    initial_weights,
    run_steps,
    single_frame_step,
    validation_seed,
)


class Counting:
    """Step ``s`` has loss ``s``; a report records the step, the window's mean loss and the history's length."""

    def __init__(self) -> None:
        self.steps: list[int] = []
        self.reports: list[Report] = []

    def train_step(self, step: int) -> dict[str, float]:
        self.steps.append(step)
        return {"loss": float(step), "twice": 2.0 * step}

    def report(self, report: Report) -> dict[str, Any] | None:
        self.reports.append(report)
        return {"step": report.step, "mean": report.mean_losses["loss"], "earlier": len(report.history)}


def test_reports_at_every_multiple_and_at_the_last_step_with_the_window_means() -> None:
    task = Counting()
    calls: list[tuple[int, float, dict[str, Any] | None]] = []

    def on_step(step: int, losses: dict[str, float], entry: dict[str, Any] | None) -> None:
        calls.append((step, losses["loss"], entry))

    result = run_steps(task, StepPlan(steps=7, report_every=3), on_step=on_step)
    assert task.steps == [1, 2, 3, 4, 5, 6, 7]
    assert result.history == [
        {"step": 3, "mean": 2.0, "earlier": 0},
        {"step": 6, "mean": 5.0, "earlier": 1},
        {"step": 7, "mean": 7.0, "earlier": 2},
    ]
    assert task.reports[1].mean_losses == {"loss": 5.0, "twice": 10.0}
    assert result.last == result.history[-1]
    assert result.steps == 7 and not result.stopped_by_time_limit and result.seconds >= 0
    assert [call[0] for call in calls] == task.steps
    assert [call[1] for call in calls] == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    assert [call[2] is not None for call in calls] == [False, False, True, False, False, True, True]


def test_a_resumed_loop_continues_the_steps_and_the_history() -> None:
    task = Counting()
    earlier = [{"step": 3, "mean": 2.0, "earlier": 0}]
    result = run_steps(task, StepPlan(steps=6, report_every=3), start=3, history=earlier)
    assert task.steps == [4, 5, 6]
    assert result.history == [*earlier, {"step": 6, "mean": 5.0, "earlier": 1}]
    assert earlier == [{"step": 3, "mean": 2.0, "earlier": 0}], "the caller's list is not changed"


def test_a_loop_with_nothing_left_runs_no_step() -> None:
    task = Counting()
    result = run_steps(task, StepPlan(steps=4, report_every=2), start=4, history=[{"step": 4}])
    assert task.steps == [] and result.steps == 4 and result.history == [{"step": 4}]


def test_reports_that_return_none_leave_the_history_empty() -> None:
    class Silent(Counting):
        def report(self, report: Report) -> dict[str, Any] | None:
            super().report(report)
            return None

    task = Silent()
    result = run_steps(task, StepPlan(steps=4, report_every=2))
    assert [report.step for report in task.reports] == [2, 4] and result.history == [] and result.last is None


def test_the_time_limit_stops_after_the_step_that_passes_it_with_a_report() -> None:
    task = Counting()
    result = run_steps(task, StepPlan(steps=10, report_every=5, max_seconds=0.0))
    assert task.steps == [1]
    assert result.steps == 1 and result.stopped_by_time_limit
    assert result.history == [{"step": 1, "mean": 1.0, "earlier": 0}]


def test_a_time_limit_passed_at_the_last_step_is_no_early_stop() -> None:
    result = run_steps(Counting(), StepPlan(steps=1, report_every=5, max_seconds=0.0))
    assert result.steps == 1 and not result.stopped_by_time_limit


def test_report_every_must_be_positive() -> None:
    with pytest.raises(ValueError, match="report_every"):
        StepPlan(steps=3, report_every=0)


@pytest.mark.parametrize(("every", "single"), [(2, [2, 4, 6]), (3, [3, 6]), (1, [1, 2, 3, 4, 5, 6]), (0, [])])
def test_single_frame_steps_are_every_nth_step_counted_from_one(every: int, single: list[int]) -> None:
    assert [step for step in range(1, 7) if single_frame_step(step, every)] == single


def test_the_validation_set_depends_on_the_seed_only() -> None:
    def draw(generator: torch.Generator) -> torch.Tensor:
        return torch.rand(2, generator=generator)

    first = draw_validation_batches(draw, size=8, batch=2, seed=5)
    torch.manual_seed(99)
    torch.rand(3)
    second = draw_validation_batches(draw, size=8, batch=2, seed=5)
    other = draw_validation_batches(draw, size=8, batch=2, seed=6)
    assert len(first) == 4 and len(draw_validation_batches(draw, size=1, batch=2, seed=5)) == 1
    assert all(torch.equal(a, b) for a, b in zip(first, second, strict=True))
    assert not torch.equal(first[0], first[1]), "one generator drawn in turn, not reseeded per batch"
    assert not torch.equal(first[0], other[0])
    assert torch.equal(first[0], torch.rand(2, generator=torch.Generator().manual_seed(validation_seed(5))))


def test_initial_weights_are_those_of_the_seeded_global_generator_which_is_left_as_it_was() -> None:
    torch.manual_seed(3)
    expected = nn.Linear(4, 3).weight.detach().clone()
    torch.manual_seed(11)
    state = torch.get_rng_state()
    built = initial_weights(3, lambda: nn.Linear(4, 3))
    assert torch.equal(built.weight, expected)
    assert torch.equal(torch.get_rng_state(), state)
