"""The estimate checked on its own reference: the profile's noise put back on the reference's denoised version must
show on the flattest blocks the noise the reference shows there.

One statistic serves the estimate (per intensity, to correct a level the reference contradicts) and the judgement
of a change on real data (over the whole reference: ``benchmarks/real_data.py``): the std of 32-px blocks, read on
the blocks whose denoised version is flattest and whose mean lies inside the 8-bit range (a block of crushed black or
of a lamp shows no noise). Real and synthetic hold the same denoised scene, so what the denoiser left of the scene
counts on both sides alike; their ratio is 1 when the profile's noise is as strong as what the denoiser took off.
What the denoiser left of the noise stays in the synthetic side's base under the profile's noise, and the real side
does not have it twice: the synthetic side is read without it. How much it is (a share of the noise's variance: 0.02-0.1
for noise the denoiser is set to, a third for a phone's ISO-3200 noise under a denoiser set to the level the
estimate read) is read on noise of the profile's kind at the reference's level (:meth:`_CheckedWindow.leftovers`).
A true level then reads about 1; a correction moves a level only to the near edge of the consistent range
(:data:`CORRECTION_TARGET`).

Pure functions on (3, H, W) frames in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import torch
import torch.nn.functional as F

from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK, analysis_window, block_gradient, level_stratum
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import LEVEL_KNOTS
from darksynth.noise.values import NoiseValues

CHECK_SHARE = 0.1
"""Share of the blocks (the flattest, by the denoised version's gradient) the check reads."""

CHECK_MEAN_RANGE = (8.0 / 255.0, 247.0 / 255.0)
"""Block means (of the denoised version, over channels) the check reads: outside it noise is cut off at 0 or full
scale (a camera's crushed black, a lamp) and the block shows less than the noise."""

CONSISTENT_RANGE = (0.8, 1.25)
"""Synthetic over real std within this range: the profile reproduces what the reference shows."""

MIN_CHECK_BLOCKS = 3
"""Fewest blocks an intensity needs before its ratio is read (one or two blocks are one patch of scene)."""


@dataclass(frozen=True)
class BlockCheck:
    """The check on one set of blocks: the median over its blocks of the real and the synthetic std, the median
    variance of the denoised reference under the synthetic noise (its scene and what the denoiser left of the
    reference's noise: what :meth:`supported_for` leaves out), and the share of a noise's variance the denoiser
    leaves (``leftover``, :meth:`_CheckedWindow.leftovers`; 0 where not read)."""

    blocks: int
    real_std: float
    synthetic_std: float
    scene_variance: float
    leftover: float = 0.0

    @property
    def leftover_variance(self) -> float:
        """What the denoiser left of the reference's noise in the denoised base (which the synthetic side carries
        under the profile's noise and the real side does not): real = scene + noise and denoised = scene +
        leftover * noise (variances) give noise = (real - denoised) / (1 - leftover)."""
        noise = max(self.real_std**2 - self.scene_variance, 0.0) / (1.0 - self.leftover)
        return self.leftover * noise

    def supported_for(self, target: float) -> float:
        """The level factor that brings the ratio to ``target``: real = scene + noise and synthetic = scene +
        leftover + factor^2 * noise (variances); nan where the denoised scene alone is already as rough as that."""
        noise_variance = self.synthetic_std**2 - self.scene_variance
        wanted = (target * self.real_std) ** 2 - self.scene_variance + self.leftover_variance
        return math.sqrt(wanted / noise_variance) if wanted > 0 and noise_variance > 0 else math.nan

    @property
    def supported(self) -> float:
        """The level factor that makes the synthetic std the real one (:meth:`supported_for` 1)."""
        return self.supported_for(1.0)

    def correction(self) -> float:
        """1 where the blocks are consistent, else the level factor that brings them to the near end of
        :data:`CORRECTION_TARGET`, within :data:`FACTOR_BOUNDS`, and never away from it: up where the synthetic
        noise is too weak, down where it is too strong. Where :meth:`supported_for` gives no factor, a ratio
        above 1 means the denoised scene alone is as rough as the reference supports (no noise: the lower bound);
        a ratio below 1 means the medians of the scene and of the synthetic blocks left no noise variance to scale
        (the scene's median above the synthetic one's), and the std ratio alone says how far to go."""
        if self.consistent:
            return 1.0
        weak = self.ratio < 1.0
        target = CORRECTION_TARGET[0] if weak else CORRECTION_TARGET[1]
        supported = self.supported_for(target)
        if not math.isfinite(supported):
            # No synthetic noise at all on the blocks (a level scaled to 0): the largest step up.
            supported = (target / self.ratio if self.ratio > 0 else FACTOR_BOUNDS[1]) if weak else 0.0
        # A factor against the check's direction came from medians of different blocks: none moves that way.
        supported = max(supported, 1.0) if weak else min(supported, 1.0)
        return min(max(supported, FACTOR_BOUNDS[0]), FACTOR_BOUNDS[1])

    @property
    def ratio(self) -> float:
        """Synthetic over real std, the synthetic side without what the denoiser left of the reference's noise (1: the
        profile shows what the reference shows)."""
        synthetic = math.sqrt(max(self.synthetic_std**2 - self.leftover_variance, 0.0))
        return synthetic / max(self.real_std, 1e-12)

    @property
    def consistent(self) -> bool:
        return CONSISTENT_RANGE[0] <= self.ratio <= CONSISTENT_RANGE[1]


def _block_std(frame: torch.Tensor) -> torch.Tensor:
    """(rows * cols,) std of each whole 32-px block of ``frame`` (3, H, W), the mean over channels of each
    channel's std about the block's mean."""
    blocks = F.unfold(frame[:, None].to(torch.float64), FLAT_BLOCK, stride=FLAT_BLOCK)
    return blocks.std(dim=1).mean(0)


def _block_means(frame: torch.Tensor) -> torch.Tensor:
    grey = frame.mean(0)[None, None].to(torch.float64)
    return F.avg_pool2d(grey, FLAT_BLOCK)[0, 0].flatten()


def _flattest(candidates: torch.Tensor, gradient: torch.Tensor, least: int) -> torch.Tensor:
    """Of the ``candidates`` (n,) bool, the :data:`CHECK_SHARE` with the least ``gradient`` (at least ``least``)."""
    members = candidates.nonzero().flatten()
    chosen = torch.zeros_like(candidates)
    count = max(least, round(CHECK_SHARE * members.numel()))
    chosen[members[gradient[members].argsort()[:count]]] = True
    return chosen


def _in_range_blocks(denoised: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(rows * cols,) each of the blocks of ``denoised`` (3, H, W): the gradient, the mean, and whether the mean
    lies in :data:`CHECK_MEAN_RANGE`."""
    gradient = block_gradient(denoised).flatten().to(torch.float64)
    means = _block_means(denoised)[: gradient.numel()]
    return gradient, means, (means >= CHECK_MEAN_RANGE[0]) & (means <= CHECK_MEAN_RANGE[1])


def checked_blocks(denoised: torch.Tensor) -> torch.Tensor:
    """(rows * cols,) bool: the :data:`CHECK_SHARE` flattest of the blocks of ``denoised`` (3, H, W) whose mean lies in
    :data:`CHECK_MEAN_RANGE`."""
    gradient, _, inside = _in_range_blocks(denoised)
    return _flattest(inside, gradient, 1)


def checked_blocks_per_intensity(denoised: torch.Tensor) -> dict[int, torch.Tensor]:
    """Per segment of the level curve (:func:`~darksynth.estimation.noise.flat_blocks.level_stratum`) that holds
    :data:`MIN_CHECK_BLOCKS` blocks in :data:`CHECK_MEAN_RANGE`, the flattest :data:`CHECK_SHARE` of them (at least
    :data:`MIN_CHECK_BLOCKS`): flat for the noise at that intensity."""
    gradient, means, inside = _in_range_blocks(denoised)
    stratum = level_stratum(means)
    chosen: dict[int, torch.Tensor] = {}
    for segment in sorted(set(stratum[inside].tolist())):
        members = inside & (stratum == segment)
        if int(members.sum()) >= MIN_CHECK_BLOCKS:
            chosen[segment] = _flattest(members, gradient, MIN_CHECK_BLOCKS)
    return chosen


def block_check(
    reference: torch.Tensor, denoised: torch.Tensor, synthetic: torch.Tensor, blocks: torch.Tensor
) -> BlockCheck:
    """The check on the ``blocks`` (rows * cols,) bool: ``synthetic`` is the profile's noise added to ``denoised``
    (all three (3, H, W), the same size)."""
    real, clean, made = (_block_std(frame)[: blocks.numel()][blocks] for frame in (reference, denoised, synthetic))
    real_std, synthetic_std = float(real.median()), float(made.median())
    return BlockCheck(int(blocks.sum()), real_std, synthetic_std, float(clean.square().median()))


def self_consistency(reference: torch.Tensor, denoised: torch.Tensor, synthetic: torch.Tensor) -> BlockCheck:
    """The check over the whole reference (3, H, W): on the :data:`CHECK_SHARE` flattest blocks of its denoised
    version whose mean lies in :data:`CHECK_MEAN_RANGE`."""
    return block_check(reference, denoised, synthetic, checked_blocks(denoised))


CHECK_WINDOW = 1024
"""Side of the window of the reference the estimate checks itself on (its flattest unclipped one): a 4K frame's
denoising would cost more than the rest of the estimate, and a 1024-px window holds about a thousand blocks."""

LEFTOVER_BOUNDS = (0.0, 0.8)
"""The shares of a noise's variance the denoiser may be read to leave: past 0.8 the reference's noise read through it
(divided by 1 - share) would be mostly the reading's own error."""

FACTOR_BOUNDS = (1.0 / 16.0, 4.0)
"""The level factors one step of a correction may take: a reference whose denoised scene alone is as rough as the
reference supports no noise at all, which the lower bound stands for."""

CORRECTION_TARGET = (0.85, 1.2)
"""The ratios a correction aims at, from below and from above: just inside :data:`CONSISTENT_RANGE`, not 1. The
check reads a true level somewhat above 1 (what the denoiser left of the noise stays in the synthetic side's base),
so a correction from above that aimed at 1 settled under the truth (the round trip's case 32: 1.02 -> 0.85 of the
true std); the least move that makes the reference consistent is the one it supports."""

CORRECTION_STEPS = 3
"""Steps of the correction at most (each one synthesis on the denoised window)."""

FALLBACK_RANGE = (0.5, 2.0)
"""A corrected level whose check still lies outside this range at some intensity is not kept: the network's level
curve stands where it checks better."""

NETWORK_DISAGREEMENT = 3.0
"""A level this factor away from the network's (geometric mean over the knots) is kept only when its check passes."""


@dataclass
class SelfCheck:
    """The level curve (3, 8) the estimate keeps after checking itself, and what the check found."""

    curve: torch.Tensor
    meta: dict[str, Any]
    warnings: list[str]


def _segment_label(segment: int) -> str:
    low, high = LEVEL_KNOTS[segment], LEVEL_KNOTS[segment + 1]
    return f"{low * 255:.0f}-{high * 255:.0f}"


def _knot_factors(factors: dict[int, float]) -> torch.Tensor:
    """(8,) a factor per level knot from the factors of the segments (knot k bounds segments k - 1 and k): the
    geometric mean of its checked neighbours, else the nearest checked segment's."""
    knots = torch.ones(len(LEVEL_KNOTS), dtype=torch.float64)
    for knot in range(len(LEVEL_KNOTS)):
        neighbours = [factors[s] for s in (knot - 1, knot) if s in factors]
        if not neighbours:
            nearest = min(factors, key=lambda s: min(abs(s - knot), abs(s + 1 - knot)))
            neighbours = [factors[nearest]]
        knots[knot] = math.exp(sum(math.log(f) for f in neighbours) / len(neighbours))
    return knots


def _worst(checks: dict[int, BlockCheck]) -> float:
    """The largest departure from 1 over the checked segments, as a factor (1: all consistent)."""
    return max((math.exp(abs(math.log(max(c.ratio, 1e-12)))) for c in checks.values()), default=1.0)


def _worst_said(checks: dict[int, BlockCheck]) -> str:
    """:func:`_worst` as a warning says it: a segment left with no synthetic noise at all reads as such, not as a
    factor of a trillion."""
    if any(c.ratio <= 0.0 for c in checks.values()):
        return "no noise at some levels"
    return f"{_worst(checks):.2f}x"


def _within(checks: dict[int, BlockCheck], bounds: tuple[float, float]) -> bool:
    return all(bounds[0] <= c.ratio <= bounds[1] for c in checks.values())


def _describe(checks: dict[int, BlockCheck]) -> dict[str, Any]:
    return {
        _segment_label(s): {
            "blocks": c.blocks,
            "ratio": round(c.ratio, 3),
            "real_std_8bit": round(c.real_std * 255, 3),
            "leftover": round(c.leftover, 3),
        }
        for s, c in checks.items()
    }


@dataclass(frozen=True)
class _CheckedWindow:
    """What every draw of a check shares: the window of the reference, its denoised version (non-local means of
    ``strength`` 8-bit levels), the blocks per segment, the profile's values and the seed."""

    frame: torch.Tensor
    denoised: torch.Tensor
    strength: float
    strata: dict[int, torch.Tensor]
    values: NoiseValues
    seed: int

    leftover: dict[int, float] = field(default_factory=dict)
    """Per segment, the share of the reference's noise the denoiser left in the denoised window (:meth:`leftovers`;
    0 where not read)."""

    def _drawn(self, base: torch.Tensor, level: torch.Tensor, seed: int) -> torch.Tensor:
        drawn = self.values.replace(level_curve=level.flatten()).to(dtype=torch.float32)
        generator = torch.Generator().manual_seed(seed)
        return quantised(add_noise(base[None, None], drawn, generator=generator)[0, 0])

    def checked(self, level: torch.Tensor) -> dict[int, BlockCheck]:
        """The check per segment of the profile with the level curve ``level`` (3, 8)."""
        synthetic = self._drawn(self.denoised, level, self.seed)
        return {
            s: replace(block_check(self.frame, self.denoised, synthetic, b), leftover=self.leftover.get(s, 0.0))
            for s, b in self.strata.items()
        }

    def leftovers(self, first: dict[int, BlockCheck], level: torch.Tensor) -> dict[int, float]:
        """Per segment, the share of a noise's variance the denoiser leaves, read on noise of the profile's kind (level
        curve ``level`` (3, 8), whose check without a leftover is ``first``) scaled per segment to the least noise
        the reference can hold (its block variance less the denoised one's): drawn on the denoised window, denoised
        with the same strength, less the window denoised twice, within :data:`LEFTOVER_BOUNDS`. Read at the
        reference's level, not the profile's: a denoiser set for weaker noise leaves much of stronger noise (phones
        at ISO 3200: about a third), and a profile read 2x too loud would otherwise be judged by the leftover of its
        own loud noise and pass."""
        factors = {
            s: math.sqrt((c.real_std**2 - c.scene_variance) / (c.synthetic_std**2 - c.scene_variance))
            for s, c in first.items()
            if c.real_std**2 > c.scene_variance and c.synthetic_std**2 > c.scene_variance
        }
        if not factors:
            return {}
        probe = self._drawn(self.denoised, level * _knot_factors(factors)[None, :], self.seed + 1)
        left = nlm_denoise(probe[None], self.strength)[0] - nlm_denoise(self.denoised[None], self.strength)[0]
        added = probe - self.denoised
        shares = {}
        for s in factors:
            blocks = self.strata[s]
            kept, drawn = (float(_block_std(x)[: blocks.numel()][blocks].square().median()) for x in (left, added))
            # The probe's frame holds the base's leftover beside the drawn noise, as much noise as the reference.
            share = kept / max(drawn + first[s].scene_variance, 1e-12)
            shares[s] = min(max(share, LEFTOVER_BOUNDS[0]), LEFTOVER_BOUNDS[1])
        return shares


def check_level(
    reference: torch.Tensor,
    values: NoiseValues,
    network_curve: torch.Tensor,
    strength: float,
    name: str,
    seed: int = 0,
) -> SelfCheck:
    """The measured level checked on the reference frame (3, H, W) it was measured on: the profile's ``values``
    drawn on the frame's denoised version (non-local means of ``strength`` 8-bit levels, the estimate's), compared
    per intensity on the flattest in-range blocks (:func:`checked_blocks_per_intensity`). An intensity whose
    synthetic noise lies outside :data:`CONSISTENT_RANGE` of the reference's has its knots scaled by the factor the
    check supports; a correction that still leaves an intensity outside :data:`FALLBACK_RANGE`, or a level
    :data:`NETWORK_DISAGREEMENT` from the network's that does not pass, gives way to ``network_curve`` (3, 8) where
    that checks better. One warning says which and why."""
    top, left, height, width = analysis_window(reference, CHECK_WINDOW)
    frame = reference[:, top : top + height, left : left + width].to(torch.float32)
    denoised = nlm_denoise(frame[None], strength)[0]
    window = _CheckedWindow(frame, denoised, strength, checked_blocks_per_intensity(denoised), values, seed)
    curve = values["level_curve"].reshape(3, len(LEVEL_KNOTS)).to(torch.float64)
    # One draw serves the first check and the leftover's scaling; the leftover then joins the window's every check.
    unread = window.checked(curve)
    window = replace(window, leftover=window.leftovers(unread, curve))
    network_curve = network_curve.to(curve)
    disagreement = over_network(curve, network_curve)
    meta: dict[str, Any] = {"window": [top, left, height, width], "over_network": round(disagreement, 3)}
    if not window.strata:
        return _unchecked(curve, network_curve, disagreement, meta, name)
    first = {s: replace(c, leftover=window.leftover.get(s, 0.0)) for s, c in unread.items()}
    meta["measured"] = _describe(first)
    if _within(first, CONSISTENT_RANGE):
        meta["kept"] = "measurement: its check passes"
        # The check reads block std: where the flattest blocks are texture, a level that is texture passes it too.
        note = (
            f"{name}: the measured level, {disagreement:.1f}x the network's, passes the self-check on the flattest "
            "blocks; where those are texture (foliage, stone), texture passes it too: look at a preview"
        )
        return SelfCheck(curve, meta, [note] if _far(curve, network_curve) else [])
    return _corrected(window, curve, first, network_curve, meta, name)


def _unchecked(
    curve: torch.Tensor, network_curve: torch.Tensor, disagreement: float, meta: dict[str, Any], name: str
) -> SelfCheck:
    """No block to check on: a level :data:`NETWORK_DISAGREEMENT` from the network's gives way to it; ``meta`` is
    the check's record so far (a new one is returned)."""
    meta = meta | {"result": "no flat block with a mean of 8-247 levels to check on"}
    if not _far(curve, network_curve):
        return SelfCheck(curve, meta | {"kept": "measurement, unchecked"}, [])
    warning = (
        f"{name}: the measured level is {disagreement:.1f}x the network's and no flat block of 8-247 levels can "
        "check it: the profile holds the network's level curve"
    )
    return SelfCheck(network_curve.clone(), meta | {"kept": "network"}, [warning])


def _corrected(
    window: _CheckedWindow,
    curve: torch.Tensor,
    first: dict[int, BlockCheck],
    network_curve: torch.Tensor,
    meta: dict[str, Any],
    name: str,
) -> SelfCheck:
    """A level its check contradicts, scaled to what the check supports, or the network's where that checks
    better (see :func:`check_level`); ``meta`` is the check's record so far (a new one is returned)."""
    corrected, second = curve, first
    for _ in range(CORRECTION_STEPS):
        # A segment's std follows both of its knots, and a knot serves two segments: a few steps settle them.
        step = {s: c.correction() for s, c in second.items()}
        corrected = corrected * _knot_factors(step)[None, :]
        second = window.checked(corrected)
        if _within(second, CONSISTENT_RANGE):
            break
    factors = {
        s: float(v) for s, v in enumerate((corrected / curve.clamp_min(1e-12)).mean(0)[:-1].tolist()) if s in first
    }
    meta = meta | {"corrected": _describe(second)}
    worst_first = max(first.items(), key=lambda item: abs(math.log(max(item[1].ratio, 1e-12))))
    said = (
        f"{name}: the measured noise put back on the denoised reference gives {worst_first[1].ratio:.2f}x the noise "
        f"the reference shows at {_segment_label(worst_first[0])} levels"
    )
    far = _far(curve, network_curve)
    if _within(second, FALLBACK_RANGE) and (
        not far or _within(second, CONSISTENT_RANGE) or not _far(corrected, network_curve)
    ):
        scaled = f"; its level is scaled by {_span(factors)} to what the reference supports (now {_worst_said(second)}"
        kept = {"kept": "measurement scaled to what the check supports"}
        return SelfCheck(corrected, meta | kept, [f"{said}{scaled} at worst)"])
    network = window.checked(network_curve)
    meta = meta | {"network": _describe(network)}
    if _worst(network) <= _worst(second):
        fallback = (
            f", and scaled to what the reference supports still {_worst_said(second)}; the profile holds the "
            f"network's level curve ({_worst_said(network)} at worst)"
        )
        kept = {"kept": "network: the measurement failed its check"}
        return SelfCheck(network_curve.clone(), meta | kept, [said + fallback])
    uncertain = (
        f"; scaled by {_span(factors)} it is still {_worst_said(second)} at worst (the network's level: "
        f"{_worst_said(network)}): the level is uncertain"
    )
    kept = {"kept": "measurement scaled to what the check supports, though it still fails"}
    return SelfCheck(corrected, meta | kept, [said + uncertain])


def over_network(curve: torch.Tensor, network_curve: torch.Tensor, knots: torch.Tensor | None = None) -> float:
    """A level curve (3, 8) over the network's: the geometric mean of their ratio over the ``knots`` (3, 8) bool
    (all by default)."""
    ratio = curve / network_curve.clamp_min(1e-6)
    return float((ratio if knots is None else ratio[knots]).log().mean().exp())


def far_from_network(ratio: float) -> bool:
    """Whether a level ``ratio`` times the network's lies :data:`NETWORK_DISAGREEMENT` or more from it."""
    return not 1.0 / NETWORK_DISAGREEMENT <= ratio <= NETWORK_DISAGREEMENT


def _far(curve: torch.Tensor, network_curve: torch.Tensor) -> bool:
    return far_from_network(over_network(curve, network_curve))


def _span(factors: dict[int, float]) -> str:
    low, high = min(factors.values()), max(factors.values())
    return f"{low:.2f}" if math.isclose(low, high, rel_tol=0.01) else f"{low:.2f}-{high:.2f} by intensity"
