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

Codec video (issue 39, part 4). A codec does not make AR(1) noise: it codes one frame whole and the next ones as
changes from it (block-based motion compensation), copies the blocks it finds unchanged bit for bit (skipped
blocks), and phones denoise over time before it. The differences of 4 frames then follow the frame types, not a
coefficient: a fresh frame among copied ones gives the ratio 4/3 (or -4/3 when it comes last), beyond anything AR(1)
noise gives, and the estimate used to call such a video unreadable and take independent frames, the one thing no
compressed night video shows. So:

* a finest octave the ratio cannot read while the lag-one reading can takes the lag-one reading alone, on every
  octave (each still falling to the finer octave where it cannot read): it is the lag-1 correlation whatever the
  process, which is what the codec leaves and what a viewer sees. Its own error, noise fitted too strong, is the
  same as on a clip the ratio reads; a still clip that drifts makes it read low, not high (drift adds to ``D_1``);
* skipped blocks stay in the statistics: their difference is 0, noise that persists fully for that pair of frames,
  a real property of the video that the synthetic should show. ``meta`` gives the share of still blocks the codec
  repeated per pair (``persistence_skipped_share``: 8-px cells, see :data:`SKIP_CELL`). Above
  :data:`SKIPPED_WARNING_SHARE` (a codec's, not chance's) the profile's ``codec_repeat`` is that share, which the
  synthesis copies from frame to frame itself (:mod:`darksynth.noise.codec_repeat`), a one-line warning says so,
  and the coefficient is the coded cells' (the pooled reading with the repeated cells taken out; a reading under
  the share repeated is no noise's, and the coded cells keep that share, see :func:`_coded`). Where more than
  :data:`CODEC_SKIPPED_SHARE` were repeated the lag-one reading stands alone;
* where neither statistic reads the finest octave, the coefficients are the video prior :data:`VIDEO_PRIOR`
  (what this read gives on the shared real night clips), stated in ``meta.persistence_prior`` and the warning, not
  independent frames. A single image keeps 0 (:func:`read_persistence`): a photo's noise is a still camera's, whose
  exposures are independent; it says nothing about a codec.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from darksynth.estimation.findings import Findings
from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK
from darksynth.estimation.noise.resynthesis import FittedReference, MeasuredValues
from darksynth.estimation.noise.spectral_fit import SpectralParameters, quantised, uncensored_signal
from darksynth.estimation.noise.spectral_statistics import band_weights
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

SKIP_CELL = 8
"""Side of the cells whose bit-identical repetition from one frame to the next counts as a codec's skipped block:
the smallest block a codec skips or copies (H.264 partitions its 16-px macroblocks into 8-px ones, HEVC's smallest
coding unit is 8 px). 192 values (8 x 8, 3 channels) unchanged by chance need noise far under one 8-bit level
(each value repeats with probability about 0.4 at half a level: 0.4 ** 192 is nothing), so a repeated cell is a copy,
whatever the image size."""

SKIPPED_WARNING_SHARE = 0.1
"""A share of the still flat cells repeated bit-identically (mean over the pairs of frames) above this is named in a
warning: the compression, not the camera, sets the persistence there. One cell in ten: compression of each frame
alone repeats some cells whose noise is under its quantiser (JPEG quality 80 on 2.5 levels of noise: 6% in the drawn
clip of ``scripts/noise/temporal_harness.py`` case 3), which the model's own compression also does."""

CODEC_SKIPPED_SHARE = 0.5
"""A share of the still flat cells repeated bit-identically (mean over the pairs of frames) above this: most of what
the ratio sees is the codec's choice of which blocks to code afresh, not a process of the noise, and the lag-one
reading (the pooled lag-1 correlation, repeated cells included) stands alone. The shared clip132 (82% repeated) read
0 as the smaller of the two, its real lag-1 1.00."""

VIDEO_PRIOR = (0.55, 0.6, 0.55, 0.4, 0.35, 0.3)
"""The coefficient per octave (2-4 px first) of a video whose persistence cannot be read: the median per octave of
what this read gives on the 12 shared real night clips and video it reads, rounded to 0.05 (``scripts/noise/
spectral_temporal_check.py``, its printed median; docs/spectral-noise.md, "Frame to frame on codec video"). Judged
leave-one-out (each reference's synthetic lag-1 with the median of the others in place of its own coefficients, the
script's ``prior (loo)`` lines): on the 9 read references whose real lag-1 is 0.25-0.64 the gap is -0.11 to +0.35,
median |gap| 0.09, 6 within 0.15 (the two quietest-persisting, clip1021 and clip893 at 0.27 and 0.25, get 0.62 and
0.55); on the clips that read 0.00 in the real it gives 0.50-0.99. Not 0: every compressed night video shows
persistence (the held-out ones 0.69 and 0.92)."""

UNDER_REPEATED = 0.1
"""A pooled lag-one reading this far under the share of still cells a codec repeated is no noise's (see
:func:`_coded`): independent coded cells give the share itself, within sampling error (a few hundredths on the drawn
codec clips of ``tests/estimation/test_persistence_fit.py``)."""

VIDEO_PRIOR_SOURCE = "median of this read on the shared real night clips (docs/spectral-noise.md, 'Frame to frame')"
"""Where :data:`VIDEO_PRIOR` comes from, as ``meta`` and the warning state it."""


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
    weights = band_weights(height, width, frames.device)
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


def _read(target: torch.Tensor, curve: torch.Tensor, *, above_reads_as_top: bool = False) -> _Reading:
    """The coefficients a ``target`` statistic (OCTAVES,) gives on its simulated ``curve`` (grid, OCTAVES), and
    which octaves it can set: those whose statistic moves with the coefficient (:data:`MIN_TEMPORAL_RESPONSE`) and
    whose target lies within :data:`BEYOND_REACH` of what some coefficient gives (else the "still" blocks change in
    a way no noise does: slow motion, light, a codec). With ``above_reads_as_top`` a target above every simulated
    point is read, as the top coefficient: for the lag-one reading it means the still blocks change less than the
    most persistent simulated noise does (a codec that copies them, where JPEG's rounding of each simulated frame
    keeps the simulation's top lower), which is persistence, not a change no noise makes."""
    response = curve.max(dim=0).values - curve[0]
    above = target > curve.max(dim=0).values + BEYOND_REACH
    reachable = (~above | above_reads_as_top) & (target >= curve.min(dim=0).values - BEYOND_REACH)
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


def skipped_shares(frames: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(T - 1,) per pair of consecutive frames (T, 3, H, W) the share of the masked :data:`SKIP_CELL` cells whose
    every value repeats exactly: a codec's skipped blocks. ``mask`` (H, W) in {0, 1}, whole 32-px blocks (so whole
    cells). Frames of 8-bit values compare exactly as floats (the same level gives the same float)."""
    height, width = frames.shape[-2] // SKIP_CELL * SKIP_CELL, frames.shape[-1] // SKIP_CELL * SKIP_CELL
    changed = (frames[1:, :, :height, :width] != frames[:-1, :, :height, :width]).any(dim=1).to(torch.float32)
    changed_cells = F.max_pool2d(changed[:, None], SKIP_CELL)[:, 0]
    inside = F.avg_pool2d(mask[None, None, :height, :width].to(torch.float32), SKIP_CELL)[0, 0] > 0.5
    cells = int(inside.sum())
    if cells == 0:
        return torch.zeros(frames.shape[0] - 1, dtype=torch.float64)
    repeated = ((changed_cells == 0) & inside).sum(dim=(1, 2)).to(torch.float64)
    return repeated / cells


@dataclass(frozen=True)
class PersistenceFit:
    """What :func:`fit_persistence` gives: the coefficient per octave, the record for ``meta`` and the clauses of
    warnings (each a full statement without the reference's name)."""

    coefficient: torch.Tensor
    record: dict[str, object]
    notes: list[str]
    codec_repeat: float = 0.0
    """The share of still cells the synthesis repeats (:mod:`darksynth.noise.codec_repeat`): the share the codec
    repeated, where it is above :data:`SKIPPED_WARNING_SHARE` (a codec's, not chance's), else 0."""


def video_prior_record(source: str) -> dict[str, object]:
    """What ``meta`` says of a clip that takes :data:`VIDEO_PRIOR`: why (``source``), the values and their origin."""
    return {"persistence_source": source, "persistence_prior": f"{list(VIDEO_PRIOR)}: {VIDEO_PRIOR_SOURCE}"}


def _video_prior(record: dict[str, object], reason: str) -> PersistenceFit:
    """The fit of a clip whose finest octave neither statistic reads: :data:`VIDEO_PRIOR`, stated (with the fit's
    ``record`` so far)."""
    record = record | video_prior_record("video prior")
    note = (
        f"the frame-to-frame correlation of the noise cannot be read ({reason}): the video prior "
        f"{VIDEO_PRIOR[0]}-{max(VIDEO_PRIOR)} per octave ({VIDEO_PRIOR_SOURCE})"
    )
    return PersistenceFit(torch.tensor(VIDEO_PRIOR, dtype=torch.float64), record, [note])


def fit_persistence(
    frames: torch.Tensor,
    denoised: torch.Tensor,
    mask: torch.Tensor,
    parameters: SpectralParameters,
    compression: float,
    seed: int,
) -> PersistenceFit:
    """The AR(1) coefficient per octave of the noise of still-block frames (T >= 3, 3, H, W) (see the module)."""
    measured = difference_powers(frames, mask)
    simulate = still_simulator(denoised, mask, parameters, compression, seed)
    simulated = torch.stack([simulate(torch.full((OCTAVES,), r, dtype=torch.float64)) for r in SEARCH_GRID])
    ratio = _read(persistence_statistic(measured), torch.stack([persistence_statistic(p) for p in simulated]))
    independent = simulated[0, 0].clamp_min(1e-30)
    lag_one = _read(1.0 - measured[0] / independent, 1.0 - simulated[:, 0] / independent, above_reads_as_top=True)
    record = _record(ratio, lag_one)
    skipped = skipped_shares(frames, mask)
    repeated = float(skipped.mean())
    record["persistence_skipped_share"] = _rounded(skipped)
    notes = []
    codec_repeat = 0.0
    if repeated > SKIPPED_WARNING_SHARE:
        codec_repeat = round(repeated, 3)
        notes.append(
            f"{repeated:.0%} of the still flat blocks repeat bit-identically from frame to frame (a "
            "codec skipped them, or compression removed their change): the profile repeats that share of still "
            "cells (codec_repeat), and reads the persistence pooled with the blocks that change"
        )
    if bool(ratio.target[0] >= 1.0) and bool(lag_one.target[0] >= 1.0 - BEYOND_REACH):
        # Repeated frames: no simulated noise changes so little, the frames' noise is the same.
        record["persistence_source"] = "frames repeated"
        record["persistence_prior"] = "frames repeated: the noise persists fully"
        return PersistenceFit(torch.full((OCTAVES,), MAX_COEFFICIENT, dtype=torch.float64), record, notes, codec_repeat)
    if bool(ratio.readable[0]) and repeated <= CODEC_SKIPPED_SHARE:
        # Each reading errs upward in its own way (see the module): the persistence is what both see.
        coefficient = torch.minimum(ratio.coefficient, lag_one.coefficient)
        readable = ratio.readable & lag_one.readable
        record["persistence_source"] = "read: the smaller of the ratio and the lag-one reading"
    else:
        # The ratio reads no AR(1) process (a codec's frame types, skipped blocks): the lag-one reading is the lag-1
        # correlation whatever the process.
        coefficient = lag_one.coefficient.clone()
        readable = lag_one.readable
        record["persistence_source"] = (
            "read: the lag-one reading alone (the ratio reads no AR(1) process)"
            if not bool(ratio.readable[0])
            else "read: the lag-one reading alone (a codec repeated most still blocks)"
        )
    if not bool(readable[0]):
        hidden = bool(ratio.response[0] < MIN_TEMPORAL_RESPONSE) and bool(lag_one.response[0] < MIN_TEMPORAL_RESPONSE)
        reason = "its noise hides it" if hidden else "its still blocks change more than noise does"
        prior = _video_prior(record, reason)
        return PersistenceFit(prior.coefficient, prior.record, notes + prior.notes, codec_repeat)
    for octave in range(1, OCTAVES):
        # An octave that cannot be read persists like the finer one next to it.
        if not bool(readable[octave]):
            coefficient[octave] = coefficient[octave - 1]
    return PersistenceFit(_coded(coefficient, codec_repeat), record, notes, codec_repeat)


def _coded(pooled: torch.Tensor, codec_repeat: float) -> torch.Tensor:
    """The coefficient per octave of the cells the codec codes afresh, from the ``pooled`` reading (repeated cells
    included, whose lag-1 is 1): ``pooled = p + (1 - p) r`` for a share ``p`` repeated, which the synthesis repeats
    itself (:mod:`darksynth.noise.codec_repeat`), so the coefficient does not count the repeated cells twice.

    A pooled reading under ``p`` by more than :data:`UNDER_REPEATED` says the coded cells change more than
    independent noise does, which no noise does: their persistence is not read there, and they keep the share
    repeated (a codec that skips most still blocks codes the rest as small changes from the previous frame, which
    keep its noise: the shared clip132, 82% repeated, read 0.57 at 2-4 px and 0.28 coarser, its real lag-1 1.00)."""
    if codec_repeat <= 0.0:
        return pooled
    coded = ((pooled - codec_repeat) / max(1.0 - codec_repeat, 1e-6)).clamp(0.0, MAX_COEFFICIENT)
    unread = pooled < codec_repeat - UNDER_REPEATED
    return torch.where(unread, torch.full_like(coded, min(codec_repeat, MAX_COEFFICIENT)), coded)


def read_persistence(reference: FittedReference, values: Mapping[str, torch.Tensor]) -> MeasuredValues:
    """The reading after the fit of the frame-to-frame correlation per octave (``temporal_correlation``) and the
    share of still cells a codec repeats (``codec_repeat``): read on a clip's still blocks over 3 or more frames
    (:func:`fit_persistence`, in place of the residual's correlation the fit moved; where that cannot be read, the
    video prior with a warning), the fit's own on 2, the video prior for a clip with no still block, 0 for a single
    image; the share repeated is read with the persistence, else 0."""
    resynthesis, name = reference.resynthesis, reference.name
    if reference.still and resynthesis.analysed.shape[0] >= 3:
        persistence = fit_persistence(
            resynthesis.analysed,
            resynthesis.denoised,
            resynthesis.mask,
            reference.fitted,
            reference.compression,
            resynthesis.seed,
        )
        findings = Findings(persistence.record, [f"{name}: {note}" for note in persistence.notes])
        return _persistence_values(persistence.coefficient, persistence.codec_repeat, findings)
    if reference.still:
        return _persistence_values(reference.fitted.temporal, 0.0, Findings())
    if reference.clip:
        # A clip whose blocks all move shows nothing of its noise's persistence; a video's is not independent frames.
        prior = Findings(video_prior_record("video prior: no flat block stays still"))
        return _persistence_values(torch.tensor(VIDEO_PRIOR, dtype=torch.float64), 0.0, prior)
    return _persistence_values(torch.zeros(OCTAVES, dtype=torch.float64), 0.0, Findings())


def _persistence_values(coefficient: torch.Tensor, codec_repeat: float, findings: Findings) -> MeasuredValues:
    values = {
        "temporal_correlation": coefficient.clamp(0.0, MAX_COEFFICIENT),
        "codec_repeat": torch.tensor([codec_repeat], dtype=torch.float64),
    }
    return MeasuredValues(values, findings)
