"""The darkening x_d = alpha * x ** (1 / gamma) read from tone distributions: a real low-light reference's against
the prior of clean scenes (``estimate``), or against one clean input (``apply`` matching the reference's exposure).

The reference's content is unknown; only its intensity distribution is seen. Against a prior, the average tone
distribution of clean natural images, the darkening is a straight line in log-log coordinates::

    log q_ref(p) = log alpha + (1 / gamma) * log q_clean(p)

where q(p) is the quantile function of the pooled R, G and B values. Because darkening acts on each value
through the same increasing function, it maps quantiles to quantiles exactly. Both quantile functions are
taken over the medians of small blocks (:data:`BLOCK` pixels square, per channel): a median commutes with any
increasing function, so the block medians of a darkened image are exactly the darkened block medians, while
noise in them shrinks by about the block side and clipping at 0 does not bias them (the median of
clip(x + n) is clip(x) for symmetric noise). Quantiles still too close to the noise or to 8-bit rounding, and
those near saturation, are left out; the line is fitted by a Huber-weighted least-squares regression.

See docs/darkening-estimate.md for the measured accuracy and scripts/evaluate_darkening.py for the commands.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening
from darksynth.light.tone_blocks import NOISE_BLOCKS, BlockStatistics, block_side, block_statistics, tiles
from darksynth.tensors import luminance

BLOCK = 4
"""Side of the square blocks whose per-channel medians make the tone distribution."""

PROBABILITIES: tuple[float, ...] = tuple(round(0.02 * i, 2) for i in range(1, 50))
"""The quantile levels p fitted: 0.02, 0.04, ..., 0.98."""

# The mean over clean training images (cbsd68, mcmaster, mirflickr; kodak24 held out) of log q_clean(p) at
# PROBABILITIES, with q the quantile of the 4x4 block medians of all channels, floored at 0.5 / 255. Made by
#   .venv/bin/python scripts/evaluate_darkening.py prior
# fmt: off
TONE_PRIOR_LOG_QUANTILES: tuple[float, ...] = (
    -3.3185, -2.9568, -2.6828, -2.5049, -2.3703, -2.2531, -2.1380, -2.0347,
    -1.9551, -1.8802, -1.8114, -1.7466, -1.6835, -1.6283, -1.5735, -1.5127,
    -1.4624, -1.4171, -1.3714, -1.3221, -1.2757, -1.2354, -1.1860, -1.1461,
    -1.1000, -1.0498, -1.0008, -0.9601, -0.9207, -0.8777, -0.8350, -0.7859,
    -0.7479, -0.7115, -0.6769, -0.6442, -0.6123, -0.5823, -0.5531, -0.5231,
    -0.4921, -0.4611, -0.4297, -0.3957, -0.3599, -0.3229, -0.2812, -0.2273,
    -0.1567,
)
# fmt: on

# The standard deviation across the same images of log q_clean(p): how far one scene's tone departs from the
# average; it weighs each quantile in the fit (the dark end of the distribution varies most between scenes).
# fmt: off
TONE_PRIOR_LOG_SPREAD: tuple[float, ...] = (
    1.4142, 1.3006, 1.1834, 1.1267, 1.0926, 1.0656, 1.0071, 0.9605,
    0.9503, 0.9382, 0.9254, 0.9118, 0.8933, 0.8866, 0.8754, 0.8390,
    0.8262, 0.8218, 0.8145, 0.7770, 0.7585, 0.7496, 0.6860, 0.6722,
    0.6152, 0.5549, 0.5173, 0.4919, 0.4631, 0.4405, 0.4062, 0.3835,
    0.3634, 0.3446, 0.3286, 0.3138, 0.3012, 0.2882, 0.2754, 0.2654,
    0.2554, 0.2457, 0.2350, 0.2236, 0.2123, 0.1986, 0.1834, 0.1650,
    0.1435,
)
# fmt: on

ALPHA_BOUNDS: tuple[float, float] = (0.005, 1.0)
"""Estimates of alpha are clipped into this interval."""

GAMMA_BOUNDS: tuple[float, float] = (0.1, 2.0)
"""Estimates of gamma are clipped into this interval: the paper's [0.1, 1] widened to allow brighter mid-tones."""

NOISE_FLOOR_FACTOR = 3.0
"""A quantile is used only if it exceeds this many standard deviations of the noise left in a block median."""

MIN_LEVEL = 4.0 / 255.0
"""Quantiles below this level are too coarsely rounded in an 8-bit reference to be used."""

MAX_LEVEL = 0.97
"""Quantiles above this level may be saturated; they are left out."""

MIN_LOG_SPAN = 0.05
"""The usable quantiles must span at least this much in log (5%): a flat grey reference tells no tone curve."""

MIN_QUANTILES = 6
"""Fewer usable quantiles than this and the reference is too dark (or too flat) to estimate its darkening."""

EFFECTIVE_QUANTILES = 3.0
"""The tone quantiles of a scene move together: their content scatter counts as this many independent values
when the fit is weighed against the prior on alpha and gamma."""

_HUBER = 1.345
_MEDIAN_EFFICIENCY = 1.2533  # std of the median of n normal samples is about 1.2533 sigma / sqrt(n)


@dataclass(frozen=True)
class ToneTarget:
    """The reference's exposure, which ``apply`` and ``synthesize`` match each input's darkening to
    (:func:`match_darkening`); a profile's ``tone``.

    Attributes:
        quantiles: the reference's :func:`tone_quantiles` at :data:`PROBABILITIES`.
        noise: the noise in one of its block medians (:func:`median_noise`).
    """

    quantiles: tuple[float, ...]
    noise: float
    colour: tuple[float, float, float] | None = None
    """The reference's colour cast (:func:`colour_cast`), or None (grey, or a profile written before it)."""
    luminance: tuple[float, ...] | None = None
    """The reference's :func:`luminance_quantiles` at :data:`PROBABILITIES`: the tones a viewer sees, noise,
    clipping and 8-bit levels included, which ``apply`` fits each output's to; None in profiles written before
    them (the match then stops at the block medians)."""


LUMINANCE_PIXELS = 1 << 20
"""At most about this many pixels are read for a reference's luminance quantiles (every k-th pixel): a million
values fix its 49 quantiles to far below an 8-bit level at a bounded cost on long 4K clips."""


def luminance_quantiles(frames: torch.Tensor, *, probabilities: tuple[float, ...] = PROBABILITIES) -> np.ndarray:
    """Quantiles of the pixel luminance of frames (..., C, H, W) on the [0, 1] scale, pooled over frames, at
    ``probabilities``: what a viewer sees of the exposure, noise and clipping included (block medians leave both
    out). Read on every k-th pixel past :data:`LUMINANCE_PIXELS`."""
    values = luminance(frames).flatten()
    values = values[:: max(1, values.numel() // LUMINANCE_PIXELS)]
    return np.quantile(values.numpy().astype(np.float64), probabilities)


def colour_cast(frames: torch.Tensor, *, block: int = BLOCK) -> tuple[float, float, float] | None:
    """The colour cast of frames (..., 3, H, W): each channel's share of the light, as the sum of its block medians
    over the mean of the three channels' sums (1, 1, 1 for grey; a sodium-lit street is about 1.4, 0.9, 0.6).

    Block medians, as for the tones, so that noise (symmetric about the level) does not move the cast; sums, so
    that the bright blocks, where the cast is seen, weigh most. None for grey input or frames without light.
    """
    if frames.dim() < 3 or frames.shape[-3] != 3:
        return None
    # On a sample of the blocks of a large frame, as the tones (:func:`sampled_blocks`).
    medians = block_medians(sampled_blocks(frames.to(torch.float32), block=block), block)
    sums = medians.movedim(-3, 0).reshape(3, -1).sum(dim=1).double()
    mean = float(sums.mean())
    if mean <= 0.0:
        return None
    red, green, blue = (float(v) / mean for v in sums)
    return (red, green, blue)


@dataclass(frozen=True)
class DarkeningEstimate:
    """The darkening read from a reference, and how well the tone prior fitted it.

    Attributes:
        darkening: alpha and gamma, clipped to :data:`ALPHA_BOUNDS` and :data:`GAMMA_BOUNDS`.
        quantiles_used: how many of the :data:`PROBABILITIES` lay above the noise floor and below saturation.
        fit_rms: root mean square of the log residuals of the fit (0: the reference has exactly the prior's
            tone distribution, darkened); above about 0.3 the content is far from an average natural image.
        noise_floor: the level below which quantiles were left out, on the [0, 1] scale.
        clipped: alpha or gamma hit a bound.
        bounds_hit: for each of ``alpha`` and ``gamma`` whose fitted value lay outside its search range
            (:data:`ALPHA_BOUNDS`, :data:`GAMMA_BOUNDS`) and was clipped to it, ``"lower"`` or ``"upper"``.
        prior_share: for ``alpha`` and ``gamma``, the share of the estimate's precision that comes from the prior
            on the paper's ranges rather than from the reference's tones, in [0, 1] (0: the tones alone determine
            it; 1: the reference says nothing about it and the value is the paper's mid-range). Empty without
            the prior (``use_prior=False``).
        tone_quantiles: the fitted tone quantiles (at :data:`PROBABILITIES`), which ``apply`` matches each input's
            exposure to (:func:`match_darkening`).
        block_noise: the noise in a block median the fit was given.
    """

    darkening: Darkening
    quantiles_used: int
    fit_rms: float
    noise_floor: float
    clipped: bool
    bounds_hit: dict[str, str] = field(default_factory=dict)
    prior_share: dict[str, float] = field(default_factory=dict)
    tone_quantiles: tuple[float, ...] = ()
    block_noise: float = 0.0

    @property
    def confidence(self) -> float:
        """A score in [0, 1]: the fraction of quantiles used, lowered by a poor fit and by hitting a bound."""
        score = self.quantiles_used / len(PROBABILITIES) / (1.0 + (self.fit_rms / 0.15) ** 2)
        return score * (0.5 if self.clipped else 1.0)


def block_medians(frames: torch.Tensor, block: int = BLOCK) -> torch.Tensor:
    """Per-channel medians of non-overlapping ``block`` x ``block`` tiles.

    Args:
        frames: (..., C, H, W) values on the [0, 1] scale; rows and columns past a multiple of ``block`` are
            dropped.
        block: tile side; smaller frames use their shorter side.

    Returns:
        (..., C, H // block, W // block) medians (the lower middle value of an even count, so an actual pixel
        value: the medians of a darkened frame are exactly the darkened medians).
    """
    if frames.dim() < 3:
        raise ValueError(f"expected frames shaped (..., C, H, W), got shape {tuple(frames.shape)}")
    medians: torch.Tensor = tiles(frames, block).median(dim=-1).values
    return medians


MATCH_BLOCKS = 1 << 14
"""At most about this many blocks of a clean input are read to match its exposure (every k-th block row and
column): its 49 quantiles are as well determined by 16k blocks as by a 1080p frame's 130k (67 ms, against
about 5)."""


def sampled_blocks(frames: torch.Tensor, *, block: int = BLOCK, most: int = MATCH_BLOCKS) -> torch.Tensor:
    """Every k-th block row and column of ``frames`` (..., C, H, W), put side by side, k the smallest that leaves
    at most ``most`` blocks per channel and frame (``frames`` itself for small frames)."""
    rows, columns = frames.shape[-2] // block, frames.shape[-1] // block
    step = max(1, math.ceil(math.sqrt(rows * columns / most)))
    if step == 1:
        return frames
    # The first block of every step x step group of blocks.
    rows, columns = rows // step, columns // step
    grouped = frames[..., : rows * step * block, : columns * step * block].reshape(
        *frames.shape[:-2], rows, step * block, columns, step * block
    )
    return grouped[..., :block, :, :block].reshape(*frames.shape[:-2], rows * block, columns * block)


def sampled_tone_quantiles(frames: torch.Tensor, *, block: int = BLOCK) -> np.ndarray:
    """:func:`tone_quantiles` of :func:`sampled_blocks` of ``frames`` (the same numbers for small frames)."""
    return tone_quantiles(sampled_blocks(frames, block=block), block=block)


def tone_quantiles(
    frames: torch.Tensor, *, block: int = BLOCK, probabilities: tuple[float, ...] = PROBABILITIES
) -> np.ndarray:
    """Quantiles q(p) of the block medians of all channels and frames.

    Args:
        frames: (..., C, H, W) values on the [0, 1] scale.

    Returns:
        (len(probabilities),) float64 array.
    """
    values = block_medians(frames.to(torch.float32), block).flatten().numpy().astype(np.float64)
    # numpy's quantile selects in linear time and has no size limit (torch.quantile stops at 2**24 values).
    return np.quantile(values, probabilities)


def median_noise(frames: torch.Tensor, block: int = BLOCK) -> float:
    """Standard deviation of the noise left in one block median, on the [0, 1] scale.

    The noise of a block is read from its upper half, (75th percentile - median) / 0.6745, which clipping at
    0 leaves intact for any block whose median is above 0; the median over blocks with a non-zero 75th
    percentile keeps texture in a few blocks from weighing. The median of ``block ** 2`` pixels has about
    1.25 / ``block`` of that standard deviation.
    """
    frames = frames.to(torch.float32)
    centre, upper = _block_noise_quantiles(frames, block)
    return _noise_of_quantiles(centre, upper, block_side(frames, block))


def _block_noise_quantiles(frames: torch.Tensor, block: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Median and 75th percentile of every block of float32 frames, in flat order (frame, channel, row, column)."""
    flat = tiles(frames, block).flatten(0, -2)
    # An even subsample of the blocks reads the same median noise at a bounded cost (4K clips have ~25 M).
    flat = flat[:: max(1, flat.shape[0] // NOISE_BLOCKS)]
    centre, upper = torch.quantile(flat, torch.tensor([0.5, 0.75]), dim=-1)
    return centre, upper


def _noise_of_quantiles(centre: torch.Tensor, upper: torch.Tensor, side: int) -> float:
    lit = upper > 0
    if not bool(lit.any()):
        return 0.0
    return float((upper - centre)[lit].median()) / 0.6745 * _MEDIAN_EFFICIENCY / side


def estimate_darkening_pooled_and_per_frame(
    frames: torch.Tensor,
    *,
    block: int = BLOCK,
    source: str = "reference",
    statistics: list[BlockStatistics] | None = None,
) -> tuple[DarkeningEstimate, list[DarkeningEstimate | None]]:
    """:func:`estimate_darkening` of frames (T, C, H, W) pooled, and of each frame alone (None where one is too
    dark or flat), from one sort of each frame's blocks (:func:`~darksynth.light.tone_blocks.block_statistics`; given
    as ``statistics`` when the caller has them) instead of four passes.

    The pooled figures are read from the frames' block statistics concatenated in frame order, the order in which
    :func:`estimate_darkening` reads them: the same numbers, as long as one frame's blocks are few enough to be
    read without subsampling (up to :data:`NOISE_BLOCKS`, past 4K per frame); past that the pooled noise is read
    from every step-th block of the frames' subsamples.

    Raises:
        DarksynthError: the pooled reference is too dark or too flat (see :func:`estimate_darkening`).
    """
    medians, centres, uppers = [], [], []
    per_frame: list[DarkeningEstimate | None] = []
    side = block_side(frames, block)
    if statistics is None:
        statistics = [block_statistics(frame, block) for frame in frames]
    for found in statistics:
        frame_medians = found.medians.flatten().numpy().astype(np.float64)
        centre, upper = found.noise_quantiles()
        medians.append(frame_medians)
        centres.append(centre)
        uppers.append(upper)
        try:
            per_frame.append(
                fit_darkening(
                    np.quantile(frame_medians, PROBABILITIES), _noise_of_quantiles(centre, upper, side), source=source
                )
            )
        except DarksynthError:
            per_frame.append(None)
    centre_all, upper_all = torch.cat(centres), torch.cat(uppers)
    step = max(1, centre_all.shape[0] // NOISE_BLOCKS)
    pooled_noise = _noise_of_quantiles(centre_all[::step], upper_all[::step], side)
    pooled = fit_darkening(np.quantile(np.concatenate(medians), PROBABILITIES), pooled_noise, source=source)
    return pooled, per_frame


def _paper_prior() -> tuple[float, float, float, float]:
    """Mean and standard deviation of log alpha and of 1 / gamma under the paper's uniform ranges."""
    alpha = np.linspace(*ALPHA_RANGE, 10001)
    exponent = 1.0 / np.linspace(*GAMMA_RANGE, 10001)
    return float(np.log(alpha).mean()), float(np.log(alpha).std()), float(exponent.mean()), float(exponent.std())


PAPER_PRIOR: tuple[float, float, float, float] = _paper_prior()
"""(mean, std) of log alpha and (mean, std) of 1 / gamma when drawn from the paper's ranges."""


def _fit_line(
    x: np.ndarray, y: np.ndarray, spread: np.ndarray, *, use_prior: bool, iterations: int = 30
) -> tuple[float, float, tuple[float, float] | None]:
    """Intercept log alpha and slope 1 / gamma of y = a + b x, and the prior's share of each one's precision.

    Each point is weighed by 1 / (b spread)^2 (a scene's log quantile departs from the prior's by about
    ``spread``, scaled by the exponent), Huber-downweighted where its residual is an outlier, and the whole
    data term counts as :data:`EFFECTIVE_QUANTILES` values against the paper's prior on (a, b).

    The prior's share of a parameter is its prior precision times its variance under data and prior together,
    (1 / std^2) * [(D + P)^-1]_ii with D and P the data's and the prior's precision matrices: 1 when the data
    say nothing about it, towards 0 as they determine it (None without the prior).
    """
    mean_a, std_a, mean_b, std_b = PAPER_PRIOR
    huber = np.ones_like(x)
    intercept, slope = mean_a, mean_b
    for _ in range(iterations):
        exponent = max(slope, 1.0)
        weights = huber / (exponent * spread) ** 2 * (EFFECTIVE_QUANTILES / x.size)
        rows = [np.stack([np.ones_like(x), x], axis=1) * np.sqrt(weights)[:, None]]
        targets = [y * np.sqrt(weights)]
        if use_prior:
            rows.append(np.array([[1.0 / std_a, 0.0], [0.0, 1.0 / std_b]]))
            targets.append(np.array([mean_a / std_a, mean_b / std_b]))
        (new_intercept, new_slope), *_ = np.linalg.lstsq(np.concatenate(rows), np.concatenate(targets), rcond=None)
        standardised = (y - new_intercept - new_slope * x) / (max(new_slope, 1.0) * spread)
        ratio = np.abs(standardised) / _HUBER
        huber = np.where(ratio <= 1.0, 1.0, 1.0 / np.maximum(ratio, 1e-12))
        done = abs(new_intercept - intercept) < 1e-6 and abs(new_slope - slope) < 1e-6
        intercept, slope = float(new_intercept), float(new_slope)
        if done:
            break
    if not use_prior:
        return intercept, slope, None
    data = rows[0].T @ rows[0]
    prior = np.diag([1.0 / std_a**2, 1.0 / std_b**2])
    covariance = np.linalg.inv(data + prior)
    share_a, share_b = (float(np.clip(prior[i, i] * covariance[i, i], 0.0, 1.0)) for i in range(2))
    return intercept, slope, (share_a, share_b)


def fit_darkening(
    quantiles: np.ndarray,
    noise_floor: float = 0.0,
    *,
    prior: tuple[float, ...] | np.ndarray = TONE_PRIOR_LOG_QUANTILES,
    spread: tuple[float, ...] | np.ndarray = TONE_PRIOR_LOG_SPREAD,
    use_prior: bool = True,
    source: str = "reference",
) -> DarkeningEstimate:
    """Fit alpha and gamma to a reference's tone quantiles (at :data:`PROBABILITIES`) against the prior.

    Args:
        quantiles: the reference's :func:`tone_quantiles`.
        noise_floor: standard deviation of the noise in a block median (:func:`median_noise`).
        prior: mean log quantiles of clean images at the same levels (:data:`TONE_PRIOR_LOG_QUANTILES`).
        spread: their standard deviation across images (:data:`TONE_PRIOR_LOG_SPREAD`).
        use_prior: pull the estimate towards the paper's ranges as far as the data leave it undetermined.
        source: the name error messages start with.

    Raises:
        DarksynthError: fewer than :data:`MIN_QUANTILES` quantiles lie between the floor and saturation
            (an all-black, nearly black or saturated reference), or they span too little of the prior.
    """
    prior = np.asarray(prior, dtype=np.float64)
    quantiles = np.asarray(quantiles, dtype=np.float64)
    if quantiles.shape != prior.shape:
        raise ValueError(f"expected {prior.size} quantiles, got shape {quantiles.shape}")
    floor = max(MIN_LEVEL, NOISE_FLOOR_FACTOR * noise_floor)
    usable = (quantiles > floor) & (quantiles < MAX_LEVEL)
    used = int(usable.sum())
    if used < MIN_QUANTILES:
        raise DarksynthError(
            f"{source}: too dark or too flat to estimate its darkening: {used} of {prior.size} tone quantiles "
            f"lie between the noise floor {floor:.4f} and saturation (at least {MIN_QUANTILES} are needed)"
        )
    x, y = prior[usable], np.log(quantiles[usable])
    if np.ptp(y) < MIN_LOG_SPAN:
        raise DarksynthError(
            f"{source}: too flat to estimate its darkening: its usable tone quantiles span a factor of only "
            f"{math.exp(float(np.ptp(y))):.3f} (at least {math.exp(MIN_LOG_SPAN):.3f} is needed)"
        )
    if np.ptp(x) < 0.2:
        # Usable quantiles that the tones they are fitted against barely tell apart (with match_darkening: a
        # nearly uniform input), so no slope can be read.
        raise DarksynthError(
            f"{source}: its usable tone quantiles ({used}) face tones that span a factor of only "
            f"{math.exp(float(np.ptp(x))):.3f} (at least {math.exp(0.2):.3f} is needed) to fit a darkening to"
        )
    log_alpha, exponent, shares = _fit_line(x, y, np.asarray(spread, dtype=np.float64)[usable], use_prior=use_prior)
    gamma = 1.0 / exponent if exponent > 0 else math.inf
    alpha = math.exp(log_alpha)
    clipped_alpha = min(max(alpha, ALPHA_BOUNDS[0]), ALPHA_BOUNDS[1])
    clipped_gamma = min(max(gamma, GAMMA_BOUNDS[0]), GAMMA_BOUNDS[1])
    clipped = clipped_alpha != alpha or clipped_gamma != gamma
    bounds_hit = {
        name: "lower" if value < low else "upper"
        for name, value, (low, high) in (("alpha", alpha, ALPHA_BOUNDS), ("gamma", gamma, GAMMA_BOUNDS))
        if not low <= value <= high
    }
    # The share belongs to 1 / gamma, which the fit works in; it is the same share for gamma.
    prior_share = {"alpha": shares[0], "gamma": shares[1]} if shares is not None else {}
    residual = y - (math.log(clipped_alpha) + x / clipped_gamma)
    return DarkeningEstimate(
        darkening=Darkening(alpha=clipped_alpha, gamma=clipped_gamma),
        quantiles_used=used,
        fit_rms=float(np.sqrt(np.mean(residual**2))),
        noise_floor=floor,
        clipped=clipped,
        bounds_hit=bounds_hit,
        prior_share=prior_share,
        tone_quantiles=tuple(float(q) for q in quantiles),
        block_noise=float(noise_floor),
    )


def estimate_darkening(
    frames: torch.Tensor,
    *,
    block: int = BLOCK,
    prior: tuple[float, ...] | np.ndarray = TONE_PRIOR_LOG_QUANTILES,
    use_prior: bool = True,
    source: str = "reference",
) -> DarkeningEstimate:
    """Estimate alpha and gamma of a low-light reference.

    Args:
        frames: reference frames (T, C, H, W) or one frame (C, H, W), values on the [0, 1] scale; all frames
            are pooled.
        block: side of the median blocks (the prior was measured with :data:`BLOCK`; keep it).
        prior: mean clean log quantiles measured with the same ``block``.
        use_prior: see :func:`fit_darkening`.
        source: the name error messages start with.

    Returns:
        The estimate; see :class:`DarkeningEstimate` for its confidence.

    Raises:
        DarksynthError: the reference is too dark (all black) or too flat to tell a tone curve.
    """
    if frames.dim() not in (3, 4):
        raise ValueError(f"expected frames shaped (T, C, H, W) or (C, H, W), got shape {tuple(frames.shape)}")
    quantiles = tone_quantiles(frames, block=block)
    return fit_darkening(quantiles, median_noise(frames, block), prior=prior, use_prior=use_prior, source=source)


def estimate_darkening_spread(
    frames: torch.Tensor,
    *,
    regions: int = 2,
    block: int = BLOCK,
    source: str = "reference",
    statistics: list[BlockStatistics] | None = None,
) -> list[DarkeningEstimate]:
    """Estimates on parts of the reference: each frame cut into ``regions`` x ``regions`` tiles.

    The spread of these estimates shows how much the content, rather than the camera, moves the estimate;
    regions too dark to fit are skipped (the list may be empty). ``statistics``: each frame's
    :func:`~darksynth.light.tone_blocks.block_statistics`, which a region on their block grid reads its own from.
    """
    if frames.dim() == 3:
        frames = frames[None]
    height, width = frames.shape[-2], frames.shape[-1]
    rows = np.linspace(0, height, regions + 1).round().astype(int)
    columns = np.linspace(0, width, regions + 1).round().astype(int)
    estimates = []
    for index, frame in enumerate(frames):
        whole = statistics[index] if statistics is not None else block_statistics(frame, block)
        for top, bottom in itertools.pairwise(rows):
            for left, right in itertools.pairwise(columns):
                part = frame[:, top:bottom, left:right]
                if min(part.shape[-2:]) < block:
                    continue
                found = whole.region(top, bottom, left, right) or block_statistics(part, block)
                quantiles = np.quantile(found.medians.flatten().numpy().astype(np.float64), PROBABILITIES)
                try:
                    estimates.append(
                        fit_darkening(
                            quantiles, _noise_of_quantiles(*found.noise_quantiles(), found.side), source=source
                        )
                    )
                except DarksynthError:
                    continue
    return estimates
