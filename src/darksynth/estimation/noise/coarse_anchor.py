"""The coarse colour octaves a denoiser's residual cannot show, read in flat blocks as the share of their noise that
is coarse."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch
import torch.nn.functional as F

from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK, block_planes, detrended_blocks
from darksynth.estimation.noise.spectral_fit import SpectralParameters, quantised, uncensored_signal
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import level_std
from darksynth.noise.values import NoiseValues

ANCHOR_GAIN = 1.5
"""Exponent on the ratio of the anchor's odds per step: the unmeasured octaves hold only part of the coarse means'
variance, so the ratio alone moves their scale too little."""

ANCHOR_WARM_STEPS = 4
"""Updates of the anchor's scale alone before the last fit."""

ANCHOR_SCALE_RANGE = (0.1, 100.0)
"""Bounds of the factor on the unmeasured octaves' power: real cameras' coarse colour mottle reaches some 80x white
noise's power (docs/spectral-noise.md), against 1x where the prior continues a flat spectrum."""

ANCHOR_QUANTILE = 0.25
"""The quantile over blocks of the coarse odds (:func:`coarse_odds`) the anchor matches (the same in the reference and
the simulations, so any quantile is unbiased for noise): texture left in a flat block is coarse and only raises its
odds, and a low quantile reads the blocks it left alone."""


def anchor_pool(first_unmeasured: int) -> int | None:
    """Side in px of the means whose variance is a block's coarse part, for the finest octave the residual cannot show
    (index ``first_unmeasured``, wavelength ``2 ** (k + 1.5)`` px): ``2 ** k``, which keeps that octave and the
    coarser ones and loses nearly all of the finer, fitted ones; None where a block holds fewer than 4 x 4 such means
    (a plane takes 3 of them): the octaves from 45 px up alone are not read in a 32-px block.

    Means of 4 px read for the 22-px octave on, which hold the 11-px octave as well, left the phones' colour at
    16-64 px 1.2-1.8x the real against 0.94-1.12 with 8 px (the development subsample of docs/spectral-noise.md,
    issue 39); 8-px means read for the 45-px octave on ran its scale to 3-40 on white noise."""
    side = 2**first_unmeasured
    return side if side <= FLAT_BLOCK // 4 else None


ANCHOR_MOVED = 2.0
"""A scale this far from 1 (either way) must have moved the anchor's statistic to count as a reading."""

ANCHOR_RESPONSE = 1.1
"""The least change of the simulated statistic, from the first simulation to the last, that a moved scale must
have caused (a factor; the common random numbers make the simulations comparable)."""

COMPONENT_NAMES = ("brightness", "red-green", "blue-yellow")


def coarse_odds(frame: torch.Tensor, blocks: torch.Tensor, pool: int) -> torch.Tensor:
    """Per chosen block of ``frame`` (3, H, W) and component (brightness and the two colours), the odds
    ``coarse / (total - coarse)`` of its variance about the block's plane: ``coarse`` the variance of its
    ``pool``-px means, ``total`` that of its pixels. (3, n) float64 for the ``blocks`` (rows, cols) bool.

    A ratio of one block's noise to itself does not depend on the noise's level, which the level curve sets: matched
    as a variance, an error of a few percent in the level at the blocks' intensities came back as a 2-5x error in the
    coarse octaves' power (the phones of issue 39). The odds rather than the share: the share saturates at 1 as the
    coarse power grows, the odds grow with it."""
    detrended = detrended_blocks(frame, blocks).to(torch.float64)
    components, side, _, count = detrended.shape
    total = detrended.square().sum(dim=(1, 2)) / (side * side - 3)
    means = F.avg_pool2d(detrended.permute(0, 3, 1, 2).reshape(components * count, 1, side, side), pool)
    coarse = means.reshape(components, count, -1).square().mean(dim=2)
    return coarse / (total - coarse).clamp_min(1e-30)


def anchor_statistic(odds: torch.Tensor) -> torch.Tensor:
    """The :data:`ANCHOR_QUANTILE` over blocks of the coarse odds (3, n): (3,) float64."""
    return odds.to(torch.float64).quantile(ANCHOR_QUANTILE, dim=1)


@dataclass
class CoarseAnchor:
    """The noise under the block size that the denoiser's residual cannot show, read about planes.

    Non-local means leaves noise coarser than its search window in the image it returns, so octaves from about
    11 px up barely move its residual and take a prior (the finer octaves' spectrum continued). On a flat block the
    scene is close to a plane, and the noise about the plane holds every octave under 32 px: the
    :data:`ANCHOR_QUANTILE` over the measured blocks of its coarse odds (:func:`coarse_odds`) in the reference,
    against that of the model's noise added to the blocks' planes (no denoiser: no scene, no coarse noise of the
    reference in the base), scales the unmeasured octaves (``scale``). Texture left in a flat block reads as coarse
    noise here, which is why a low quantile over blocks flat for their level is used. Only colour is anchored (see
    :meth:`update`).

    Attributes:
        target: the reference's statistic of the coarse odds, brightness and the two colours (3,).
        pool: the side of the means of :func:`coarse_odds` (:func:`anchor_pool`), None where none reads.
        planes: the denoised frame's blocks as planes (3, H, W), the base of the simulations.
        blocks: (rows, cols) bool, the measured blocks.
        scale: the factor (3,) on the unmeasured octaves' power of each component, moved by :meth:`update`.
        last: the statistic of the last :meth:`observe`, until :meth:`update` uses it.
        first, latest: the first and the latest statistic an update used (for :meth:`unmatched`).
    """

    target: torch.Tensor
    pool: int | None
    planes: torch.Tensor
    blocks: torch.Tensor
    scale: torch.Tensor = field(default_factory=lambda: torch.ones(3, dtype=torch.float64))
    last: torch.Tensor | None = None
    first: torch.Tensor | None = None
    latest: torch.Tensor | None = None

    @classmethod
    def read(
        cls, frame: torch.Tensor, denoised: torch.Tensor, mask: torch.Tensor, first_unmeasured: int
    ) -> CoarseAnchor:
        """The anchor of a reference frame (3, H, W), its denoised version, and the measured pixels ``mask``
        ((H, W), or (T, H, W) of which the last frame's counts), for the octaves from ``first_unmeasured`` on."""
        last_mask = mask[-1] if mask.dim() == 3 else mask
        blocks = F.avg_pool2d(last_mask[None, None], FLAT_BLOCK)[0, 0] > 0.5
        pool = anchor_pool(first_unmeasured)
        target = (
            anchor_statistic(coarse_odds(frame, blocks, pool))
            if pool is not None and bool(blocks.any())
            else torch.zeros(3, dtype=torch.float64)
        )
        return cls(target=target, pool=pool, planes=block_planes(denoised), blocks=blocks)

    @property
    def readable(self) -> bool:
        """Whether the reference gave a target in every component (no measured block, or unmeasured octaves all too
        coarse for a block: nothing to anchor to)."""
        return bool((self.target > 0.0).all())

    def observe(self, parameters: SpectralParameters, compression: float, seed: int) -> None:
        """Simulate ``parameters`` (with the JPEG strength ``compression``) about the planes, for the next
        :meth:`update`; one draw of the estimate's ``seed``, the same at every step."""
        values = NoiseValues.from_values(parameters.as_values() | {"compression": compression}, dtype=torch.float32)
        generator = torch.Generator(device=self.planes.device).manual_seed(seed * 1009 + 7)
        self.last = self.simulated(values, parameters.curve, generator)

    def simulated(self, values: NoiseValues, curve: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        signal = uncensored_signal(self.planes, level_std(self.planes, curve.reshape(-1).to(self.planes)))
        if self.pool is None:
            raise ValueError("an anchor without a pool reads nothing: check readable before simulating")
        synthetic = quantised(add_noise(signal[None, None], values, generator=generator)[0, 0])
        return anchor_statistic(coarse_odds(synthetic, self.blocks, self.pool))

    @property
    def observed(self) -> bool:
        """Whether an update moved the scale on a simulation. A simulated statistic of 0 in any component is skipped
        (weak noise that JPEG and 8-bit rounding erase leaves no colour on a quarter of the flat blocks), and an
        anchor that only ever saw such statistics holds the prior: it read nothing."""
        return self.first is not None

    def update(self) -> None:
        """Move ``scale`` by the ratio of the target to the last simulation (bounded per step and overall)."""
        if self.last is not None and bool((self.last > 0.0).all()):
            self.first = self.last if self.first is None else self.first
            self.latest = self.last
            step = (self.target / self.last).pow(ANCHOR_GAIN).clamp(0.25, 4.0)
            # Brightness keeps the prior: texture left in flat blocks is brightness, and even the lower quartile of
            # the blocks read it as coarse brightness noise (up to 70x white on textured images of the round trip,
            # where colour stayed within 0.8-1.25; docs/spectral-noise.md).
            step[0] = 1.0
            self.scale = (self.scale * step).clamp(*ANCHOR_SCALE_RANGE)
        self.last = None

    def unmatched(self) -> list[int]:
        """The colour components whose scale is not a reading: moved more than :data:`ANCHOR_MOVED` from the prior
        while the simulated statistic it was moved for changed by less than :data:`ANCHOR_RESPONSE` (noise under
        one 8-bit level, where the rounding of the scene's planes is the variance, ran one component to 100 and
        the other to 0.1 with no effect on it). A scale held at 100 whose statistic followed is a strong mottle
        read. Brightness is never anchored."""
        if self.first is None or self.latest is None:
            return []
        moved = self.scale.log().abs() > math.log(ANCHOR_MOVED)
        silent = (self.latest / self.first.clamp_min(1e-30)).log().abs() < math.log(ANCHOR_RESPONSE)
        return [int(k) for k in torch.nonzero((moved & silent)[1:]).flatten() + 1]

    def release(self, components: list[int]) -> None:
        """Return ``components`` to the prior (scale 1): the finer octaves' spectrum continued."""
        self.scale[components] = 1.0

    def apply(self, covariances: torch.Tensor, first_unmeasured: int) -> torch.Tensor:
        """The octaves' covariances with the unmeasured ones' components scaled (their correlations kept)."""
        covariances = covariances.clone()
        root = self.scale.sqrt().to(covariances)
        covariances[first_unmeasured:] *= root[:, None] * root[None, :]
        return covariances
