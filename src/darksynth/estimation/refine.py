"""Test-time refinement of a noise estimate on the reference itself: analysis by synthesis.

A blind estimate (the DEN's) is corrected so that the simulator, run on a denoised copy of the reference,
reproduces the reference's own residual statistics measured through the same operator (indirect inference,
Gourieroux, Monfort and Renault 1993). With ``x_hat = D(y)`` the denoised reference and ``s(.)`` the
statistics of the residual ``z - D(z)`` of an image z:

1. ``s(y)`` is measured once on the reference: the residual's variance per channel and per level of x_hat
   (on the smoothest half of the pixels, where D removes noise and little else), its lag-1 autocorrelation,
   its red-green, green-blue and red-blue correlations, and the variance of its column means;
2. for the current values v, ``y_s = add_noise(x_hat, v)`` on 8-bit levels, and ``s(y_s)`` is measured with
   the same mask and level bins;
3. each parameter moves by the gap between the two: the correlation length so that the theoretical scale
   ratio (half resolution over full) of the brightness detail changes by the gap, the chroma length likewise
   on the opponent colour components' ratio; the per-bin noise variance by the added gap s(y) - s(y_s)
   (less what the lengths' change does to the detail's variance, in theory) and the table's law (green's shot
   and read, red's and blue's gains) is refitted to it; the channel correlations by theirs; the column
   components (banding, temporal banding, periodic) are scaled together to close the
   gap in column-mean variance. Everything is clipped to the table's bounds; quantization keeps its initial
   value;
4. steps 2-3 run for each of a few compression strengths (:data:`COMPRESSION_CANDIDATES`), and the strength
   whose refined simulation's residual structure (scale ratios, autocorrelation, channel correlations) is
   closest to the reference's wins.

What D does to the noise (it removes part of it, more of correlated noise, and leaves texture) is the same for
y and y_s, so it cancels instead of biasing the estimate; what remains is the difference between D(y) and the
true clean image, small on the smooth pixels the statistics read. The synthetic noise has a fixed seed in
every iteration (common random numbers), so the refinement is deterministic and its steps are not noise.

``D`` is a Gaussian filter: cheap on a CPU and with no training; the DEN's decoder output was the other
candidate (docs/refine.md compares them on synthetic references). The reference as the steps read it and the
statistics s(.) are in :mod:`darksynth.estimation.refine_statistics`; the steps and their loop are here.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import torch

from darksynth.estimation.refine_statistics import (
    ANALYSIS_SIDE,
    DENOISE_SIGMA,
    Analysis,
    ResidualStatistics,
    analyse,
    as_frames,
    gaussian_denoise,
    level_variance,
    log_ratio,
    residual_statistics,
)
from darksynth.noise.components import noise_parameter
from darksynth.noise.correlated import kernel_autocorrelation
from darksynth.noise.fit import (
    LENGTH_GRID,
    PoissonGaussian,
    autocorrelation,
    central_crop,
    channel_correlations,
    clipped,
    fit_correlation_length,
    normalised_noise,
    oracle_poisson_gaussian,
    values_of_law,
    weighted_line,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels

ITERATIONS = 2
"""Refinement steps for each compression candidate; each simulates and measures the reference's crop once."""

FINAL_ITERATIONS = 1
"""Further steps for the chosen compression candidate."""

COMPRESSION_CANDIDATES = (0.0, 0.1, 0.25, 0.4)
"""Compression strengths tried (none, JPEG quality 90, 75, 60); the refined values of each are simulated once
more and the one whose residual structure is closest to the reference's wins. The DEN's own strength is not
among them: it is never exactly 0, and any strength above 0 means JPEG with 4:2:0 chroma subsampling, which
removes most colour from fine noise."""

MAX_STEP_RATIO = 4.0
"""Most a step may scale a level bin's variance by (or divide it by): a simulation far off in structure (a
length at a bound, a wrong compression) must not throw the level out of range in one step."""

CATCH_UP_STEPS = 4
"""Further steps for the chosen candidate while its level is still held back by MAX_STEP_RATIO: with the fixed
steps, a level can then move by up to 4^(2 + 1 + 4) in variance (128x in std) from the network's."""

MAX_LENGTH_STEP = 0.75
"""Most a step may move a kernel length (pixels)."""

COLUMN_PARAMETERS = ("banding", "temporal_banding", "periodic")
"""The column components, scaled together: their column-mean variances add up."""


@lru_cache(maxsize=1)
def _scale_theory() -> np.ndarray[tuple[int], np.dtype[np.float64]]:
    """For every length of LENGTH_GRID, :func:`_pooled_scale_ratio` of noise filtered by the table's Gaussian
    kernel of that length, in theory: 1/4 for white noise, rising with the length.

    Separable again: along each axis the fine detail is the difference ``[1, -1]`` and the coarse one, after
    the 2x2 average, ``[1, 1, -1, -1] / 2``; a filter h applied to noise of autocorrelation r has the variance
    ``sum_ij h_i h_j r(|i - j|)``, and the 2-D ratio is the square of the 1-D one.
    """
    fine = np.array([1.0, -1.0])
    coarse = np.array([1.0, 1.0, -1.0, -1.0]) / 2.0
    ratios = []
    for length in LENGTH_GRID:
        r = np.array([kernel_autocorrelation(length, lag) for lag in range(4)])
        ratios.append((_filtered_variance(coarse, r) / max(_filtered_variance(fine, r), 1e-20)) ** 2)
    return np.array(ratios)


def _filtered_variance(
    h: np.ndarray[tuple[int], np.dtype[np.float64]], r: np.ndarray[tuple[int], np.dtype[np.float64]]
) -> float:
    lags = np.abs(np.subtract.outer(np.arange(h.size), np.arange(h.size)))
    return float(h @ r[lags] @ h)


@lru_cache(maxsize=1)
def _detail_gain() -> np.ndarray[tuple[int], np.dtype[np.float64]]:
    """For every length of LENGTH_GRID, the variance (relative to the noise's) of the diagonal detail of noise
    filtered by the table's Gaussian kernel of that length.

    The kernel's autocorrelation r(d) is separable, so is the detail's: a first difference along x and along y
    has the variance 2 - 2 r1, which gives (1 - r1)^2 for the detail's factor 1/2.
    """
    r1 = np.array([kernel_autocorrelation(length, 1) for length in LENGTH_GRID])
    return np.square(1.0 - r1)


def _length_index(length: float) -> int:
    return int(np.argmin(np.abs(np.asarray(LENGTH_GRID) - length)))


def simulate(analysis: Analysis, values: NoiseValues, *, seed: int) -> torch.Tensor:
    """The denoised reference through the composer: add_noise(x_hat, v) as one clip, on 8-bit levels."""
    generator = torch.Generator().manual_seed(seed)
    return to_8bit_levels(add_noise(analysis.denoised, values, generator=generator))


def _floored(values: NoiseValues) -> NoiseValues:
    # A level of zero would draw no noise, and a ratio of residual variances could never move it.
    shot = max(values.scalar("shot"), noise_parameter("shot").log_floor or 0.0)
    read = max(values.scalar("read"), noise_parameter("read").log_floor or 0.0)
    return values.replace(shot=shot, read=read)


def _model_variance(values: NoiseValues, levels: torch.Tensor) -> torch.Tensor:
    red, blue = (float(g) for g in values["channel_gain"].tolist())
    gains = torch.tensor([red, 1.0, blue], dtype=levels.dtype).view(3, 1)
    return gains.square() * (values.scalar("shot") ** 2 * levels.clamp_min(0.0) + values.scalar("read") ** 2)


def _refit_levels(values: NoiseValues, levels: torch.Tensor, target: torch.Tensor, clean: torch.Tensor) -> NoiseValues:
    a_values, b_values = [], []
    for channel in range(3):
        level = levels[channel].numpy()
        variance = target[channel].numpy()
        weights = 1.0 / np.maximum(variance, 1e-12)
        a, b = weighted_line(level, variance, weights)
        # The 1/variance weights follow the quiet bins, and sRGB noise (after the tone curve) often does not
        # rise with the level as the law does: the line is rescaled so that its mean over the bins is the
        # target's, the total the histogram of the noise sees (as the oracle's level correction does).
        fitted = np.maximum(a * level + b, 0.0).mean()
        scale = float(variance.mean() / fitted) if fitted > 0.0 else 1.0
        a_values.append(a * scale)
        b_values.append(b * scale)
    law = PoissonGaussian(a=(a_values[0], a_values[1], a_values[2]), b=(b_values[0], b_values[1], b_values[2]))
    fitted = values_of_law(law, clean)
    return values.replace(shot=fitted["shot"], read=fitted["read"], channel_gain=fitted["channel_gain"])


def _moved_length(length: float, reference_ratio: float, simulated_ratio: float) -> float:
    """The kernel length whose theoretical scale ratio differs from ``length``'s as the reference's from the
    simulation's (in logs), moved by at most MAX_LENGTH_STEP pixels."""
    theory = np.log(_scale_theory())
    gap = log_ratio(reference_ratio) - log_ratio(simulated_ratio)
    wanted = theory[_length_index(length)] + gap
    moved = float(LENGTH_GRID[int(np.argmin(np.abs(theory - wanted)))])
    return min(max(moved, length - MAX_LENGTH_STEP), length + MAX_LENGTH_STEP)


def _finer_channel_factors(
    length_old: float, length: float, reference: ResidualStatistics, simulated: ResidualStatistics
) -> torch.Tensor:
    """Per channel (3, 1), the detail gain of the shared kernel ``length`` over that of the channel's own length,
    which moves from ``length_old`` by the gap in the channel's scale ratio (unbounded by MAX_LENGTH_STEP: it is
    read afresh at every step, not carried)."""
    gain = _detail_gain()
    theory = np.log(_scale_theory())
    factors = []
    for channel in range(3):
        gap = log_ratio(float(reference.scale_ratio[channel])) - log_ratio(float(simulated.scale_ratio[channel]))
        own = int(np.argmin(np.abs(theory - (theory[_length_index(length_old)] + gap))))
        factors.append(gain[_length_index(length)] / gain[own])
    return torch.tensor(factors, dtype=reference.variance.dtype).view(3, 1)


def _detail_variance(length: float, colour_length: float, colour_share: float) -> float:
    """The finest detail's variance, relative to the noise's, of noise whose brightness part has the kernel
    length ``length`` and whose colour part (``colour_share`` of the variance) ``colour_length``."""
    gain = _detail_gain()
    return float((1.0 - colour_share) * gain[_length_index(length)] + colour_share * gain[_length_index(colour_length)])


def refine_step(
    values: NoiseValues, analysis: Analysis, reference: ResidualStatistics, *, seed: int = 0
) -> tuple[NoiseValues, ResidualStatistics, bool]:
    """One step: simulate with ``values``, measure, move every refined parameter by the gap to the reference.

    Returns:
        The moved values, the statistics of the simulation with ``values`` (before the move), and whether the
        level was held back by :data:`MAX_STEP_RATIO` (the median level bin wanted more than the cap allows).
    """
    values = _floored(values)
    simulation = simulate(analysis, values, seed=seed)
    simulated = residual_statistics(simulation, analysis)
    # What of the simulation's level band is its own noise: the rest is content of x_hat, which the reference
    # shares (or, where D removed it, holds more of); the gap is added to the noise, not multiplied into it.
    own = level_variance(simulation - analysis.denoised, analysis)
    # The lengths move first, on theory, so that the levels can discount what the new lengths change of the
    # detail's variance: one step then moves them without their gaps feeding each other. The brightness part
    # of the noise has the kernel length l, its colour part sqrt(l^2 + e^2) (e the chroma length).
    length_old = values.scalar("correlation_length")
    chroma_old = values.scalar("chroma_length")
    colour_old = math.hypot(length_old, chroma_old)
    moved = _moved_length(length_old, reference.luma_scale_ratio, simulated.luma_scale_ratio)
    length = clipped("correlation_length", moved)
    colour = max(_moved_length(colour_old, reference.colour_scale_ratio, simulated.colour_scale_ratio), length)
    chroma = clipped("chroma_length", math.sqrt(max(colour**2 - length**2, 0.0)))
    colour = math.hypot(length, chroma)
    correlation = sum(float(c) for c in values["channel_correlation"].tolist()) / 3.0
    colour_share = min(max(2.0 * (1.0 - correlation) / 3.0, 0.0), 1.0)
    discount = _detail_variance(length_old, colour_old, colour_share) / _detail_variance(length, colour, colour_share)
    # A channel whose noise is finer than the others' (demosaiced green is 1.2-1.7x finer than red and blue on
    # the real pairs) shows more of its variance in the finest detail than the shared length gives it, and
    # matched on that detail it would come out too strong: its target is scaled by the detail gain of the
    # shared length over that of the channel's own length (read, as the shared one is, from the gap in its
    # scale ratio), so that its total variance, which the histogram of its noise sees, is the reference's.
    wanted = (
        own + reference.variance * _finer_channel_factors(length_old, length, reference, simulated) - simulated.variance
    )
    ratio = wanted / own.clamp_min(1e-12)
    valid = (reference.variance > 0) & (own > 0)
    ratio = torch.where(valid, ratio, torch.ones_like(ratio))
    held_back = bool(ratio.median() > MAX_STEP_RATIO or ratio.median() < 1.0 / MAX_STEP_RATIO)
    ratio = ratio.clamp(1.0 / MAX_STEP_RATIO, MAX_STEP_RATIO)
    ratio = ratio * min(max(discount, 1.0 / MAX_STEP_RATIO), MAX_STEP_RATIO)
    target = _model_variance(values, analysis.levels) * ratio
    refined = _refit_levels(values, analysis.levels, target, analysis.denoised[0])
    refined = refined.replace(correlation_length=length, chroma_length=chroma)
    pairs = [
        clipped("channel_correlation", float(value) + real - synthetic)
        for value, real, synthetic in zip(
            values["channel_correlation"].tolist(), reference.correlations, simulated.correlations, strict=True
        )
    ]
    refined = refined.replace(channel_correlation=pairs)
    column = sum(float(values[name].square().sum()) for name in COLUMN_PARAMETERS)
    if column > 0.0:
        wanted_column = max(0.0, column + reference.column_variance - simulated.column_variance)
        scale = math.sqrt(wanted_column / column)
        refined = refined.replace(
            **{name: [clipped(name, float(v) * scale) for v in values[name].tolist()] for name in COLUMN_PARAMETERS}
        )
    return refined, simulated, held_back


def refine_profile(
    reference: torch.Tensor,
    initial: NoiseValues,
    *,
    iterations: int = ITERATIONS,
    final_iterations: int = FINAL_ITERATIONS,
    seed: int = 0,
    denoised: torch.Tensor | None = None,
    sigma: float = DENOISE_SIGMA,
) -> NoiseValues:
    """Refine a blind noise estimate so that the simulator reproduces the reference's residual statistics.

    Args:
        reference: the real noisy reference, an image (3, H, W) or frames (T, 3, H, W) in [0, 1], as read
            by :func:`darksynth.estimation.reference.load_reference`.
        initial: unbatched noise values to start from, e.g. ``estimate(...).profile.noise`` or :func:`plain_fit`.
        iterations: refinement steps for each compression candidate (at least 1).
        final_iterations: further steps for the chosen candidate.
        seed: seed of the synthetic noise (the same in every step).
        denoised: the denoised :func:`~darksynth.estimation.refine_statistics.analysis_crop` of the reference
            (e.g. :func:`darksynth.estimation.network.den_denoise`); the Gaussian filter when not given.
        sigma: std in pixels of the Gaussian denoiser.

    Returns:
        Unbatched noise values (float64): shot, read, channel gains, correlation length, channel correlations
        and the column components refined, compression chosen among :data:`COMPRESSION_CANDIDATES`;
        quantization as in ``initial``.

    References:
        Gourieroux, Monfort and Renault 1993, Indirect inference.
    """
    if iterations < 1:
        raise ValueError(f"refine_profile needs at least one iteration per candidate, got {iterations}")
    if initial.batch_shape:
        raise ValueError(f"refine_profile needs unbatched values, got batch {initial.batch_shape}")
    analysis = analyse(reference, denoised=denoised, sigma=sigma)
    target = residual_statistics(analysis.noisy, analysis)
    best, best_distance = initial, math.inf
    for compression in COMPRESSION_CANDIDATES:
        values = initial.to("cpu", torch.float64).replace(compression=compression)
        for _ in range(iterations):
            values, simulated, _ = refine_step(values, analysis, target, seed=seed)
        # Scored by the simulation of the last step's input, which is one step behind but costs nothing more.
        distance = target.distance(simulated)
        if distance < best_distance:
            best, best_distance = values, distance
    held_back = False
    for _ in range(final_iterations):
        best, _, held_back = refine_step(best, analysis, target, seed=seed)
    # A start far off (a network that calls a visibly noisy reference nearly noise-free) is still held back by
    # the step cap after the fixed steps: it gets up to CATCH_UP_STEPS more, as long as the cap holds it.
    for _ in range(CATCH_UP_STEPS):
        if not held_back:
            break
        best, _, held_back = refine_step(best, analysis, target, seed=seed)
    return best


def plain_fit(reference: torch.Tensor, *, sigma: float = DENOISE_SIGMA) -> NoiseValues:
    """The clean-aided fit with the denoised reference as the clean image, uncorrected: biased by what the
    denoiser removes of the noise and leaves of the content (the refinement's control and a starting point)."""
    frame = central_crop(as_frames(reference)[0], ANALYSIS_SIDE).to(torch.float64)
    denoised = gaussian_denoise(frame, sigma)
    values = values_of_law(oracle_poisson_gaussian(frame, denoised), denoised)
    unit = normalised_noise(frame, denoised, values)
    return values.replace(
        correlation_length=fit_correlation_length(autocorrelation(unit)),
        channel_correlation=channel_correlations(unit),
    )
