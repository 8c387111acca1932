"""The spectral model measured on a real reference, blind: octave by octave, per intensity, and in time.

No clean image: the residual of a denoiser, ``y - D(y)``, stands for the noise. Two biases are removed by
indirect inference (the statistics of a simulation on ``D(y)``, denoised again, must equal the reference's):
what the denoiser leaves of the noise (nearly all of the coarse octaves: no denoiser tells a 60-px colour blotch
from the scene) and what it takes of the scene. The steps:

1. An analysis window of the reference (at most :data:`WINDOW` px a side) with the most flat blocks, the same
   in every analysed frame.
2. ``D``: OpenCV's non-local means, its strength from the fine-scale noise of the window's flattest blocks.
3. The flat blocks: the :data:`FLAT_SHARE` of 32x32 blocks of ``D(y)`` with the least gradient energy (texture
   is read as noise elsewhere), for a clip those that also stay still between the frames.
4. The statistics (:func:`~darksynth.estimation.noise.spectral_statistics.measure`): the residual band-passed as a
   whole, then its band cross-powers averaged over the flat blocks (a masked spectrum would leak mid frequencies into
   the coarse bands), the variance per channel and intensity knot, and for a clip the frame-to-frame correlation per
   band.
5. The fit by re-synthesis for each JPEG strength of
   :data:`~darksynth.estimation.noise.spectral_fit.COMPRESSION_CANDIDATES`; the best match is refined further.

A reference that cannot show something gets the prior for it, with a warning: a single image has no temporal
correlation to read (0, independent frames); a clip whose every block moves the same; a reference without flat
blocks is measured on its least textured ones, with a warning that texture may be read as noise.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import torch

from darksynth.estimation.findings import Findings
from darksynth.estimation.noise import readings
from darksynth.estimation.noise.camera_conditional import (
    TEXTURE_NAMES,
    CameraPriorUse,
    prior_first_octave,
    prior_octaves,
)
from darksynth.estimation.noise.coarse_anchor import ANCHOR_WARM_STEPS, COMPONENT_NAMES, CoarseAnchor
from darksynth.estimation.noise.flat_blocks import (
    CLIPPED_SHARE,
    MIN_LEVEL_BLOCKS,
    analysis_window,
    clipped_share,
    denoiser_strength,
    flat_mask,
)
from darksynth.estimation.noise.jpeg_quality import read_compression
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.resynthesis import FittedReference, Resynthesis
from darksynth.estimation.noise.spectral_fit import (
    COMPRESSION_CANDIDATES,
    SpectralParameters,
    continue_octaves,
    fill_knots_along,
    fit_by_resynthesis,
    initial_parameters,
    mismatch,
)
from darksynth.estimation.noise.spectral_statistics import SpectralStatistics, measure
from darksynth.estimation.noise.spectrum_checks import (
    fitted_noise_8bit,
    level_checks,
    mean_level,
    readability_warnings,
)
from darksynth.estimation.noise.still_blocks import still_flat_mask
from darksynth.noise.spectral import OCTAVES

TEXTURED_GRADIENT = 4.0 / 255
"""A reference whose flat blocks still have a mean gradient magnitude of the denoised image above this (in the
[0, 1] scale per pixel) is textured all over: the estimate warns that texture may be read as noise."""

TEMPORAL_FRAMES = 4
"""Consecutive frames a clip is analysed on for the frame-to-frame correlation."""

START_ITERATIONS, FINAL_ITERATIONS = 2, 3
"""Corrections with each JPEG candidate (one draw), then with the best one (two draws)."""

CANDIDATE_RULED_OUT = 4.0
"""A JPEG strength whose first simulation's mismatch is this many times the best strength's is not fitted further:
its correction cannot close such a gap (a JPEG stage that is not there, or one that is, shows in every band).
Each strength fitted cost a sixth of a photo's estimate."""

PROBED_OCTAVES = range(2, OCTAVES)
"""Octaves whose visibility is probed (11 px and coarser); the two finest are always in the denoiser's residual."""

PROBE_BOOST = 4.0
"""Factor by which a probe raises one octave's power over white noise."""

KNOT_PROBE_BOOST = 1 / 1.5
"""Factor by which the probe of :func:`knot_responses` moves the level curve: down, since noise raised above the
denoiser's strength stops raising the residual (a flat grey reference read a response of 0.26 probed upward)."""

MIN_RESPONSE = 0.35
"""An octave is measured when its band's statistic follows its power with at least this exponent (1: in
proportion; 0: not at all). Below it the band holds mostly other octaves' leakage and the scene, a fit would
read noise of its own sampling error (on a 384-px LOL reference the 90-px octave came out 1000x the others')."""


@dataclass
class SpectrumEstimate:
    """The spectral parameters by name (with ``compression``), and what the measurement says about itself."""

    values: dict[str, torch.Tensor]
    meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


COLOUR_COMPONENTS = slice(1, 3)
"""The two colour components of the statistics' brightness-colour basis (the first is brightness)."""


def octave_responses(
    simulate_and_measure: Callable[[SpectralParameters, int], SpectralStatistics],
    start: SpectralParameters,
    *,
    octaves: range = PROBED_OCTAVES,
    components: slice = slice(None),
    white: bool = True,
) -> torch.Tensor:
    """How much each octave's band statistic follows that octave's power on this reference: white noise at the
    level of ``start`` (or, not ``white``, its own spectrum), then each probed octave's power times
    :data:`PROBE_BOOST`, through the same simulation; the exponent ``log(band ratio) / log(boost)`` per octave (1
    for the unprobed ones), the band's power summed over ``components`` (all three by default)."""
    identity = torch.eye(3, dtype=torch.float64).expand(OCTAVES, 3, 3)
    spectrum = identity if white else start.covariances
    base_parameters = SpectralParameters(covariances=spectrum.clone(), curve=start.curve, temporal=start.temporal)
    base = simulate_and_measure(base_parameters, 0).cross_power.diagonal(dim1=-2, dim2=-1)[..., components].sum(-1)
    responses = torch.ones(OCTAVES, dtype=torch.float64)
    for octave in octaves:
        covariances = spectrum.clone()
        covariances[octave] = covariances[octave] * PROBE_BOOST
        boosted = SpectralParameters(covariances=covariances, curve=start.curve, temporal=start.temporal)
        power = simulate_and_measure(boosted, 0).cross_power.diagonal(dim1=-2, dim2=-1)[..., components].sum(-1)
        responses[octave] = torch.log(power[octave] / base[octave].clamp_min(1e-30)) / math.log(PROBE_BOOST)
    return responses


def colour_through_compression(
    resynthesis: Resynthesis, fitted: SpectralParameters, compression: float
) -> tuple[int, dict[str, Any]]:
    """How many colour octaves, from the finest, still move the reference's statistics through its JPEG stage, and
    the responses for ``meta``; all of them without one.

    The octaves are probed without the JPEG stage (:func:`_first_unmeasured_octave`), before its strength is chosen.
    A 4:2:0 JPEG rounds away colour noise a few levels strong, so through it the colour statistics may follow none
    of the colour octaves' power: the fit's colour there is what the search left, not what the reference shows
    (polyu's quality-75 files, docs/spectral-noise.md). Probed about the fitted spectrum (how far the JPEG rounds
    depends on how strong the colour is), from the 5.7-px octave on (the 2.8-px one is never probed: the denoiser's
    residual holds it whole)."""
    if compression <= 0.0:
        return OCTAVES, {}
    probed = range(1, OCTAVES)
    simulate = resynthesis.simulator(compression, 1)
    responses = octave_responses(simulate, fitted, octaves=probed, components=COLOUR_COMPONENTS, white=False)
    read = next((k for k in probed if responses[k] < MIN_RESPONSE), OCTAVES)
    meta: dict[str, Any] = {"colour_response_through_compression": [round(float(r), 3) for r in responses]}
    if read < OCTAVES:
        meta["colour_prior"] = (
            f"colour octaves {read + 1}-{OCTAVES} (wavelengths from {2 ** (read + 1.5):.0f} px) barely move this "
            f"reference's statistics through its JPEG stage (strength {compression:g}): not read, their values "
            "are the fit's"
        )
    return read, meta


def knot_responses(
    simulate_and_measure: Callable[[SpectralParameters, int], SpectralStatistics], start: SpectralParameters
) -> torch.Tensor:
    """How much each level knot's variance statistic follows that knot's noise on this reference: the start's
    curve, then the curve times :data:`KNOT_PROBE_BOOST`, through the same simulation; the exponent of the
    variance ratio over the factor's square per channel and knot (C, 8): 1 in proportion, nan where unmeasured. A
    knot whose pixels are mostly clipped, or where the denoiser returned the noise, reads the same whatever the
    noise: its statistic cannot set it."""
    base = simulate_and_measure(start, 0).knot_variance
    boosted = SpectralParameters(
        covariances=start.covariances, curve=start.curve * KNOT_PROBE_BOOST, temporal=start.temporal
    )
    raised = simulate_and_measure(boosted, 0).knot_variance
    return (raised / base.clamp_min(1e-30)).log() / (2.0 * math.log(KNOT_PROBE_BOOST))


def estimate_spectrum(
    reference: torch.Tensor,
    *,
    seed: int = 0,
    name: str = "reference",
    prior_curve: torch.Tensor | None = None,
    camera_prior: CameraPriorUse | None = None,
) -> SpectrumEstimate:
    """The spectral model's parameters measured on reference frames (T, 3, H, W) in [0, 1] (see the module).

    Args:
        prior_curve: (3, 8) noise std per channel at the level knots from another source (the network): the knots
            the reference cannot show (no unclipped flat block at that intensity) follow its shape through the
            measured ones, and it stands alone when no block is unclipped.
        camera_prior: supplies what one reference cannot show (:mod:`darksynth.estimation.noise.camera_conditional`);
            without it the coarse octaves continue the finer ones.

    Returns:
        The parameters (``level_curve``, ``octave_power``, ``octave_correlation``, ``temporal_correlation``,
        ``compression``) and a record of the measurement for the profile's ``meta``, with warnings.
    """
    reference = reference.to(torch.float32)
    clip = reference.shape[0] >= 2
    frames = reference[:TEMPORAL_FRAMES] if clip else reference[:1]
    top, left, height, width = analysis_window(frames[0])
    frames = frames[..., top : top + height, left : left + width]
    strength = denoiser_strength(frames)
    denoised = nlm_denoise(frames, strength)
    unclipped = clipped_share(frames) <= CLIPPED_SHARE
    mask, flat_gradient = flat_mask(denoised[0], unclipped)
    findings = Findings(
        {
            "method": "blind spectral measurement (docs/spectral-noise.md): non-local-means residual on the flat "
            "unclipped blocks of each intensity, band-passed per octave, corrected by re-synthesis on the denoised "
            "reference",
            "window": [top, left, height, width],
            "frames": int(frames.shape[0]),
            "denoiser_strength_8bit": round(strength, 3),
            "flat_block_gradient_8bit": round(flat_gradient * 255, 3),
            "unclipped_blocks": f"{int(unclipped.sum())} of {unclipped.numel()}",
        }
    )
    if flat_gradient > TEXTURED_GRADIENT:
        findings.warnings.append(
            f"{name}: no flat region (its flattest blocks still have a gradient of {flat_gradient * 255:.1f} 8-bit "
            "levels per pixel): fine texture may be read as noise, the level may be too high"
        )
    resynthesis, analysed = _analysed(frames, denoised, mask, strength, seed, name)
    findings.include(analysed)
    target = measure(resynthesis.analysed - resynthesis.denoised, resynthesis.denoised, resynthesis.mask)
    fitted, measured_knots, fit = _fit(resynthesis, target, prior_curve, camera_prior)
    findings.include(fit)
    findings.warnings += readability_warnings(fit.meta, fitted.curve, measured_knots, name)
    enough_blocks = int(unclipped.sum()) >= MIN_LEVEL_BLOCKS
    fitted.curve, level = level_checks(fitted.curve, measured_knots, prior_curve, enough_blocks, name)
    findings.include(level)
    findings.meta["strength_over_fitted_noise"] = round(
        strength / fitted_noise_8bit(fitted.curve, denoised[0], mask), 3
    )
    compression, still = fit.meta["compression_chosen"], target.temporal is not None
    fitted_reference = FittedReference(resynthesis, fitted, compression, still, clip, name, camera_prior)
    after = readings.read_after_fit(fitted_reference)
    findings.include(after.findings)
    return SpectrumEstimate(values=after.values, meta=findings.meta, warnings=findings.warnings)


def _analysed(
    frames: torch.Tensor, denoised: torch.Tensor, mask: torch.Tensor, strength: float, seed: int, name: str
) -> tuple[Resynthesis, Findings]:
    """What the fit reads: a clip's frames on the flat blocks that stay still through them (moving pixels carry the
    scene's change, not the noise's persistence), else the first frame on its flat blocks."""
    if frames.shape[0] == 1:
        single = Findings(
            {"temporal_prior": "single image: frame-to-frame correlation of the noise not measurable; prior 0"}
        )
        return Resynthesis(frames, denoised, mask, strength, seed), single
    still_mask, findings = still_flat_mask(frames, denoised, mask, strength, seed, name)
    if still_mask is None:
        return Resynthesis(frames[:1], denoised[:1], mask, strength, seed), findings
    return Resynthesis(frames, denoised, still_mask, strength, seed), findings


def _first_unmeasured_octave(resynthesis: Resynthesis, start: SpectralParameters) -> tuple[int, dict[str, Any]]:
    """The finest octave the reference cannot show (:data:`OCTAVES` when it shows them all), probed on its first
    frame, with the responses and the prior's note for ``meta``."""
    responses = octave_responses(resynthesis.simulator(0.0, 1), start)
    first_unmeasured = next((k for k in PROBED_OCTAVES if responses[k] < MIN_RESPONSE), OCTAVES)
    meta: dict[str, Any] = {"octave_response": [round(float(r), 3) for r in responses]}
    if first_unmeasured < OCTAVES:
        meta["octave_prior"] = (
            f"octaves {first_unmeasured + 1}-{OCTAVES} (wavelengths from {2 ** (first_unmeasured + 1.5):.0f} px) "
            "barely move this reference's statistics: they continue the finer octaves' spectrum"
        )
    return first_unmeasured, meta


def anchor_outcome(
    anchor: CoarseAnchor, anchored: bool, first_unmeasured: int, colour_limit: int = OCTAVES
) -> tuple[list[int], dict[str, Any]]:
    """The colour components released to the prior (:meth:`CoarseAnchor.unmatched`) and what ``meta`` says of the
    anchor: their scales before the release (one at a bound warns), an anchor that read nothing, the octaves read
    (colour no further than ``colour_limit``, :func:`colour_through_compression`)."""
    unmatched = anchor.unmatched() if anchored else []
    meta: dict[str, Any] = {}
    if unmatched:
        meta["coarse_octave_prior"] = {COMPONENT_NAMES[k]: round(float(anchor.scale[k]), 3) for k in unmatched}
        anchor.release(unmatched)
    meta["coarse_octave_scale"] = [round(float(v), 3) for v in anchor.scale]
    if anchored and not anchor.observed:
        meta["coarse_anchor"] = "not read: no simulation left a colour statistic to match; the prior stands"
    colour_read = anchored and anchor.observed and not unmatched
    meta["read_octaves"] = read_octaves(first_unmeasured, colour_anchored=colour_read, colour_limit=colour_limit)
    return unmatched, meta


def read_octaves(first_unmeasured: int, *, colour_anchored: bool, colour_limit: int = OCTAVES) -> dict[str, int]:
    """How many octaves of the spectral model, from the finest, the reference's own statistics set, per component
    (``brightness``, ``colour``); the coarser ones are the prior (the finer octaves' spectrum continued). Brightness
    is read up to the first octave the probe finds the reference cannot show; colour one octave further where the
    coarse anchor read that one (its scale carries on to the coarser octaves, with the finer ones' shape), and no
    further than ``colour_limit`` (the first colour octave the reference's JPEG stage leaves unread)."""
    colour = first_unmeasured + 1 if colour_anchored else first_unmeasured
    return {"brightness": min(first_unmeasured, OCTAVES), "colour": min(colour, colour_limit, OCTAVES)}


def _anchored_fit(
    resynthesis: Resynthesis,
    target: SpectralStatistics,
    start: SpectralParameters,
    compression: float,
    anchor: CoarseAnchor | None,
    constrain: Callable[[SpectralParameters], SpectralParameters],
) -> tuple[SpectralParameters, float]:
    """The last fit, on all analysed frames with the chosen JPEG ``compression``; with an ``anchor``, each step also
    simulates about its planes, so that ``constrain`` moves the coarse colour octaves with the rest. Returns the
    parameters and what was left over (:func:`~darksynth.estimation.noise.spectral_fit.fit_by_resynthesis`)."""
    simulate = resynthesis.simulator(compression)

    def simulate_with_anchor(parameters: SpectralParameters, draw: int) -> SpectralStatistics:
        if draw == 0 and anchor is not None:
            anchor.observe(parameters, compression, resynthesis.seed)
        return simulate(parameters, draw)

    if anchor is not None:
        # The anchor alone first (no denoiser in its simulation: cheap), so that the fit starts near its scale; a
        # colour mottle 50x white needs more steps than the fit makes.
        for _ in range(ANCHOR_WARM_STEPS):
            anchor.observe(start, compression, resynthesis.seed)
            start = constrain(start)
    # Two draws of one frame, or one draw of a clip's frames (which hold as many pixels again).
    draws = 2 if resynthesis.analysed.shape[0] == 1 else 1
    return fit_by_resynthesis(
        target, simulate_with_anchor, start=start, iterations=FINAL_ITERATIONS, draws=draws, constrain=constrain
    )


def _compression_search(
    resynthesis: Resynthesis,
    target: SpectralStatistics,
    start: SpectralParameters,
    constrain: Callable[[SpectralParameters], SpectralParameters],
    candidates: tuple[float, ...],
) -> tuple[dict[float, SpectralParameters], dict[float, float]]:
    """Each JPEG strength of ``candidates`` fitted on the first frame from ``start``, with what each left over; a
    strength whose first simulation matches the target :data:`CANDIDATE_RULED_OUT` times worse than the best one's
    is not fitted further (its score is that first mismatch)."""
    start = constrain(start)
    first = {c: resynthesis.simulator(c, 1)(start, 0) for c in candidates}
    first_mismatch = {c: mismatch(target, statistics) for c, statistics in first.items()}
    best = min(first_mismatch.values())
    fits: dict[float, SpectralParameters] = {}
    scores: dict[float, float] = {}
    for compression in candidates:
        if first_mismatch[compression] > CANDIDATE_RULED_OUT * best:
            fits[compression], scores[compression] = start, first_mismatch[compression]
            continue
        fits[compression], scores[compression] = fit_by_resynthesis(
            target,
            resynthesis.simulator(compression, 1),
            start=start,
            iterations=START_ITERATIONS,
            draws=1,
            constrain=constrain,
            first=first[compression],
        )
    return fits, scores


def _prior_note(camera_prior: CameraPriorUse, first_prior: int) -> dict[str, Any]:
    """What ``meta`` says the camera prior supplied: the octaves (1-based, as the notes count them), the texture
    dependence when the prior holds it, and the sets of real pairs it was fitted on."""
    supplied = []
    if camera_prior.octaves and first_prior < OCTAVES:
        supplied.append(f"octaves {first_prior + 1}-{OCTAVES} (wavelengths from {2 ** (first_prior + 1.5):.0f} px)")
    if all(name in camera_prior.prior.names for name in TEXTURE_NAMES):
        supplied.append("texture dependence")
    return {
        "first_octave": first_prior + 1,
        "supplied": supplied,
        "sets": list(camera_prior.prior.sets),
        "note": "what one reference cannot show, from the prior over real cameras given the level curve and the "
        "finer octaves (docs/camera-prior.md)",
    }


def _fit(
    resynthesis: Resynthesis,
    target: SpectralStatistics,
    prior_curve: torch.Tensor | None,
    camera_prior: CameraPriorUse | None,
) -> tuple[SpectralParameters, torch.Tensor, Findings]:
    """The fit by re-synthesis on the denoised frames: the octaves the reference shows probed, each JPEG strength
    fitted on the first frame, the knots probed at the best, which is fitted further on all analysed frames with the
    coarse colour anchored. Returns the fit, the knots (C, 8) the target measures and the probe finds responsive (the
    caller checks the level against them), and the choices and what was left over."""
    analysed, denoised = resynthesis.analysed, resynthesis.denoised
    measured_knots = ~torch.isnan(target.knot_variance).expand(3, -1)  # narrowed by the probe, read by the constraint

    def constrain_curve(parameters: SpectralParameters) -> SpectralParameters:
        if prior_curve is not None:
            parameters.curve = fill_knots_along(parameters.curve, measured_knots, prior_curve)
        return parameters

    start = constrain_curve(initial_parameters(target))
    # The probes and the search over JPEG strengths are spatial: a clip's first frame is enough for them (a 16-frame
    # 1080p clip took 20 s with every analysed frame in every simulation); the last fit reads all of them.
    spatial_target = (
        target if analysed.shape[0] == 1 else measure(analysed[:1] - denoised[:1], denoised[:1], resynthesis.mask)
    )
    first_unmeasured, meta = _first_unmeasured_octave(resynthesis, start)
    anchor = CoarseAnchor.read(analysed[0], denoised[0], resynthesis.mask, first_unmeasured)
    anchored = first_unmeasured < OCTAVES and anchor.readable
    if camera_prior is not None:
        first_prior = prior_first_octave(first_unmeasured)
        meta["camera_prior"] = _prior_note(camera_prior, first_prior)

    def constrain(parameters: SpectralParameters) -> SpectralParameters:
        if camera_prior is not None and camera_prior.octaves:
            parameters = prior_octaves(parameters, first_prior, camera_prior.prior)
        else:
            parameters = continue_octaves(parameters, first_unmeasured)
        anchor.update()
        if first_unmeasured < OCTAVES:
            parameters.covariances = anchor.apply(parameters.covariances, first_unmeasured)
        return constrain_curve(parameters)

    lattice_read, meta["jpeg_lattice"] = read_compression(analysed[0], COMPRESSION_CANDIDATES)
    candidates = COMPRESSION_CANDIDATES if lattice_read is None else (lattice_read,)
    fits, scores = _compression_search(resynthesis, spatial_target, start, constrain, candidates)
    chosen = min(scores, key=lambda c: scores[c])
    # A knot's response is probed where the fit has brought the level: at the raw residual's level (too weak on
    # textured references) texture dominates every knot's statistic and none would seem to respond.
    responses_per_knot = knot_responses(resynthesis.simulator(chosen, 1), fits[chosen])
    unresponsive = ~(responses_per_knot >= MIN_RESPONSE)
    meta["knot_response"] = [[round(float(r), 2) for r in row] for row in responses_per_knot.nan_to_num(0.0)]
    measured_knots &= ~unresponsive
    target = dataclasses.replace(target, knot_variance=target.knot_variance.masked_fill(unresponsive, math.nan))
    fitted, left_over = _anchored_fit(
        resynthesis, target, fits[chosen], chosen, anchor if anchored else None, constrain
    )
    colour_read, through = colour_through_compression(resynthesis, fits[chosen], chosen)
    unmatched, outcome = anchor_outcome(anchor, anchored, first_unmeasured, colour_read)
    if unmatched:
        fitted = constrain(fitted)  # the released components continue the finer octaves again
    meta |= outcome | through
    meta["compression_scores"] = {str(c): round(v, 4) for c, v in scores.items()}
    meta["level_by_compression_8bit"] = {str(c): round(mean_level(fits[c].curve, measured_knots), 3) for c in fits}
    meta["compression_chosen"] = chosen
    meta["mismatch"] = round(left_over, 4)
    return fitted, measured_knots, Findings(meta)
