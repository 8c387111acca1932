"""The loop shared by darksynth's trainers (the DEN, the Starlight generator, the downstream denoiser).

What every trainer does the same way lives here: the step loop with a report every ``report_every`` steps (and
at the last), the mean of each loss over the steps since the last report, the history of reports, the time
taken and an optional time limit, resumption from a step and a history, a callback after every step; the
conventions of the fixed validation set (:func:`draw_validation_batches`, drawn from held-out material with
:func:`validation_seed`), of single-frame batches (:func:`single_frame_step`) and of seeded initial weights
(:func:`initial_weights`). What differs stays with each trainer, behind :class:`TrainingSteps`: how a step
draws its batch and updates the networks, and what a report holds (validation figures, a checkpoint).

Steps are counted from 1: step ``s`` is the ``s``-th optimiser step, and after it ``s`` steps are done (the
number a checkpoint records and a resumed run starts from).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any, Protocol, TypeVar

import torch

from darksynth.seeding import seeded_generator
from darksynth.training.corpus import CleanCorpus, sample_clean_clips

VALIDATION_SEED_OFFSET = 1_000_003
"""Added to the run seed to seed the validation set: far from the seeds of nearby runs' training streams."""

Drawn = TypeVar("Drawn")
Built = TypeVar("Built")


def validation_seed(seed: int) -> int:
    """The seed of a run's validation set: the same for every run with ``seed``, whatever it trains on."""
    return seed + VALIDATION_SEED_OFFSET


def draw_validation_batches(draw: Callable[[torch.Generator], Drawn], size: int, batch: int, seed: int) -> list[Drawn]:
    """A run's fixed validation set: ``max(1, size // batch)`` batches drawn in turn by ``draw`` from one
    generator seeded with :func:`validation_seed` of the run seed. ``draw`` samples held-out material only, so
    that the figures measure what the network has not trained on."""
    generator = seeded_generator(validation_seed(seed))
    return [draw(generator) for _ in range(max(1, size // batch))]


def single_frame_step(step: int, every: int) -> bool:
    """Whether step ``step`` (counted from 1) trains on single frames (T = 1) rather than clips: every
    ``every``-th step (the 2nd, 4th, ... for 2); never for 0. One network then serves images and clips."""
    return every > 0 and step % every == 0


CALIBRATION_BATCHES = 16
"""Batches a network's input statistics are standardised on before training."""


def calibration_clip_lengths(frames: int) -> list[int]:
    """The clip length of each calibration batch: single frames and ``frames``-frame clips in turn, so that the
    scale fits both kinds of reference whatever share of single-frame steps the training has."""
    return [1 if single_frame_step(index + 1, 2) else frames for index in range(CALIBRATION_BATCHES)]


def initial_weights(seed: int, build: Callable[[], Built]) -> Built:
    """``build()`` (networks made on the CPU) with torch's global generator seeded with ``seed`` for it alone:
    the weights are those of ``torch.manual_seed(seed); build()``, and the caller's global generator is left as
    it was. Layers draw their initial weights from the global generator; every later draw of a trainer uses an
    explicit generator."""
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return build()


@dataclass(frozen=True)
class SyntheticTrainingConfig:
    """The settings every trainer on the DEN's synthetic data has: how its batches are drawn and how its run goes.

    Each trainer's config adds its own fields (and its own defaults where they differ); all are written beside the
    weights.
    """

    steps: int = 1500
    """Optimiser steps."""
    batch: int = 8
    """Clips per step."""
    frames: int = 4
    """Frames per clip, but on single-frame steps (``single_frame_every``)."""
    crop: int = 64
    """Side of the square training crops, pixels."""
    clip_fraction: float = 0.5
    """Share of the clips taken from videos rather than from a still repeated
    (:func:`~darksynth.training.corpus.sample_clean_clips`)."""
    single_frame_every: int = 2
    """Every this-th step trains on single frames (:func:`single_frame_step`); 0: none."""
    absent_probability: float = 0.15
    """Probability that each noise component of a drawn v is absent."""
    learning_rate: float = 5e-4
    betas: tuple[float, float] = (0.5, 0.999)
    """Adam's learning rate and betas for the network trained."""
    seed: int = 0
    """The run seed: initial weights, the training stream, the validation set."""
    validation_size: int = 64
    """Clips of the fixed validation set."""
    device: str = "cpu"
    """Torch device of the networks."""

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON document, a nested network config as its own ``to_dict`` writes it."""
        document = asdict(self)
        for option in fields(self):
            value = getattr(self, option.name)
            if hasattr(value, "to_dict"):
                document[option.name] = value.to_dict()
        return document

    def frames_at(self, step: int) -> int:
        """The clip length of step ``step`` (counted from 1): 1 on single-frame steps, else ``frames``."""
        return 1 if single_frame_step(step, self.single_frame_every) else self.frames

    def clean_clips(
        self,
        corpus: CleanCorpus,
        frames: int,
        crop: int,
        generator: torch.Generator,
        *,
        batch: int | None = None,
    ) -> torch.Tensor:
        """A batch (``batch`` clips, the configured number by default) of clean ``frames``-frame clips cropped to
        ``crop`` pixels, drawn as configured: (B, T, 3, crop, crop) in [0, 1]."""
        return sample_clean_clips(
            corpus,
            self.batch if batch is None else batch,
            frames,
            crop,
            clip_fraction=self.clip_fraction,
            generator=generator,
        )


@dataclass(frozen=True)
class Report:
    """What a trainer's report sees: the steps since the last report and the history before this one.

    Attributes:
        step: the step just done (counted from 1).
        mean_losses: each loss of :meth:`TrainingSteps.train_step` averaged over the steps since the last report.
        seconds: time since the loop started (in this run, not counting a resumed run's earlier part).
        history: the entries of the earlier reports, oldest first (a resumed run's included).
    """

    step: int
    mean_losses: dict[str, float]
    seconds: float
    history: Sequence[dict[str, Any]]


class TrainingSteps(Protocol):
    """The model-specific parts of a training run."""

    def train_step(self, step: int) -> dict[str, float]:
        """Do optimiser step ``step`` (counted from 1): draw a batch, update the networks; return its losses."""
        ...

    def report(self, report: Report) -> dict[str, Any] | None:
        """The history entry of a report step (validation figures, logged losses; a checkpoint may be written
        here), or None for none (a process that does not validate)."""
        ...


StepCallback = Callable[[int, dict[str, float], dict[str, Any] | None], None]
"""Called after every step with the step, its losses and the entry its report made (None: no report)."""


@dataclass(frozen=True)
class StepPlan:
    """How many steps to run and when to report.

    Attributes:
        steps: the step to stop after.
        report_every: report after every multiple of this step, and after the last step.
        max_seconds: stop after the first step that ends later than this after the start (with a report), if
            it is not the last; None: no limit.
    """

    steps: int
    report_every: int
    max_seconds: float | None = None

    def __post_init__(self) -> None:
        if self.report_every < 1:
            raise ValueError(f"report_every must be at least 1, got {self.report_every}")

    def reports_at(self, step: int) -> bool:
        return step % self.report_every == 0 or step == self.steps


@dataclass
class LoopResult:
    """How a loop ended: the steps done (a resumed run's earlier ones included), the time this run took,
    whether the time limit stopped it, and the history of reports."""

    steps: int
    seconds: float
    stopped_by_time_limit: bool
    history: list[dict[str, Any]] = field(default_factory=list)

    @property
    def last(self) -> dict[str, Any] | None:
        """The latest report's entry, None without any."""
        return self.history[-1] if self.history else None


def run_steps(
    task: TrainingSteps,
    plan: StepPlan,
    *,
    start: int = 0,
    history: Sequence[dict[str, Any]] = (),
    on_step: StepCallback | None = None,
) -> LoopResult:
    """Run ``task``'s steps ``start + 1`` to ``plan.steps``, reporting as ``plan`` says.

    Args:
        task: the model-specific steps and reports.
        plan: the number of steps, the report period and the time limit.
        start: steps already done (a resumed run: the checkpoint's step, taken at a report).
        history: the entries of the reports already made (a resumed run's).
        on_step: called after every step (see :data:`StepCallback`).
    """
    entries = list(history)
    sums: dict[str, float] = {}
    count = 0
    step = start
    stopped = False
    started = time.perf_counter()
    while step < plan.steps:
        step += 1
        losses = task.train_step(step)
        for name, value in losses.items():
            sums[name] = sums.get(name, 0.0) + value
        count += 1
        seconds = time.perf_counter() - started
        stopped = plan.max_seconds is not None and seconds > plan.max_seconds and step < plan.steps
        entry = None
        if plan.reports_at(step) or stopped:
            means = {name: total / count for name, total in sums.items()}
            entry = task.report(Report(step=step, mean_losses=means, seconds=seconds, history=entries))
            if entry is not None:
                entries.append(entry)
            sums, count = {}, 0
        if on_step is not None:
            on_step(step, losses, entry)
        if stopped:
            break
    return LoopResult(steps=step, seconds=time.perf_counter() - started, stopped_by_time_limit=stopped, history=entries)
