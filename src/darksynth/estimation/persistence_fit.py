"""The frame-to-frame correlation of a clip's noise, fitted by re-synthesis on frame differences of still blocks.

The spectral fit reads the correlation of a denoiser's residual from frame to frame. On a still region that
residual keeps some of the still scene (fine texture the denoiser took for noise, the same in every frame), which a
correlation reads as noise that persists, and its simulation, built on the denoised frames, forgets more between
frames than the reference does (each denoised frame carries its own leftover noise): the coefficient came out too
high on every drawn clip of ``scripts/noise/temporal_harness.py`` and every real clip of
``scripts/noise/spectral_temporal_check.py``.

Here the statistics hold no scene: on the still flat blocks a frame minus an earlier one (each block's plane of change
taken out: a change of exposure or light) is the difference of their noise. Per band the power of those
differences at lag ``k`` is ``D_k = 2 v (1 - rho_k)`` for noise of variance ``v``. Two statistics are read from it:

* the ratio ``(D_3 - D_1) / D_2`` (4 frames; ``D_2 / D_1 - 1`` with 3): ``rho`` for AR(1) noise, with neither ``v``
  nor the scene in it (with 4 frames also right for noise that persists into the next frame only: phone clips
  whose frames come in near-identical pairs). It errs upward when the "still" blocks change slowly (light, a
  codec, slight motion), a change that grows with the lag;
* the lag-one reading ``1 - D_1 / D_1(independent)``, the lag-1 difference power over that of a simulation with
  independent frames: the lag-1 correlation whatever the noise's process (what a viewer and
  ``evaluation.structure.temporal_lag_correlation`` see), but as good as the fitted level: noise fitted too strong
  (texture counted as noise) reads as persistence.

Rounding to 8 bits, the clipping at black, JPEG and the masking of the differences bend both, so neither is
inverted by formula but by simulation (indirect inference, like the level fit): the still base (the mean of the
denoised frames), noise of the fitted spectrum with candidate coefficients, quantised and compressed as the model
does, the same differences on the same blocks (no denoiser is needed: the differences of a still scene are noise).
Per octave each statistic's coefficient is read off a grid of coefficients on [0, :data:`MAX_COEFFICIENT`] (all
octaves at once, the same noise draw at every point; the first crossing), and the smaller of the two is kept: each
errs upward in its own way, and persistence is what both see.

An octave that a statistic cannot read takes the finer octave's coefficient: its statistic barely moves with the
coefficient (:data:`MIN_TEMPORAL_RESPONSE`), or the reference's lies far beyond what any coefficient gives
(:data:`BEYOND_REACH`: the "still" blocks change in a way no noise does, as the coarse content of real clips' does).
When the finest octave cannot be read, the prior 0 with a warning.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from darksynth.estimation.flat_blocks import FLAT_BLOCK
from darksynth.estimation.spectral_fit import SpectralParameters, quantised, uncensored_signal
from darksynth.estimation.spectral_statistics import band_masks
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import OCTAVES, level_std
from darksynth.noise.values import NoiseValues

MAX_COEFFICIENT = 0.99
"""The AR(1) coefficient's upper bound (the table's)."""

MIN_TEMPORAL_RESPONSE = 0.15
"""An octave's statistic must rise by at least this over the search grid in the simulation (ideally by 0.99) for
the reference to set it: below, rounding, JPEG or sampling error hide its persistence."""

BEYOND_REACH = 0.25
"""A band's statistic above the simulation's highest by more than this: the still blocks change in a way no noise
does (slow motion, light, a codec), and the band's reading is not trusted."""

FROZEN_POWER = 1e-12
"""A band whose lag-2 difference power is below this does not change between frames (repeated frames: exactly 0;
one pixel changed by one 8-bit level leaves about 1e-6)."""

SEARCH_GRID = (0.0, 0.2, 0.4, 0.55, 0.7, 0.8, 0.9, 0.95, MAX_COEFFICIENT)
"""The coefficients simulated (the same on every octave at once, the same noise draw each time)."""


def _band_weights(height: int, width: int, device: torch.device) -> torch.Tensor:
    """(OCTAVES, H, W // 2 + 1) which half-plane frequencies of an ``rfft2`` fall in each band of
    :data:`~darksynth.estimation.spectral_statistics.BANDS`, counted twice where the half-plane stands for two."""
    twice = torch.full((height, width // 2 + 1), 2.0, dtype=torch.float64, device=device)
    twice[:, 0] = 1.0
    if width % 2 == 0:
        twice[:, -1] = 1.0
    return band_masks(height, width, device) * twice


def without_block_planes(differences: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Differences of frames (P, 3, H, W) float64, masked, with each :data:`FLAT_BLOCK` block's least-squares plane per
    channel taken out: a change of exposure or light between frames moves each block's level and, on its shading,
    its slope (the starlight video dims by 7 levels in 4 frames). A gain fitted over the whole mask was tried: its
    error, times the steps between blocks of different brightness, read as change in every band."""
    height, width = differences.shape[-2:]
    pad = (0, -width % FLAT_BLOCK, 0, -height % FLAT_BLOCK)
    masked = F.pad(differences * mask, pad)
    weight = F.pad(mask, pad).expand_as(masked[:1, :1])
    offsets = torch.arange(FLAT_BLOCK, dtype=torch.float64, device=differences.device) - (FLAT_BLOCK - 1) / 2
    across = offsets.repeat(masked.shape[-1] // FLAT_BLOCK)[None, :].expand(masked.shape[-2], -1)
    down = offsets.repeat(masked.shape[-2] // FLAT_BLOCK)[:, None].expand(-1, masked.shape[-1])
    plane = torch.zeros_like(masked)
    # Masks are whole blocks, so within one the constant and the two centred slopes are orthogonal.
    for basis in (torch.ones_like(across), across, down):
        loading = F.avg_pool2d(masked * basis, FLAT_BLOCK) / F.avg_pool2d(
            weight * basis.square(), FLAT_BLOCK
        ).clamp_min(1e-12)
        plane += loading.repeat_interleave(FLAT_BLOCK, dim=-2).repeat_interleave(FLAT_BLOCK, dim=-1) * basis
    return ((masked - plane) * weight)[..., :height, :width]


def difference_powers(frames: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(lags, OCTAVES) per lag ``k`` (1 to T - 1) the mean over the pairs ``k`` apart of each band's power of the
    masked difference ``frame[t + k] - frame[t]``, summed over the channels. ``frames`` (T, 3, H, W), ``mask``
    (H, W) in {0, 1}. The power is read on the difference's spectrum (Parseval: no band-passed field is formed)."""
    mask = mask.to(device=frames.device, dtype=torch.float64)
    frames = frames.to(torch.float64)
    count, height, width = frames.shape[0], frames.shape[-2], frames.shape[-1]
    weights = _band_weights(height, width, frames.device)
    powers = torch.zeros(count - 1, OCTAVES, dtype=torch.float64, device=frames.device)
    for lag in range(1, count):
        differences = without_block_planes(frames[lag:] - frames[:-lag], mask)
        spectrum = torch.fft.rfft2(differences).abs().square().sum(dim=1)  # (pairs, H, W // 2 + 1)
        powers[lag - 1] = torch.einsum("phw,bhw->b", spectrum, weights) / differences.shape[0]
    return powers


def persistence_statistic(powers: torch.Tensor) -> torch.Tensor:
    """(OCTAVES,) the statistic of the module from :func:`difference_powers` of 3 or 4+ frames (lags 1-3)."""
    lag_one, lag_two = powers[0], powers[1].clamp_min(1e-30)
    # Three frames: AR(1) from lags 1 and 2; four or more: the form that also holds for a one-frame persistence.
    statistic = (powers[2] - lag_one) / lag_two if powers.shape[0] >= 3 else lag_two / lag_one.clamp_min(1e-30) - 1
    # A band that does not change at all (frames repeated) persists fully.
    return torch.where(powers[1] <= FROZEN_POWER, torch.ones_like(statistic), statistic)


def still_simulator(
    denoised: torch.Tensor,
    mask: torch.Tensor,
    parameters: SpectralParameters,
    compression: float,
    seed: int,
) -> Callable[[torch.Tensor], torch.Tensor]:
    """The :func:`difference_powers` of a still clip of ``parameters``' noise with coefficients ``temporal``
    (OCTAVES,): the mean of the denoised frames (T, 3, H, W) in every frame, noise drawn from the same seed at every
    call."""
    base = denoised.mean(dim=0, keepdim=True).expand_as(denoised)
    signal = uncensored_signal(base, level_std(base, parameters.curve.reshape(-1).to(base)))

    def powers(temporal: torch.Tensor) -> torch.Tensor:
        candidate = SpectralParameters(parameters.covariances, parameters.curve, temporal)
        values = NoiseValues.from_values(candidate.as_values() | {"compression": compression}, dtype=torch.float32)
        generator = torch.Generator(device=denoised.device).manual_seed(104729 + seed * 1009)
        synthetic = quantised(add_noise(signal[None], values, generator=generator)[0])
        return difference_powers(synthetic, mask)

    return powers


def solve_coefficients(target: torch.Tensor, curve: torch.Tensor) -> torch.Tensor:
    """Per octave the smallest coefficient whose simulated statistic (``curve``, one row per point of
    :data:`SEARCH_GRID`) reaches ``target`` (OCTAVES,), linear between the grid's points; 0 when the target is at or
    below the statistic at 0, the coefficient of the highest statistic when the target is above every point. The
    first crossing, not any: JPEG's rounding of each frame turns a small change between frames into a large one, so
    past a point more persistence can read as less."""
    grid = torch.tensor(SEARCH_GRID, dtype=torch.float64)
    coefficient = grid[curve.argmax(dim=0)]
    for octave in range(OCTAVES):
        reached = (curve[:, octave] >= target[octave]).nonzero()
        if len(reached) == 0:
            continue
        first = int(reached[0])
        if first == 0:
            coefficient[octave] = 0.0
            continue
        below, above = curve[first - 1, octave], curve[first, octave]
        share = (target[octave] - below) / (above - below).clamp_min(1e-9)
        coefficient[octave] = grid[first - 1] + share * (grid[first] - grid[first - 1])
    return coefficient


@dataclass(frozen=True)
class _Reading:
    """One statistic's reading per octave: the coefficient, whether the reference can set it, and the figures."""

    coefficient: torch.Tensor
    readable: torch.Tensor
    target: torch.Tensor
    response: torch.Tensor


def _read(target: torch.Tensor, curve: torch.Tensor) -> _Reading:
    """The coefficients a ``target`` statistic (OCTAVES,) gives on its simulated ``curve`` (grid, OCTAVES), and
    which octaves it can set: those whose statistic moves with the coefficient (:data:`MIN_TEMPORAL_RESPONSE`) and
    whose target lies within :data:`BEYOND_REACH` of what some coefficient gives (else the "still" blocks change in
    a way no noise does: slow motion, light, a codec)."""
    response = curve.max(dim=0).values - curve[0]
    reachable = (target <= curve.max(dim=0).values + BEYOND_REACH) & (target >= curve.min(dim=0).values - BEYOND_REACH)
    readable = (response >= MIN_TEMPORAL_RESPONSE) & reachable
    return _Reading(solve_coefficients(target, curve), readable, target, response)


def _rounded(values: torch.Tensor) -> list[float]:
    return [round(float(v), 3) for v in values]


def _record(ratio: _Reading, lag_one: _Reading) -> dict[str, object]:
    """What ``meta.spectrum`` keeps of the two readings."""
    return {
        "persistence_ratio": {"statistic": _rounded(ratio.target), "response": _rounded(ratio.response)},
        "persistence_lag_one": {"statistic": _rounded(lag_one.target), "response": _rounded(lag_one.response)},
        "persistence_read": [bool(v) for v in ratio.readable & lag_one.readable],
    }


def fit_persistence(
    frames: torch.Tensor,
    denoised: torch.Tensor,
    mask: torch.Tensor,
    parameters: SpectralParameters,
    compression: float,
    seed: int,
) -> tuple[torch.Tensor, dict[str, object], str | None]:
    """The AR(1) coefficient per octave of the noise of still-block frames (T >= 3, 3, H, W) (see the module):
    the coefficients, a record for ``meta`` and a warning's reason (None when the reading stands)."""
    measured = difference_powers(frames, mask)
    simulate = still_simulator(denoised, mask, parameters, compression, seed)
    simulated = torch.stack([simulate(torch.full((OCTAVES,), r, dtype=torch.float64)) for r in SEARCH_GRID])
    ratio = _read(persistence_statistic(measured), torch.stack([persistence_statistic(p) for p in simulated]))
    independent = simulated[0, 0].clamp_min(1e-30)
    lag_one = _read(1.0 - measured[0] / independent, 1.0 - simulated[:, 0] / independent)
    record = _record(ratio, lag_one)
    if bool(ratio.target[0] >= 1.0):
        # Repeated frames: no simulated noise changes so little, the frames' noise is the same.
        record["persistence_prior"] = "frames repeated: the noise persists fully"
        return torch.full((OCTAVES,), MAX_COEFFICIENT, dtype=torch.float64), record, None
    # Each reading errs upward in its own way (see the module): the persistence is what both see.
    coefficient = torch.minimum(ratio.coefficient, lag_one.coefficient)
    readable = ratio.readable & lag_one.readable
    if not bool(readable[0]):
        hidden = bool(ratio.response[0] < MIN_TEMPORAL_RESPONSE)
        reason = "its noise hides it" if hidden else "its still blocks change more than noise does"
        return torch.zeros(OCTAVES, dtype=torch.float64), record, reason
    for octave in range(1, OCTAVES):
        # An octave that cannot be read persists like the finer one next to it.
        if not bool(readable[octave]):
            coefficient[octave] = coefficient[octave - 1]
    return coefficient, record, None
