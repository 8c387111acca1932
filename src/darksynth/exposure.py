"""An input's darkening matched to the reference's exposure: the profile's tone target against the input's own
tones (docs/darkening-estimate.md). ``apply``, ``convert`` and ``synthesize`` (the training transforms)
take it for each image, clip and video, from its first frame, unless the darkening is given (``--alpha/--gamma``,
``--no-darken``, a ``darkening`` argument)."""

from __future__ import annotations

import logging
import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.light.darkening import Darkening, darken
from darksynth.light.tone_fit import ALPHA_BOUNDS, GAMMA_BOUNDS, DarkeningEstimate, fit_darkening
from darksynth.light.tones import PROBABILITIES, TONE_BLOCK, ToneTarget, colour_cast, sampled_tone_quantiles
from darksynth.noise.level import channel_noise_std
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues
from darksynth.tensors import LUMINANCE_WEIGHTS, unit_float

logger = logging.getLogger(__name__)


def match_darkening(
    reference_quantiles: np.ndarray,
    reference_noise: float,
    clean: torch.Tensor,
    *,
    block: int = TONE_BLOCK,
    source: str = "reference",
) -> DarkeningEstimate:
    """Alpha and gamma that darken ``clean`` to the tones of a reference: the fit of
    :func:`darksynth.light.tone_fit.fit_darkening` with the clean input's own log tone quantiles (every block, or every
    k-th of a large frame: :func:`darksynth.light.tones.sampled_tone_quantiles`) in place of the prior of average
    scenes (and no pull to the paper's ranges), so the darkened input's block-median quantiles follow the
    reference's. The exposure is then "as dark as the reference" for this input, which one (alpha, gamma) read off
    the reference against average scenes is not (with that one, the luminance quantiles of ``apply``'s output lay
    0.137 from the reference's, median).

    Args:
        reference_quantiles: the reference's :func:`darksynth.light.tones.tone_quantiles` at its ``PROBABILITIES``.
        reference_noise: the noise in the reference's block medians (:func:`darksynth.light.tones.median_noise`).
        clean: the clean input (..., C, H, W) in [0, 1] (a clip's first frame is enough).
        block: as for :func:`darksynth.light.tones.tone_quantiles`.
        source: the name error messages start with.

    Raises:
        DarksynthError: as :func:`darksynth.light.tone_fit.fit_darkening`: the reference is too dark or too flat to
            match.
    """
    clean_quantiles = sampled_tone_quantiles(clean, block=block)
    # Black input quantiles have no logarithm: floored, as the prior's were, at half an 8-bit level.
    log_clean = np.log(np.maximum(clean_quantiles, 0.5 / 255.0))
    return fit_darkening(
        reference_quantiles,
        reference_noise,
        prior=log_clean,
        spread=np.ones_like(log_clean),
        use_prior=False,
        source=source,
    )


def matched_darkening(
    frame: torch.Tensor,
    tone: ToneTarget | None,
    *,
    noise: NoiseValues | None = None,
    source: str = "input",
) -> Darkening | None:
    """The darkening that gives ``frame`` (C, H, W), a clip's first frame (uint8, uint16 or float in [0, 1]), the
    reference's tones, to be held over the clip's frames: alpha and gamma fitted between a profile's ``tone`` and
    the frame's own block-median tone quantiles (:func:`match_darkening`), then, where the tone target has the
    reference's luminance quantiles, refined so that the output's luminance quantiles, the profile's ``noise``
    added (None: simulated without noise), meet them (:func:`fit_output_darkening`). None without a tone target
    (an older profile) or where no block-median match can be made (a nearly uniform frame; logged, and the caller
    keeps the profile's darkening)."""
    if tone is None:
        return None
    clean = unit_float(frame.cpu())
    if clean.shape[0] == 1:
        clean = clean.expand(3, -1, -1)
    clean = clean[:3]
    try:
        start = match_darkening(np.asarray(tone.quantiles), tone.noise, clean, source=source).darkening
    except DarksynthError as error:
        # Without a block-median match the output fit would start nowhere in particular, and on a frame too flat
        # for one, alpha and gamma trade off freely along its few tones.
        logger.warning("%s; the profile's darkening is used", error)
        return None
    if tone.luminance is None:
        return start
    return fit_output_darkening(np.asarray(tone.luminance), output_model(clean, noise), start)


ColourScale = tuple[float, float, float]
"""Per-channel factors (red, green, blue) on the clean frame, each at most 1."""


def matched_colour(
    frame: torch.Tensor, tone: ToneTarget | None, darkening: Darkening
) -> tuple[ColourScale, Darkening] | None:
    """The reference's colour cast (``tone.colour``) on an input: per-channel gains g on the darkened signal that
    give ``frame`` (C, H, W), darkened by ``darkening``, the reference's channel shares.

    A gain g on the darkened signal alpha * x ** (1 / gamma) is a factor g ** gamma on the clean x. The factors are
    scaled to at most 1 (a clean frame scaled up would clip at white) and alpha takes the rest, so the result is
    the clean frame times the returned scale, darkened by the returned darkening. None without a cast in the tone
    target, for a grey input, or for one without light.
    """
    if tone is None or tone.colour is None or frame.shape[0] != 3:
        return None
    own = colour_cast(darken(unit_float(frame.cpu()), darkening.alpha, darkening.gamma))
    if own is None or min(own) <= 0.0:
        return None
    gains = [target / have for target, have in zip(tone.colour, own, strict=True)]
    factors = [gain**darkening.gamma for gain in gains]
    largest = max(factors)
    scale = (factors[0] / largest, factors[1] / largest, factors[2] / largest)
    adjusted = Darkening(alpha=min(1.0, darkening.alpha * largest ** (1.0 / darkening.gamma)), gamma=darkening.gamma)
    return scale, adjusted


# --- the output's luminance quantiles, simulated on a sample of the input's pixels ----------------------------

MATCH_PIXELS = 1 << 12
"""Pixels of the clean input the output is simulated on per candidate darkening: 4k values place the luminance
quantiles between 4% and 96% within about 1% in probability, and the fit averages 45 of them, at a fraction of a
millisecond per candidate."""

NOISE_FIELD_SHAPE: tuple[int, int] = (64, 64)
"""Height and width of the patch the profile's noise is drawn on once per profile (:data:`MATCH_PIXELS` pixels):
the noise's joint distribution over the channels, which sets the luminance's, is read from it."""

NOISE_FIELD_LEVEL = 0.1
"""The flat level the noise patch is drawn at; the draw is divided by the noise std there, so any level with
noise serves, and a dark one is where low-light outputs lie."""

NOISE_FIELD_SEED = 20_251
"""Seed of the noise patch: a fixed draw, so the same input and profile always give the same darkening and the
caller's generator is left untouched."""

STD_TABLE_STEPS = 28
"""Steps of the table of the noise std, uniform in the square root of the level: it holds every knot of the
spectral level curve ((j / 7)^2) and is densest in the dark, where the noise changes fastest and clipping bites;
each entry costs a pass over the components, so the table is short."""

NOISE_CACHE_SIZE = 8
"""Profiles whose noise draw and std table are kept: ``apply`` matches every file of a run with one profile."""

FIT_PROBABILITY_RANGE: tuple[float, float] = (0.04, 0.96)
"""The luminance quantiles fitted: those that the gap a user measures (5% to 95%) spans, with their neighbours;
the extremes are single lamps and crushed blacks."""

SEARCH_STEPS: tuple[float, float] = (0.2, 0.01)
"""First and last step, in log units, of the search over the darkened median level and gamma: the first moves
the output by about 22%, the block-median match's usual distance from the end; the last by 1% (a tenth of an
8-bit level at the mid-grey of a dark output)."""

BOUND_SEARCH_STEPS: tuple[float, float] = (0.1, 0.01)
"""First and last step, in log alpha and log gamma, of the search along a bound: it starts where the first search
ended, near the answer."""

PIVOT_FLOOR = 0.02
"""The least clean level taken as the pivot of the search (an input whose median is black pivots here)."""


@dataclass(frozen=True)
class OutputNoise:
    """The profile's noise as the simulation of the output reads it.

    Attributes:
        unit: (MATCH_PIXELS, 3) the noise drawn on a flat patch, each channel scaled to zero mean and unit std,
            the channels' correlation kept (it sets the luminance's noise).
        std_table: (STD_TABLE_STEPS + 1, 3) the noise std per channel at the levels (j / STD_TABLE_STEPS)^2.
    """

    unit: np.ndarray
    std_table: np.ndarray


@dataclass(frozen=True)
class OutputModel:
    """What the output's luminance quantiles are simulated from.

    Attributes:
        clean: (N, 3) clean pixel values of the input in [0, 1], N at most :data:`MATCH_PIXELS`.
        noise: the profile's noise.
    """

    clean: np.ndarray
    noise: OutputNoise


def output_noise(noise: NoiseValues | None) -> OutputNoise:
    """The :class:`OutputNoise` of a profile's noise values (None: no noise), drawn once with a fixed seed and
    kept for the next inputs of the same profile."""
    if noise is None:
        return OutputNoise(np.zeros((MATCH_PIXELS, 3)), np.zeros((STD_TABLE_STEPS + 1, 3)))
    # Keyed by the numbers themselves: NoiseValues hold tensors, which do not hash by value.
    key = tuple((name, tuple(tensor.flatten().tolist())) for name, tensor in noise.items())
    with _NOISE_CACHE_LOCK:
        found = _NOISE_CACHE.get(key)
    if found is None:
        found = _draw_output_noise(noise)
        with _NOISE_CACHE_LOCK:
            _NOISE_CACHE[key] = found
            while len(_NOISE_CACHE) > NOISE_CACHE_SIZE:
                _NOISE_CACHE.popitem(last=False)
    return found


_NOISE_CACHE: OrderedDict[tuple[tuple[str, tuple[float, ...]], ...], OutputNoise] = OrderedDict()
_NOISE_CACHE_LOCK = threading.Lock()


def _draw_output_noise(noise: NoiseValues) -> OutputNoise:
    levels = torch.linspace(0.0, 1.0, STD_TABLE_STEPS + 1).square()
    table = channel_noise_std(noise, levels).numpy()
    flat = torch.full((1, 3, *NOISE_FIELD_SHAPE), NOISE_FIELD_LEVEL)
    drawn = noise_sum(flat, noise, generator=torch.Generator().manual_seed(NOISE_FIELD_SEED))
    field = drawn.reshape(3, -1).T.numpy().astype(np.float64)
    spread = field.std(axis=0)
    unit = np.where(spread > 0.0, (field - field.mean(axis=0)) / np.maximum(spread, 1e-12), 0.0)
    return OutputNoise(np.resize(unit, (MATCH_PIXELS, 3)), table)


def output_model(clean: torch.Tensor, noise: NoiseValues | None) -> OutputModel:
    """The :class:`OutputModel` of a clean frame (3, H, W) in [0, 1] and the profile's noise values: every k-th
    pixel of the frame (at most :data:`MATCH_PIXELS`), each paired with one draw of the noise (the two are of
    independent origin, so any pairing serves)."""
    pixels = clean.reshape(3, -1)
    step = max(1, math.ceil(pixels.shape[1] / MATCH_PIXELS))
    sample = pixels[:, ::step].T.numpy().astype(np.float64)
    return OutputModel(sample, output_noise(noise))


def simulated_luminance_quantiles(
    model: OutputModel, darkening: Darkening, probabilities: tuple[float, ...] = PROBABILITIES
) -> np.ndarray:
    """The luminance quantiles of the output ``apply`` would write for the model's pixels and ``darkening``: the
    darkened signal, the noise at its level, clipped to [0, 1] and rounded to 8-bit levels."""
    signal = darkening.alpha * model.clean ** (1.0 / darkening.gamma)
    position = np.sqrt(signal) * STD_TABLE_STEPS
    low = np.minimum(position.astype(np.int64), STD_TABLE_STEPS - 1)
    fraction = position - low
    table = model.noise.std_table
    columns = np.arange(3)
    std = table[low, columns] * (1.0 - fraction) + table[low + 1, columns] * fraction
    unit = model.noise.unit[: signal.shape[0]]
    output = np.round(np.clip(signal + std * unit, 0.0, 1.0) * 255.0) / 255.0
    return sorted_quantiles(np.sort(output @ np.asarray(LUMINANCE_WEIGHTS)), probabilities)


def sorted_quantiles(values: np.ndarray, probabilities: tuple[float, ...]) -> np.ndarray:
    """Quantiles of sorted ``values`` at ``probabilities``, linear between order statistics (numpy's default
    method), without the selection ``np.quantile`` repeats for each probability."""
    position = np.asarray(probabilities) * (values.size - 1)
    low = np.floor(position).astype(np.int64)
    high = np.minimum(low + 1, values.size - 1)
    weight = position - low
    result: np.ndarray = values[low] * (1.0 - weight) + values[high] * weight
    return result


def fit_output_darkening(target: np.ndarray, model: OutputModel, start: Darkening) -> Darkening:
    """The darkening whose simulated output (:func:`simulated_luminance_quantiles`) has luminance quantiles
    nearest the reference's ``target`` (at :data:`PROBABILITIES`) in mean absolute difference over
    :data:`FIT_PROBABILITY_RANGE`, searched from ``start``.

    The output's quantiles are step functions of alpha and gamma (8-bit levels, clipping), so the search is a
    compass search, without derivatives. It moves in log of the darkened level of the input's median pixel and
    log gamma: there gamma turns the tone curve about the median, where alpha and gamma would trade off along
    one valley. Where it ends on a bound of alpha or gamma, a second search moves in log alpha and log gamma,
    where the bound is one coordinate's and the other can move along it.
    """
    low, high = FIT_PROBABILITY_RANGE
    fitted = np.array([low - 1e-9 <= p <= high + 1e-9 for p in PROBABILITIES])
    wanted = np.asarray(target, dtype=np.float64)[fitted]
    chosen = tuple(p for p, keep in zip(PROBABILITIES, fitted, strict=True) if keep)
    pivot = max(float(np.median(model.clean)), PIVOT_FLOOR)

    def pivoted(point: np.ndarray) -> Darkening:
        gamma = float(np.clip(np.exp(point[1]), *GAMMA_BOUNDS))
        return _bounded(np.exp(point[0]) / pivot ** (1.0 / gamma), gamma)

    def gap(darkening: Darkening) -> float:
        return float(np.abs(simulated_luminance_quantiles(model, darkening, chosen) - wanted).mean())

    origin = np.array([np.log(start.alpha) + np.log(pivot) / start.gamma, np.log(start.gamma)])
    found = pivoted(compass_search(lambda point: gap(pivoted(point)), origin, *SEARCH_STEPS))
    if not _on_a_bound(found):
        return found
    point = compass_search(
        lambda point: gap(_bounded(np.exp(point[0]), np.exp(point[1]))),
        np.log([found.alpha, found.gamma]),
        *BOUND_SEARCH_STEPS,
    )
    return _bounded(np.exp(point[0]), np.exp(point[1]))


def _bounded(alpha: float, gamma: float) -> Darkening:
    """alpha and gamma clipped to :data:`darksynth.light.tone_fit.ALPHA_BOUNDS` and ``GAMMA_BOUNDS``."""
    return Darkening(alpha=float(np.clip(alpha, *ALPHA_BOUNDS)), gamma=float(np.clip(gamma, *GAMMA_BOUNDS)))


def _on_a_bound(darkening: Darkening) -> bool:
    # Within rounding: the pivoted coordinates give back a clipped alpha through exp and log.
    return any(
        math.isclose(value, bound, rel_tol=1e-9)
        for value, bounds in ((darkening.alpha, ALPHA_BOUNDS), (darkening.gamma, GAMMA_BOUNDS))
        for bound in bounds
    )


def compass_search(
    objective: Callable[[np.ndarray], float], start: np.ndarray, first_step: float, last_step: float
) -> np.ndarray:
    """The point a compass search reaches from ``start``: move by ``step`` along the first direction that lowers
    ``objective`` (the axes, then the diagonals), halve the step when none does, stop below ``last_step``. Needs
    no derivatives, so it works on objectives with steps (quantiles of rounded values); the diagonals get it along
    a bound that clamps one coordinate (alpha at 1: a brighter curve needs gamma and the level to rise together).
    """
    point, value, step = np.asarray(start, dtype=np.float64), objective(start), first_step
    axes = np.eye(point.size)
    diagonals = [
        axes[i] * a + axes[j] * b
        for i in range(point.size)
        for j in range(i + 1, point.size)
        for a in (1, -1)
        for b in (1, -1)
    ]
    directions = np.concatenate([axes, -axes, np.array(diagonals).reshape(-1, point.size)])
    while step >= last_step:
        for direction in directions:
            candidate = point + step * direction
            candidate_value = objective(candidate)
            if candidate_value < value:
                point, value = candidate, candidate_value
                break
        else:
            step /= 2.0
    return point
