"""The estimate checked on its own reference: the profile's noise put back on the reference's denoised version must
show on the flattest blocks of each intensity the noise the reference shows there (the statistic:
:mod:`darksynth.estimation.noise.block_check`).

How much of the reference's noise the denoiser left in its output (a share of the noise's variance: 0.02-0.1 for
noise the denoiser is set to, a third for a phone's ISO-3200 noise under a denoiser set to the level the estimate
read) is read on noise of the profile's kind at the reference's level (:meth:`_CheckedWindow.leftovers`). A true
level then reads about 1; a correction from below aims at 1, one from above at the near edge of the consistent
range (:data:`~darksynth.estimation.noise.block_check.CORRECTION_TARGET`), and a weak reading on texture-like blocks
moves nothing.

Pure functions on (3, H, W) frames in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import torch

from darksynth.estimation.noise.block_check import (
    CONSISTENT_RANGE,
    BlockCheck,
    block_check,
    block_std,
    checked_blocks_per_intensity,
)
from darksynth.estimation.noise.flat_blocks import analysis_window
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import LEVEL_KNOTS
from darksynth.noise.values import NoiseValues

CHECK_WINDOW = 1024
"""Side of the window of the reference the estimate checks itself on (its flattest unclipped one): a 4K frame's
denoising would cost more than the rest of the estimate, and a 1024-px window holds about a thousand blocks."""

LEFTOVER_BOUNDS = (0.0, 0.8)
"""The shares of a noise's variance the denoiser may be read to leave: past 0.8 the reference's noise read through it
(divided by 1 - share) would be mostly the reading's own error."""

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
    return max((c.departure for c in checks.values()), default=1.0)


def _worst_said(checks: dict[int, BlockCheck]) -> str:
    """:func:`_worst` as a warning says it: a segment left with no synthetic noise at all reads as such, not as a
    factor of a trillion."""
    if any(c.ratio <= 0.0 for c in checks.values()):
        return "no noise at some levels"
    return f"{_worst(checks):.2f}x"


def _within(checks: dict[int, BlockCheck], bounds: tuple[float, float]) -> bool:
    return all(c.within(bounds) for c in checks.values())


def _describe(checks: dict[int, BlockCheck]) -> dict[str, Any]:
    return {
        _segment_label(s): {
            "blocks": c.blocks,
            "ratio": round(c.ratio, 3),
            "real_std_8bit": round(c.real_std * 255, 3),
            "leftover": round(c.leftover, 3),
            "texture_like": c.texture_like,
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
            kept, drawn = (float(block_std(x)[: blocks.numel()][blocks].square().median()) for x in (left, added))
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
    that checks better. One warning says which and why, and which weak readings were not raised
    (:attr:`BlockCheck.texture_like`)."""
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
        not_raised = _not_raised_said(first)
        return SelfCheck(
            curve,
            meta,
            ([note] if _far(curve, network_curve) else [])
            + ([f"{name}: the self-check passes{not_raised}"] if not_raised else []),
        )
    return _corrected(window, curve, first, network_curve, meta, name)


def _not_raised_said(first: dict[int, BlockCheck]) -> str:
    """The intensities whose first check read weak on texture-like blocks, as a clause of a warning ('' if none)."""
    not_raised = {s: c for s, c in first.items() if c.weak_on_texture and c.ratio < CONSISTENT_RANGE[0]}
    if not not_raised:
        return ""
    where = ", ".join(f"{c.ratio:.2f}x at {_segment_label(s)}" for s, c in not_raised.items())
    return (
        f"; where the profile shows less than the reference ({where} levels), what the denoiser took off is more "
        "alike across channels or smoother than noise (texture, or colour the profile has wrong): not raised"
    )


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
    worst_first = max(first.items(), key=lambda item: item[1].departure)
    said = (
        f"{name}: the measured noise put back on the denoised reference gives {worst_first[1].ratio:.2f}x the noise "
        f"the reference shows at {_segment_label(worst_first[0])} levels{_not_raised_said(first)}"
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
