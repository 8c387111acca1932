"""An input's darkening matched to the reference's exposure: the profile's tone target against the input's own
tones (issue 25; docs/darkening-estimate.md). ``apply`` and ``convert`` take it for each image, clip and video,
from its first frame, unless ``--alpha/--gamma`` or ``--no-darken`` fix the darkening."""

from __future__ import annotations

import logging

import numpy as np
import torch

from darksynth.darkening import Darkening
from darksynth.errors import DarksynthError
from darksynth.profile import Profile
from darksynth.tones import match_darkening

logger = logging.getLogger(__name__)


def matched_darkening(frame: torch.Tensor, profile: Profile, *, source: str = "input") -> Darkening | None:
    """The darkening that gives ``frame`` (C, H, W), a clip's first frame (uint8, uint16 or float in [0, 1]), the
    reference's tones: alpha and gamma fitted between the profile's :class:`~darksynth.profile.ToneTarget` and the
    frame's own tone quantiles (:func:`darksynth.tones.match_darkening`), to be held over the clip's frames. None
    without a tone target (an older profile) or where the match fails (a nearly uniform frame; logged, and the
    caller keeps the profile's darkening)."""
    if profile.tone is None:
        return None
    clean = frame.to(torch.float32).cpu()
    if not frame.dtype.is_floating_point:
        clean = clean / (255.0 if frame.dtype == torch.uint8 else 65535.0)
    if clean.shape[0] == 1:
        clean = clean.expand(3, -1, -1)
    try:
        found = match_darkening(np.asarray(profile.tone.quantiles), profile.tone.noise, clean[:3], source=source)
    except DarksynthError as error:
        logger.warning("%s; the profile's darkening is used", error)
        return None
    return found.darkening
