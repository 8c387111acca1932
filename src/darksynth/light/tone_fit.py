"""The darkening x_d = alpha * x ** (1 / gamma) fitted between two tone distributions: a real low-light
reference's against the prior of clean scenes (``estimate``), or against one clean input (``apply`` matching the
reference's exposure).

The reference's content is unknown; only its intensity distribution is seen. Against a prior, the average tone
distribution of clean natural images, the darkening is a straight line in log-log coordinates::

    log q_ref(p) = log alpha + (1 / gamma) * log q_clean(p)

where q(p) is the quantile function of the pooled R, G and B values (:mod:`darksynth.light.tones`, over the medians
of small blocks). Because darkening acts on each value through the same increasing function, it maps quantiles to
quantiles exactly. Quantiles still too close to the noise or to 8-bit rounding, and those near saturation, are left
out; the line is fitted by a Huber-weighted least-squares regression.

See docs/darkening-estimate.md for the measured accuracy and scripts/light/evaluate_darkening.py for the commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from darksynth.errors import DarksynthError
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening
from darksynth.light.tones import PROBABILITIES

# The mean over clean training images (cbsd68, mcmaster, mirflickr; kodak24 held out) of log q_clean(p) at
# PROBABILITIES, with q the quantile of the 4x4 block medians of all channels, floored at 0.5 / 255. Made by
#   .venv/bin/python scripts/light/evaluate_darkening.py prior
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


@dataclass(frozen=True)
class DarkeningEstimate:
    """The darkening read from a reference, and how well the tone prior fitted it.

    Attributes:
        darkening: alpha and gamma, clipped to :data:`ALPHA_BOUNDS` and :data:`GAMMA_BOUNDS`.
        quantiles_used: how many of the :data:`~darksynth.light.tones.PROBABILITIES` lay above the noise floor and
            below saturation.
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
        tone_quantiles: the fitted tone quantiles (at :data:`~darksynth.light.tones.PROBABILITIES`), which
            ``apply`` matches each input's exposure to (:func:`~darksynth.exposure.match_darkening`).
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


def _usable_quantiles(prior: np.ndarray, quantiles: np.ndarray, floor: float, source: str) -> np.ndarray:
    """The tone quantiles a darkening can be fitted on (above ``floor``, below saturation), checked to be enough of
    them, spread enough in level and facing tones of the prior spread enough to read a slope.

    Raises:
        DarksynthError: too few quantiles, or too little spread in them or in the tones they face.
    """
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
    return usable


def fit_darkening(
    quantiles: np.ndarray,
    noise_floor: float = 0.0,
    *,
    prior: tuple[float, ...] | np.ndarray = TONE_PRIOR_LOG_QUANTILES,
    spread: tuple[float, ...] | np.ndarray = TONE_PRIOR_LOG_SPREAD,
    use_prior: bool = True,
    source: str = "reference",
) -> DarkeningEstimate:
    """Fit alpha and gamma to a reference's tone quantiles (at :data:`~darksynth.light.tones.PROBABILITIES`)
    against the prior.

    Args:
        quantiles: the reference's :func:`~darksynth.light.tones.tone_quantiles`.
        noise_floor: standard deviation of the noise in a block median (:func:`~darksynth.light.tones.median_noise`).
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
    usable = _usable_quantiles(prior, quantiles, floor, source)
    used = int(usable.sum())
    x, y = prior[usable], np.log(quantiles[usable])
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
