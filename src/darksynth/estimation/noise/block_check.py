"""The self-check's statistic on a set of 32-px blocks: the profile's noise put back on a reference's denoised
version against the reference, on the blocks whose denoised version is flattest and whose mean lies inside the 8-bit
range (a block of crushed black or of a lamp shows no noise).

One statistic serves the estimate (per intensity, to correct a level the reference contradicts:
:mod:`darksynth.estimation.noise.self_check`) and the judgement of a change on real data (over the whole reference:
``benchmarks/real_data.py``): the median block std. Real and synthetic hold the same denoised scene, so what the
denoiser left of the scene counts on both sides alike; their ratio is 1 when the profile's noise is as strong as what
the denoiser took off. What the denoiser left of the noise stays in the synthetic side's base under the profile's
noise, and the real side does not have it twice: the synthetic side is read without it (``leftover``). A reference
that shows more than the profile on its flattest blocks may show texture the denoiser took off, not noise the
estimate missed: a weak reading asks for a higher level only where what the denoiser took off there looks like the
profile's noise (:attr:`BlockCheck.texture_like`).

Pure functions on (3, H, W) frames in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK, block_gradient, level_stratum

CHECK_SHARE = 0.1
"""Share of the blocks (the flattest, by the denoised version's gradient) the check reads."""

CHECK_MEAN_RANGE = (8.0 / 255.0, 247.0 / 255.0)
"""Block means (of the denoised version, over channels) the check reads: outside it noise is cut off at 0 or full
scale (a camera's crushed black, a lamp) and the block shows less than the noise."""

CONSISTENT_RANGE = (0.8, 1.25)
"""Synthetic over real std within this range: the profile reproduces what the reference shows."""

MIN_CHECK_BLOCKS = 3
"""Fewest blocks an intensity needs before its ratio is read (one or two blocks are one patch of scene)."""

TEXTURE_CORRELATION_MARGIN = 0.15
"""How much more correlated across channels than the profile's noise what the denoiser took off a reference's blocks
may be and still be read as noise. The profile's channel correlation was measured on the same reference, and the
two are read on the same 3 or more blocks of 1024 pixels (a sampling std of about 0.03); texture is brightness, alike
in every channel. On the real pairs' weak readings (issue 39) the true under-reads of phones read 0.05-0.12 more, the
ones their clean images show to be texture 0.16-0.54."""

TEXTURE_SMOOTHNESS_MARGIN = 0.05
"""How much higher a neighbour correlation than the profile's noise's what the denoiser took off may show and still
be read as noise: the denoiser leaves the coarse part of noise in its output, so what it takes off of noise is if
anything finer than the noise (phones' under-reads: 0.01-0.10 lower); texture it takes off is smoother."""


@dataclass(frozen=True)
class BlockCheck:
    """The check on one set of blocks: the median over its blocks of the real and the synthetic std, the median
    variance of the denoised reference under the synthetic noise (its scene and what the denoiser left of the
    reference's noise: what :meth:`supported_for` leaves out), and the share of a noise's variance the denoiser
    leaves (``leftover``, :meth:`darksynth.estimation.noise.self_check._CheckedWindow.leftovers`; 0 where not read)."""

    blocks: int
    real_std: float
    synthetic_std: float
    scene_variance: float
    leftover: float = 0.0
    correlation_excess: float = 0.0
    """The mean channel correlation of what the denoiser took off the reference's blocks less that of the profile's
    noise on them (:func:`residual_structure`)."""
    smoothness_excess: float = 0.0
    """The same for the neighbour (lag-1) correlation."""

    @property
    def texture_like(self) -> bool:
        """Whether what the denoiser took off the blocks is more alike across channels or smoother than the profile's
        noise (:data:`TEXTURE_CORRELATION_MARGIN`, :data:`TEXTURE_SMOOTHNESS_MARGIN`): texture, or noise whose colour
        the profile has wrong there. A weak reading on such blocks says nothing of the level."""
        return (
            self.correlation_excess > TEXTURE_CORRELATION_MARGIN or self.smoothness_excess > TEXTURE_SMOOTHNESS_MARGIN
        )

    @property
    def weak_on_texture(self) -> bool:
        """A ratio under 1 on texture-like blocks: the reference shows more than the profile there, but not noise."""
        return self.ratio < 1.0 and self.texture_like

    def within(self, bounds: tuple[float, float]) -> bool:
        """The ratio within ``bounds``, or under them where :attr:`weak_on_texture`."""
        return self.ratio <= bounds[1] and (bounds[0] <= self.ratio or self.weak_on_texture)

    @property
    def departure(self) -> float:
        """How far the ratio lies from 1, as a factor; 1 where :attr:`weak_on_texture`."""
        return 1.0 if self.weak_on_texture else math.exp(abs(math.log(max(self.ratio, 1e-12))))

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
        """1 where the blocks are consistent, else the level factor that brings them to
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
        return self.within(CONSISTENT_RANGE)


def block_std(frame: torch.Tensor) -> torch.Tensor:
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


def residual_structure(residual: torch.Tensor, blocks: torch.Tensor) -> tuple[float, float]:
    """Of ``residual`` (3, H, W) on the ``blocks`` (rows * cols,) bool, each block less its mean per channel: the mean
    correlation of its channel pairs and the mean neighbour (lag-1, along rows and columns) correlation of its
    channels, pooled over the blocks."""
    unfolded = F.unfold(residual[:, None].to(torch.float64), FLAT_BLOCK, stride=FLAT_BLOCK)
    chosen = unfolded[:, :, : blocks.numel()][:, :, blocks].permute(0, 2, 1)
    tiles = (chosen - chosen.mean(-1, keepdim=True)).reshape(3, -1, FLAT_BLOCK, FLAT_BLOCK)
    power = tiles.square().sum(dim=(1, 2, 3)).clamp_min(1e-24)
    pairs = [(tiles[i] * tiles[j]).sum() / (power[i] * power[j]).sqrt() for i, j in ((0, 1), (1, 2), (0, 2))]
    along = (tiles[..., 1:] * tiles[..., :-1]).sum(dim=(1, 2, 3)) + (tiles[..., 1:, :] * tiles[..., :-1, :]).sum(
        dim=(1, 2, 3)
    )
    return float(torch.stack(pairs).mean()), float((along / (2 * power)).mean())


def block_check(
    reference: torch.Tensor, denoised: torch.Tensor, synthetic: torch.Tensor, blocks: torch.Tensor
) -> BlockCheck:
    """The check on the ``blocks`` (rows * cols,) bool: ``synthetic`` is the profile's noise added to ``denoised``
    (all three (3, H, W), the same size)."""
    real, clean, made = (block_std(frame)[: blocks.numel()][blocks] for frame in (reference, denoised, synthetic))
    real_std, synthetic_std = float(real.median()), float(made.median())
    taken = residual_structure(reference - denoised, blocks)
    noise = residual_structure(synthetic - denoised, blocks)
    return BlockCheck(
        int(blocks.sum()),
        real_std,
        synthetic_std,
        float(clean.square().median()),
        correlation_excess=taken[0] - noise[0],
        smoothness_excess=taken[1] - noise[1],
    )


def self_consistency(reference: torch.Tensor, denoised: torch.Tensor, synthetic: torch.Tensor) -> BlockCheck:
    """The check over the whole reference (3, H, W): on the :data:`CHECK_SHARE` flattest blocks of its denoised
    version whose mean lies in :data:`CHECK_MEAN_RANGE`."""
    return block_check(reference, denoised, synthetic, checked_blocks(denoised))


FACTOR_BOUNDS = (1.0 / 16.0, 4.0)
"""The level factors one step of a correction may take: a reference whose denoised scene alone is as rough as the
reference supports no noise at all, which the lower bound stands for."""

CORRECTION_TARGET = (1.0, 1.2)
"""The ratios a correction aims at, from below and from above. From below, 1: with what the denoiser left of the noise
taken out a true level reads 1.00-1.04, and a weak reading moves a level only where what the denoiser took off looks
like noise (:attr:`BlockCheck.texture_like`). Until both held it aimed at the near edge of :data:`CONSISTENT_RANGE`,
0.85, and sidd-phones' under-reads settled at 0.73-0.76 of their clean images' reading. From above, the near edge
1.2: a correction from above that aimed at 1 settled under the truth (the round trip's case 32: 1.02 -> 0.85 of the
true std, before the leftover was read); the least move that makes the reference consistent is the one it
supports."""
