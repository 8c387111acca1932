"""A prior over real cameras: a Gaussian over the spectral model's values of the bank's cameras, in a space where
their spread is simple, and its conditionals (docs/camera-prior.md).

The space (:data:`FEATURES`): the log of every noise std of the level curve and of every octave's power, the
inverse hyperbolic tangent of the octaves' correlations, the JPEG strength as it is, the texture gain as it is and
the log of the texture scale. Powers and stds vary over orders of magnitude between cameras and their logs move
together (a camera's whole curve is brighter or darker), which a Gaussian holds; correlations live in (-1, 1).

Each set of real pairs weighs the same, whatever its number of pairs (polyu's 100 JPEG pairs would otherwise make
every camera a DSLR JPEG), and the covariance is shrunk toward its diagonal by :data:`SHRINKAGE`: a few dozen
cameras of three or four kinds do not determine 60 dimensions' covariances.

What it gives:

* :meth:`CameraPrior.draw`: whole cameras, every value drawn jointly;
* :meth:`CameraPrior.conditional_mean`: given the values a blind estimate reads (the level curve, the finer
  octaves, JPEG), the expected values of what it cannot read (the coarse octaves, the texture dependence).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import torch

from darksynth.cameras.bank import CameraRecord, shipped_bank, without_sets
from darksynth.errors import DarksynthError
from darksynth.noise.spectral import OCTAVES
from darksynth.noise.values import NoiseValues

SHRINKAGE = 0.25
"""Share of the diagonal in the shrunk covariance, set before any leave-one-set-out figure was seen (Ledoit and
Wolf's analytic shrinkage lands in 0.2-0.4 for as many samples as dimensions)."""

RIDGE = 1e-6
"""Added to the diagonal so that a feature without spread (a JPEG strength every record shares) stays invertible."""

CORRELATION_LIMIT = 0.95
"""Correlations are clamped to this before their inverse hyperbolic tangent (a fit's +-0.99 would dominate)."""

COMPRESSION_STEPS = (0.0, 0.2, 0.4)
"""The JPEG strengths a drawn camera snaps to: those the clean-aided fit chooses between."""

LOG_NAMES = frozenset({"level_curve", "octave_power", "texture_scale"})
CORRELATION_NAMES = frozenset({"octave_correlation"})

FEATURES: tuple[str, ...] = (
    "level_curve",
    "octave_power",
    "octave_correlation",
    "compression",
    "texture_gain",
    "texture_scale",
)
"""The values the prior holds, in its feature order (the ones the bank's records lack are left out)."""


BLIND_OCTAVES = 3
"""The finest octaves (wavelengths 2.8-11 px) one reference shows: coarser, its statistics hold the scene more than
the noise (on the real pairs the blind reading of the 16-64 px bands ranged 0.2-0.7 of the real on JPEG DSLRs;
docs/spectral-noise.md). Octave powers are taken relative to these octaves' mean log brightness power: the model
normalises its unit noise, so only the spectrum's shape counts."""


LEVEL_RANGE_8BIT = (1.0, 32.0)
"""The noise std (8-bit levels, mean over the level curve) of a camera drawn with no reference, log-uniform: from a
night shot at a low gain to a phone at its highest (SIDD's low-light scenes reach 30). The bank's own levels are
those its sets were shot at, not what a camera can show; how loud a camera is at night is its exposure's choice."""


def to_features(name: str, values: torch.Tensor) -> torch.Tensor:
    """A value's entries in the prior's space (float64). The level curve's are its mean log std first, then each
    knot's log std about that mean, so that a camera's loudness and its curve's shape are separate features."""
    values = values.to(torch.float64)
    if name == "level_curve":
        logs = values.clamp_min(1e-6).log()
        scale = logs.mean(-1, keepdim=True)
        return torch.cat([scale, logs - scale], dim=-1)
    if name == "octave_power":
        logs = values.clamp_min(1e-6).log()
        return logs - logs.reshape(-1, 3)[:BLIND_OCTAVES, 0].mean()
    if name in LOG_NAMES:
        return values.clamp_min(1e-6).log()
    if name in CORRELATION_NAMES:
        return values.clamp(-CORRELATION_LIMIT, CORRELATION_LIMIT).atanh()
    return values


def on_measured_scale(relative: torch.Tensor, measured: torch.Tensor, known_octaves: int) -> torch.Tensor:
    """Octave powers (OCTAVES * 3,) from the prior's space (relative to :func:`to_features`' reference, which is
    lost) put on the scale of ``measured`` powers: their mean log brightness power over the ``known_octaves``
    finest octaves made the measured one's."""
    measured_log = measured.reshape(-1, 3)[:known_octaves, 0].clamp_min(1e-30).log().mean()
    relative_log = relative.reshape(-1, 3)[:known_octaves, 0].clamp_min(1e-30).log().mean()
    return relative * (measured_log - relative_log).exp()


def from_features(name: str, features: torch.Tensor) -> torch.Tensor:
    """The inverse of :func:`to_features`, snapped to what the model draws (JPEG steps, a gain of at least 0)."""
    if name == "level_curve":
        return (features[..., 1:] + features[..., :1]).exp()
    if name in LOG_NAMES:
        return features.exp()
    if name in CORRELATION_NAMES:
        return features.tanh()
    if name == "compression":
        steps = torch.tensor(COMPRESSION_STEPS, dtype=features.dtype, device=features.device)
        return steps[(features[..., None] - steps).abs().argmin(-1)]
    if name == "texture_gain":
        return features.clamp_min(0.0)
    return features


def _feature_mask(name: str, mask: torch.Tensor) -> torch.Tensor:
    """A mask over a value's entries as one over its features: the level curve is known whole or not at all."""
    mask = mask.reshape(-1).to(torch.bool)
    if name != "level_curve":
        return mask
    if bool(mask.any()) != bool(mask.all()):
        raise ValueError("the camera prior conditions on the whole level curve or none of it")
    return mask[:1].expand(mask.numel() + 1)


@dataclass(frozen=True)
class CameraPrior:
    """A Gaussian over cameras in the prior's space.

    Attributes:
        names: the values it holds, with ``sizes`` entries each, in feature order.
        mean, covariance: (D,), (D, D) float64.
        sets: the sets of real pairs it was fitted on.
    """

    names: tuple[str, ...]
    sizes: tuple[int, ...]
    mean: torch.Tensor
    covariance: torch.Tensor
    sets: tuple[str, ...]

    def slices(self) -> dict[str, slice]:
        """Each value's slice of the feature vector."""
        starts = torch.tensor((0, *self.sizes)).cumsum(0).tolist()
        return {name: slice(starts[i], starts[i + 1]) for i, name in enumerate(self.names)}

    def features(self, values: Mapping[str, torch.Tensor]) -> torch.Tensor:
        """(D,) the feature vector of one camera's values (each flattened)."""
        return torch.cat([to_features(name, torch.as_tensor(values[name]).reshape(-1)) for name in self.names])

    def values(self, features: torch.Tensor) -> dict[str, torch.Tensor]:
        """The values by name of feature vectors (..., D)."""
        return {name: from_features(name, features[..., part]) for name, part in self.slices().items()}

    def draw(self, generator: torch.Generator, count: int = 1) -> NoiseValues:
        """``count`` whole cameras drawn with no reference, as noise values batched (count,): each one's loudness
        log-uniform in :data:`LEVEL_RANGE_8BIT`, everything else drawn from the prior given it."""
        low, high = (math.log(level / 255.0) for level in LEVEL_RANGE_8BIT)
        uniform = torch.rand(count, generator=generator, device=generator.device, dtype=torch.float64).cpu()
        scale_index = self.slices()["level_curve"].start
        observed = torch.zeros(self.mean.numel(), dtype=torch.bool)
        observed[scale_index] = True
        drawn = []
        for position in uniform.tolist():
            given = self.mean.clone()
            given[scale_index] = low + position * (high - low)
            drawn.append(self._draw_features(*self._conditional_features(observed, given), generator))
        return NoiseValues.from_values(self.values(torch.stack(drawn)), batch_shape=(count,))

    def _draw_features(self, mean: torch.Tensor, covariance: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Features drawn from the Gaussian (``mean``, ``covariance``); entries without variance stay at the mean."""
        unknown = covariance.diagonal() > 0
        standard = torch.randn(
            int(unknown.sum()), generator=generator, device=generator.device, dtype=torch.float64
        ).cpu()
        features = mean.clone()
        if bool(unknown.any()):
            block = covariance[unknown][:, unknown]
            identity = torch.eye(block.shape[0], dtype=block.dtype)
            root = torch.linalg.cholesky(0.5 * (block + block.T) + RIDGE * identity)
            features[unknown] = mean[unknown] + root @ standard
        return features

    def mean_values(self) -> NoiseValues:
        """The prior's central camera (the mean in its space)."""
        return NoiseValues.from_values(self.values(self.mean))

    def _observed(
        self, known: Mapping[str, torch.Tensor], mask: Mapping[str, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(D,) bool the entries given, (D,) the given features there (the mean elsewhere)."""
        observed = torch.cat(
            [
                _feature_mask(name, mask[name]) if name in known else torch.zeros(size, dtype=torch.bool)
                for name, size in zip(self.names, self.sizes, strict=True)
            ]
        )
        given = torch.cat(
            [
                to_features(name, torch.as_tensor(known[name]).reshape(-1)) if name in known else self.mean[part]
                for name, part in self.slices().items()
            ]
        )
        return observed, given

    def conditional(
        self, known: Mapping[str, torch.Tensor], mask: Mapping[str, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The Gaussian of the features given the ``known`` values' entries where ``mask`` (same shapes, bool) is
        True: its mean (D,), the given entries at their value, and its covariance (D, D), zero in their rows and
        columns. Values missing from ``known`` are unknown."""
        return self._conditional_features(*self._observed(known, mask))

    def _conditional_features(self, observed: torch.Tensor, given: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        mean, covariance = self.mean.clone(), self.covariance.clone()
        mean[observed] = given[observed]
        covariance[observed] = 0.0
        covariance[:, observed] = 0.0
        if bool(observed.any()) and bool((~observed).any()):
            covariance_known = self.covariance[observed][:, observed]
            cross = self.covariance[~observed][:, observed]
            gain = torch.linalg.solve(covariance_known, cross.T).T
            mean[~observed] = self.mean[~observed] + gain @ (given[observed] - self.mean[observed])
            unknown = self.covariance[~observed][:, ~observed] - gain @ cross.T
            covariance[torch.outer(~observed, ~observed)] = unknown.reshape(-1)
        return mean, covariance

    def conditional_mean(self, known: Mapping[str, torch.Tensor], mask: Mapping[str, torch.Tensor]) -> torch.Tensor:
        """(D,) the features' expected values given the ``known`` entries (see :meth:`conditional`)."""
        return self.conditional(known, mask)[0]

    def draw_given(
        self, known: Mapping[str, torch.Tensor], mask: Mapping[str, torch.Tensor], generator: torch.Generator
    ) -> NoiseValues:
        """One camera drawn from the conditional (:meth:`conditional`): the given entries as they are, the rest
        drawn jointly."""
        features = self._draw_features(*self.conditional(known, mask), generator)
        return NoiseValues.from_values(self.values(features))


def fit_prior(records: Sequence[CameraRecord], names: Iterable[str] = FEATURES) -> CameraPrior:
    """The prior fitted on ``records``, each set weighing the same.

    Raises:
        ValueError: no records.
    """
    if not records:
        raise ValueError("a camera prior needs at least one record")
    held = tuple(name for name in names if all(name in record.values for record in records))
    sizes = tuple(to_features(name, torch.tensor(records[0].values[name])).numel() for name in held)
    rows = torch.stack(
        [
            torch.cat([to_features(name, torch.tensor(record.values[name], dtype=torch.float64)) for name in held])
            for record in records
        ]
    )
    sets = sorted({record.set for record in records})
    per_set = {name: sum(record.set == name for record in records) for name in sets}
    weights = torch.tensor([1.0 / (per_set[record.set] * len(sets)) for record in records], dtype=torch.float64)
    mean = weights @ rows
    centred = rows - mean
    covariance = (centred * weights[:, None]).T @ centred
    shrunk = (1.0 - SHRINKAGE) * covariance + SHRINKAGE * torch.diag(covariance.diagonal())
    shrunk = shrunk + RIDGE * torch.eye(mean.numel(), dtype=torch.float64)
    return CameraPrior(names=held, sizes=sizes, mean=mean, covariance=shrunk, sets=tuple(sets))


def measured_entries(
    values: Mapping[str, torch.Tensor], first_unknown: int = BLIND_OCTAVES
) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
    """What a blind estimate measures of one camera's ``values`` (unbatched), as the ``known`` values and ``mask``
    of :meth:`CameraPrior.conditional`: the level curve, the JPEG strength, and the powers and correlations of the
    octaves finer than ``first_unknown``."""
    octaves = torch.zeros(OCTAVES * 3, dtype=torch.bool)
    octaves[: first_unknown * 3] = True
    names = ("level_curve", "octave_power", "octave_correlation", "compression")
    known = {name: torch.as_tensor(values[name]).reshape(-1) for name in names if name in values}
    mask = {
        name: octaves
        if name in ("octave_power", "octave_correlation")
        else torch.ones(known[name].numel(), dtype=torch.bool)
        for name in known
    }
    return known, mask


SAME_CAMERAS: tuple[frozenset[str], ...] = (frozenset({"nam-cc15", "nam-cc60"}),)
"""Sets of real pairs from the same cameras: a set is judged by a prior fitted without any set of its group."""


def held_out_sets(judged: str) -> frozenset[str]:
    """The sets a prior that judges the set ``judged`` must leave out: the set and those of the same cameras."""
    for group in SAME_CAMERAS:
        if judged in group:
            return group
    return frozenset({judged})


@functools.cache
def shipped_prior(excluded: frozenset[str] = frozenset()) -> CameraPrior:
    """The prior fitted on the shipped bank, without the sets ``excluded`` (read and fitted once per choice).

    Raises:
        DarksynthError: the bank cannot be read, or excluding leaves no record.
    """
    records = without_sets(shipped_bank(), excluded)
    if not records:
        raise DarksynthError(f"no camera left in the bank without {', '.join(sorted(excluded))}")
    return fit_prior(records)
