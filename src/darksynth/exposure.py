"""An input's darkening matched to the reference's exposure: the profile's tone target against the input's own
tones (issue 25; docs/darkening-estimate.md). ``apply``, ``convert`` and ``synthesize`` (the training transforms)
take it for each image, clip and video, from its first frame, unless the darkening is given (``--alpha/--gamma``,
``--no-darken``, a ``darkening`` argument)."""

from __future__ import annotations

import logging

import numpy as np
import torch

from darksynth.darkening import Darkening, darken
from darksynth.errors import DarksynthError
from darksynth.tensors import full_scale
from darksynth.tones import (
    BLOCK,
    DarkeningEstimate,
    ToneTarget,
    colour_cast,
    fit_darkening,
    sampled_tone_quantiles,
)

logger = logging.getLogger(__name__)


def match_darkening(
    reference_quantiles: np.ndarray,
    reference_noise: float,
    clean: torch.Tensor,
    *,
    block: int = BLOCK,
    source: str = "reference",
) -> DarkeningEstimate:
    """Alpha and gamma that darken ``clean`` to the tones of a reference: the fit of
    :func:`darksynth.tones.fit_darkening` with the clean input's own log tone quantiles (every block, or every k-th
    of a large frame: :func:`darksynth.tones.sampled_tone_quantiles`) in place of the prior of average scenes (and
    no pull to the paper's ranges), so the darkened input's block-median quantiles follow the reference's. The
    exposure is then "as dark as the reference" for this input, which one (alpha, gamma) read off the reference
    against average scenes is not (issue 25: the luminance quantiles of `apply`'s output were 0.137 from the
    reference's, median).

    Args:
        reference_quantiles: the reference's :func:`darksynth.tones.tone_quantiles` at its ``PROBABILITIES``.
        reference_noise: the noise in the reference's block medians (:func:`darksynth.tones.median_noise`).
        clean: the clean input (..., C, H, W) in [0, 1] (a clip's first frame is enough).
        block: as for :func:`darksynth.tones.tone_quantiles`.
        source: the name error messages start with.

    Raises:
        DarksynthError: as :func:`darksynth.tones.fit_darkening`: the reference is too dark or too flat to match.
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


def matched_darkening(frame: torch.Tensor, tone: ToneTarget | None, *, source: str = "input") -> Darkening | None:
    """The darkening that gives ``frame`` (C, H, W), a clip's first frame (uint8, uint16 or float in [0, 1]), the
    reference's tones: alpha and gamma fitted between a profile's ``tone`` and the frame's own tone quantiles
    (:func:`match_darkening`), to be held over the clip's frames. None without a tone target (an
    older profile) or where the match fails (a nearly uniform frame; logged, and the caller keeps the profile's
    darkening)."""
    if tone is None:
        return None
    clean = _unit_frame(frame)
    if clean.shape[0] == 1:
        clean = clean.expand(3, -1, -1)
    try:
        found = match_darkening(np.asarray(tone.quantiles), tone.noise, clean[:3], source=source)
    except DarksynthError as error:
        logger.warning("%s; the profile's darkening is used", error)
        return None
    return found.darkening


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
    own = colour_cast(darken(_unit_frame(frame), darkening.alpha, darkening.gamma))
    if own is None or min(own) <= 0.0:
        return None
    gains = [target / have for target, have in zip(tone.colour, own, strict=True)]
    factors = [gain**darkening.gamma for gain in gains]
    largest = max(factors)
    scale = (factors[0] / largest, factors[1] / largest, factors[2] / largest)
    adjusted = Darkening(alpha=min(1.0, darkening.alpha * largest ** (1.0 / darkening.gamma)), gamma=darkening.gamma)
    return scale, adjusted


def _unit_frame(frame: torch.Tensor) -> torch.Tensor:
    """A frame (C, H, W) of any pixel type as float32 values in [0, 1], on the CPU."""
    clean = frame.to(torch.float32).cpu()
    scale = full_scale(frame.dtype)
    return clean / scale if scale else clean
