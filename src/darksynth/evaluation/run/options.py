"""The options of an evaluation run (``darksynth evaluate``), shared by the job and the per-pair runner."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from darksynth.errors import DarksynthError
from darksynth.evaluation.measures.denoiser import DENOISER_SIZES, DownstreamSettings
from darksynth.evaluation.methods.catalogue import DEFAULT_METHODS

_DOWNSTREAM_DEFAULTS: Final = DownstreamSettings()


@dataclass(frozen=True)
class EvaluationOptions:
    """What to evaluate and how; the defaults are those of ``darksynth evaluate``.

    Attributes:
        methods: the methods to compare, by name (see :mod:`darksynth.evaluation.methods.catalogue`).
        seed: seed of the synthetic noise (each pair and method draws from a seed derived from it).
        device: torch device of the methods and of the Inception network.
        weights: weights files by DEN method name, instead of the shipped ones.
        inception: compute FID and KID (InceptionV3 features of noise maps).
        downstream: folders of clean training images for the downstream check; none: no check.
        downstream_steps: training steps of each downstream denoiser.
        downstream_net: the downstream denoiser's size, a name of
            :data:`~darksynth.evaluation.measures.denoiser.DENOISER_SIZES`.
        fid_crops: noise-map tiles per set and per source (real or a method) for FID/KID, spread evenly over
            the pairs.
        examples_per_set: pairs per set shown in the report.
        example_crop: side of the crops the report shows.
        command: the command that asked for the run, stated in the results.

    Raises:
        DarksynthError: ``downstream_steps`` below 1 or an unknown ``downstream_net``.
    """

    methods: Sequence[str] = DEFAULT_METHODS
    seed: int = 0
    device: str = "cpu"
    weights: dict[str, Path] = field(default_factory=dict)
    inception: bool = True
    downstream: tuple[Path, ...] = ()
    downstream_steps: int = _DOWNSTREAM_DEFAULTS.steps
    downstream_net: str = "small"
    fid_crops: int = 64
    examples_per_set: int = 2
    example_crop: int = 128
    command: str = ""

    def __post_init__(self) -> None:
        if self.downstream_steps < 1:
            raise DarksynthError(f"--downstream-steps must be at least 1, got {self.downstream_steps}")
        if self.downstream_net not in DENOISER_SIZES:
            known = ", ".join(DENOISER_SIZES)
            raise DarksynthError(f"--downstream-net {self.downstream_net!r}: one of {known}")

    def downstream_settings(self) -> DownstreamSettings:
        """The settings of the downstream check these options ask for."""
        width, depth = DENOISER_SIZES[self.downstream_net]
        return DownstreamSettings(
            steps=self.downstream_steps, seed=self.seed, device=self.device, width=width, depth=depth
        )
