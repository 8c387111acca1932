"""Measuring the spectral model's statistics on noise, and fitting its parameters by re-synthesis.

Pure functions on tensors; the clean-aided fit (:func:`oracle_spectral_fit`) and the blind estimate
(:mod:`darksynth.estimation.spectrum`) share them. The statistics of a noise map (or of a residual, noisy minus
denoised) are:

* per octave band (:data:`BANDS`, finest first) the 3x3 cross-power of its brightness and colour components
  (:data:`darksynth.noise.spectral.OPPONENT_BASIS`), relative to white noise of unit variance: the whole map
  is band-passed first (an ideal radial filter on its FFT), then the products are averaged over the pixels of a
  mask (all pixels, or the flat blocks of a reference), so texture outside the mask cannot leak into a band;
* per channel and level-curve knot (:data:`darksynth.noise.spectral.LEVEL_KNOTS`) the variance of the map's
  frequencies in the bands, weighted by the hat function of the knot at the pixel's intensity (the clean or
  denoised image's);
* for clips, per band the correlation of each frame's band with the next frame's.

The fit moves the parameters until a simulation measured through the same operator shows the measured
statistics (indirect inference): each octave's covariance by the matrix that maps the simulated band
cross-power onto the measured one, each knot's std by the ratio of the stds, each octave's AR(1) coefficient
by the gap of the correlations.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

from darksynth.noise.spectral import (
    LEVEL_KNOTS,
    OCTAVE_FREQUENCIES,
    OCTAVES,
    OPPONENT_BASIS,
    covariance_parameters,
    octave_covariances,
)

BANDS: tuple[tuple[float, float], ...] = (
    (1 / 4, 0.71),
    (1 / 8, 1 / 4),
    (1 / 16, 1 / 8),
    (1 / 32, 1 / 16),
    (1 / 64, 1 / 32),
    (1 / 128, 1 / 64),
)
"""Radial frequency bands in cycles/px, finest first, one per octave of the model: [1/4, 0.71), [1/8, 1/4), ...,
[1/128, 1/64). The first five are the bands of the evaluation's band measure."""

COMPRESSION_CANDIDATES: tuple[float, ...] = (0.0, 0.2, 0.4)
"""JPEG strengths a fit tries for the model's output stage: none, quality 80, quality 60. JPEG's 4:2:0 chroma takes
the fine colour out of noise, including the 8-bit rounding's, which no spectrum added before rounding can do."""

MIN_KNOT_WEIGHT = 200.0
"""A knot whose hat weights sum to less than this (pixels) is not measured; it takes its neighbour's value."""


@dataclass(frozen=True)
class SpectralStatistics:
    """What :func:`measure` reads from a noise map.

    Attributes:
        cross_power: (OCTAVES, 3, 3) band cross-power in the colour basis, relative to white unit variance.
        knot_variance: (C, 8) variance per channel and knot (nan where the knot is not measured).
        temporal: (OCTAVES,) frame-to-frame correlation per band; None for a single frame.
    """

    cross_power: torch.Tensor
    knot_variance: torch.Tensor
    temporal: torch.Tensor | None


@functools.lru_cache(maxsize=4)
def band_masks(height: int, width: int, device: torch.device) -> torch.Tensor:
    """(len(BANDS), H, W // 2 + 1) float64, 1 where a frequency of an ``rfft2`` of an (H, W) map falls in a band.
    Cached: a fit measures dozens of maps of one size (the tensor is only read, never written)."""
    fy = torch.fft.fftfreq(height, dtype=torch.float64, device=device)
    fx = torch.fft.rfftfreq(width, dtype=torch.float64, device=device)
    radius = torch.sqrt(fy[:, None] ** 2 + fx[None, :] ** 2)
    return torch.stack([((radius >= low) & (radius < high)).to(torch.float64) for low, high in BANDS])


def band_fields(noise: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The band-passed colour components of noise maps (..., 3, H, W) (or grey (..., 1, H, W)):
    (..., OCTAVES, K, H, W) float64, K = 3 (or 1), each component minus its mean, and each band's share of the
    frequency square (OCTAVES,), by which a white field's band power is that share of its variance."""
    noise = noise.to(torch.float64)
    channels = noise.shape[-3]
    components = torch.einsum("ij,...jhw->...ihw", OPPONENT_BASIS.to(noise.device), noise) if channels == 3 else noise
    components = components - components.mean(dim=(-2, -1), keepdim=True)
    height, width = noise.shape[-2:]
    masks = band_masks(height, width, noise.device)
    spectrum = torch.fft.rfft2(components)
    fields = torch.stack([torch.fft.irfft2(spectrum * mask, s=(height, width)) for mask in masks], dim=-4)
    weights = torch.full(masks.shape[-2:], 2.0, dtype=torch.float64, device=noise.device)
    weights[:, 0] = 1.0
    if width % 2 == 0:
        weights[:, -1] = 1.0
    share = (masks * weights).sum(dim=(-2, -1)) / float(height * width)
    return fields, share


def measure_weight(
    frames: int, height: int, width: int, mask: torch.Tensor | None, device: torch.device
) -> torch.Tensor:
    """The pixel weights (T, H, W) float64 :func:`measure` averages with: ``mask`` on every frame, or all ones."""
    weight = torch.ones(frames, height, width, dtype=torch.float64, device=device)
    return weight if mask is None else weight * mask.to(weight)


def measure(
    noise: torch.Tensor,
    intensity: torch.Tensor,
    mask: torch.Tensor | None = None,
    *,
    binning: KnotBinning | None = None,
) -> SpectralStatistics:
    """The statistics of noise maps ``noise`` (T, C, H, W) (a clip, or one frame with T = 1) whose pixels have the
    clean or denoised intensity ``intensity`` (T, C, H, W); ``mask`` (H, W) or (T, H, W) in {0, 1} selects the
    pixels averaged over (all when None). ``binning``: :func:`knot_binning` of ``intensity`` and the mask's
    :func:`measure_weight`, when a caller measures many noise maps on the same intensity (a fit)."""
    frames, channels, height, width = noise.shape
    weight = measure_weight(frames, height, width, mask, noise.device)
    total = weight.sum().clamp_min(1.0)
    fields, share = band_fields(noise)  # (T, OCTAVES, K, H, W)
    # Per band, the weighted sum of the components' products over every pixel of every frame, as one batched
    # matrix product (an einsum over the five-axis arrays took twice as long).
    flat = fields.permute(1, 2, 0, 3, 4).reshape(fields.shape[1], fields.shape[2], -1)  # (OCTAVES, K, T * H * W)
    summed = torch.bmm(flat * weight.reshape(1, 1, -1), flat.transpose(1, 2))
    cross_power = summed / total / share.clamp_min(1e-12)[:, None, None]
    temporal = None
    if frames > 1:
        pair_weight = weight[:-1] * weight[1:]
        lagged = (fields[:-1] * fields[1:] * pair_weight[:, None, None]).sum(dim=(0, 2, 3, 4))
        # Each band's weighted energy is the trace of its summed products.
        energy = summed.diagonal(dim1=-2, dim2=-1).sum(-1) * (pair_weight.sum() / total)
        temporal = lagged / energy.clamp_min(1e-30)
    # The level is read on the same frequencies as the bands (above 1/128 cycles/px): slow drifts between a noisy
    # image and its clean reference (exposure, illumination) are not noise the model could put anywhere.
    banded = fields.sum(dim=1)
    if channels == 3:
        banded = torch.einsum("ji,tjhw->tihw", OPPONENT_BASIS.to(banded.device), banded)
    return SpectralStatistics(cross_power, knot_variances(banded, intensity, weight, binning), temporal)


def knot_pieces(intensity: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The level-curve knot below each intensity of ``intensity`` (...) and the hat weight of the knot above it:
    (index (...) int64 in 0..6, fraction (...) float64 in [0, 1]). The knot below has weight 1 - fraction, every
    other knot 0; the knots (j / 7)^2 lie on the grid of step 1/49, so a value's knot is floor(sqrt(49 x))."""
    knots = torch.tensor(LEVEL_KNOTS, dtype=torch.float64, device=intensity.device)
    x = intensity.to(torch.float64).clamp(0.0, 1.0)
    index = (x * 49.0).sqrt().floor().long().clamp(0, len(LEVEL_KNOTS) - 2)
    low, high = knots[index], knots[index + 1]
    # (A value that sqrt rounds across a knot gets a fraction of 0 or 1 at it: the same weights.)
    return index, ((x - low) / (high - low)).clamp(0.0, 1.0)


@dataclass(frozen=True)
class KnotBinning:
    """Where each pixel of a (T, C, H, W) intensity map adds to the level curve's knots, with the pixel weights:
    built once for a reference's denoised frames and its mask, read by every simulation measured on them.

    Attributes:
        bins: (T * C * H * W,) int64, channel * 8 + the knot below each value.
        below, above: (T * C * H * W,) float64, the pixel's weight times the hat of the knot below and above.
        mass: (C, 8) float64, each knot's summed weights.
    """

    bins: torch.Tensor
    below: torch.Tensor
    above: torch.Tensor
    mass: torch.Tensor


def knot_binning(intensity: torch.Tensor, weight: torch.Tensor) -> KnotBinning:
    """The :class:`KnotBinning` of ``intensity`` (T, C, H, W) with pixel weights ``weight`` (T, H, W)."""
    channels, knots = intensity.shape[1], len(LEVEL_KNOTS)
    index, fraction = knot_pieces(intensity)
    pixel_weight = weight[:, None].to(torch.float64).expand_as(fraction)
    # Each pixel adds to two knots (its piece's ends): sums per (channel, knot) by counting into C * 8 bins.
    bins = (index + torch.arange(channels, device=index.device).reshape(1, -1, 1, 1) * knots).flatten()
    below, above = (pixel_weight * (1.0 - fraction)).flatten(), (pixel_weight * fraction).flatten()
    size = channels * knots
    mass = torch.bincount(bins, below, minlength=size) + torch.bincount(bins + 1, above, minlength=size)
    return KnotBinning(bins, below, above, mass.reshape(channels, knots))


def knot_variances(
    noise: torch.Tensor, intensity: torch.Tensor, weight: torch.Tensor, binning: KnotBinning | None = None
) -> torch.Tensor:
    """(C, 8) hat-weighted variance of ``noise`` (T, C, H, W) per channel and knot of ``intensity``; pixels weighted
    by ``weight`` (T, H, W); nan where a knot's weights sum to less than :data:`MIN_KNOT_WEIGHT`. ``binning``: the
    :func:`knot_binning` of ``intensity`` and ``weight``, when already built."""
    if binning is None:
        binning = knot_binning(intensity, weight)
    size = binning.mass.numel()
    centred = noise.to(torch.float64) - noise.to(torch.float64).mean(dim=(0, 2, 3), keepdim=True)
    squares = centred.square().flatten()
    total = torch.bincount(binning.bins, binning.below * squares, minlength=size)
    total += torch.bincount(binning.bins + 1, binning.above * squares, minlength=size)
    mass = binning.mass
    variance = total.reshape(mass.shape) / mass.clamp_min(1e-12)
    return torch.where(mass >= MIN_KNOT_WEIGHT, variance, torch.full_like(variance, math.nan))


def fill_knots(values: torch.Tensor) -> torch.Tensor:
    """Knot values (C, 8) with every nan replaced by its nearest measured knot's value in the same channel (a
    channel with none takes the mean of the others' measured values)."""
    filled = values.clone()
    measured = ~torch.isnan(values)
    fallback = values[measured].mean() if bool(measured.any()) else torch.tensor(0.0, dtype=values.dtype)
    for channel in range(values.shape[0]):
        known = measured[channel].nonzero().flatten()
        if known.numel() == 0:
            filled[channel] = fallback
            continue
        for knot in range(values.shape[1]):
            if not bool(measured[channel, knot]):
                filled[channel, knot] = values[channel, known[(known - knot).abs().argmin()]]
    return filled


def fill_knots_along(curve: torch.Tensor, measured: torch.Tensor, prior: torch.Tensor) -> torch.Tensor:
    """A level curve (C, 8) std whose unmeasured knots (``measured`` False) follow the ``prior`` curve (C, 8),
    scaled to the measured knots: the log ratio of curve to prior is interpolated linearly over the knot index
    between measured knots and held beyond the first and last, so a dark knot without data continues the prior's
    shape through the measured level rather than the darkest knot's value. A channel with no measured knot takes the
    median ratio of the others; with none at all, the prior itself."""
    curve, prior = curve.to(torch.float64), prior.to(curve.device, torch.float64).clamp_min(1e-6)
    log_ratio = (curve.clamp_min(1e-6) / prior).log()
    knots = torch.arange(curve.shape[1], dtype=torch.float64, device=curve.device)
    known_ratios = log_ratio[measured]
    common = known_ratios.median() if known_ratios.numel() else torch.zeros((), dtype=torch.float64)
    filled = curve.clone()
    for channel in range(curve.shape[0]):
        known = measured[channel].nonzero().flatten()
        if known.numel() == 0:
            filled[channel] = prior[channel] * common.exp()
            continue
        x, y = knots[known], log_ratio[channel, known]
        position = torch.searchsorted(x, knots).clamp(1, max(known.numel() - 1, 1))
        if known.numel() == 1:
            interpolated = y.expand_as(knots)
        else:
            low, high = x[position - 1], x[position]
            t = ((knots - low) / (high - low)).clamp(0.0, 1.0)
            interpolated = y[position - 1] + t * (y[position] - y[position - 1])
        filled[channel] = torch.where(measured[channel], curve[channel], prior[channel] * interpolated.exp())
    return filled


def _sqrtm(matrix: torch.Tensor, inverse: bool = False) -> torch.Tensor:
    eigenvalues, eigenvectors = torch.linalg.eigh(0.5 * (matrix + matrix.transpose(-1, -2)))
    floor = 1e-6 * eigenvalues[..., -1:].clamp_min(1e-30)
    root = torch.maximum(eigenvalues, floor).sqrt()
    if inverse:
        root = 1.0 / root
    result: torch.Tensor = eigenvectors @ torch.diag_embed(root) @ eigenvectors.transpose(-1, -2)
    return result


@dataclass
class SpectralParameters:
    """The spectral model's parameters while a fit moves them (the table's form is :class:`NoiseValues`)."""

    covariances: torch.Tensor  # (OCTAVES, 3, 3) colour basis
    curve: torch.Tensor  # (3, 8) std per channel and knot
    temporal: torch.Tensor  # (OCTAVES,)

    def as_values(self) -> dict[str, torch.Tensor]:
        """The table's parameters (``level_curve``, ``octave_power``, ``octave_correlation``,
        ``temporal_correlation``), clipped to their bounds."""
        power, correlation = covariance_parameters(self.covariances)
        scale = power.reshape(OCTAVES, 3).mean()
        return {
            "level_curve": self.curve.reshape(-1).clamp(0.0, 1.0),
            # Only the shape of the spectrum matters (the unit noise is normalised): the mean power is set to 1.
            "octave_power": (power / scale.clamp_min(1e-30)).clamp(1e-6, 1.0e4),
            "octave_correlation": correlation,
            "temporal_correlation": self.temporal.clamp(0.0, 0.99),
        }


def initial_parameters(statistics: SpectralStatistics) -> SpectralParameters:
    """A start for the fit: the measured cross-powers as the octaves' covariances, the measured stds as the
    curve, the measured frame-to-frame correlations (0 for a single frame)."""
    variance = fill_knots(statistics.knot_variance)
    if variance.shape[0] == 1:
        variance = variance.expand(3, -1)
    temporal = statistics.temporal if statistics.temporal is not None else torch.zeros(OCTAVES, dtype=torch.float64)
    return SpectralParameters(
        covariances=statistics.cross_power.clone(),
        curve=variance.clamp_min(0.0).sqrt(),
        temporal=temporal.clamp(0.0, 0.99),
    )


def corrected(
    parameters: SpectralParameters, target: SpectralStatistics, simulated: SpectralStatistics
) -> SpectralParameters:
    """One step of the fit: each octave's covariance by ``T C T^T`` with ``T = P_target^1/2 P_sim^-1/2`` (so the
    simulated band cross-power would become the target's), each knot's std by the ratio of the stds where both
    are measured, each AR(1) coefficient by the gap of the correlations."""
    transform = _sqrtm(target.cross_power) @ _sqrtm(simulated.cross_power, inverse=True)
    channels = target.cross_power.shape[-1]
    covariances = parameters.covariances.clone()
    if channels == 3:
        covariances = transform @ covariances @ transform.transpose(-1, -2)
    else:
        covariances[:, 0, 0] = covariances[:, 0, 0] * transform[:, 0, 0].square()
    ratio = (target.knot_variance / simulated.knot_variance.clamp_min(1e-30)).sqrt()
    if ratio.shape[0] == 1:
        ratio = ratio.expand(3, -1)
    # Knots measured in one map only keep their value; a ratio is bounded so a noisy knot cannot run away.
    ratio = torch.where(torch.isnan(ratio), torch.ones_like(ratio), ratio.clamp(0.25, 4.0))
    temporal = parameters.temporal
    if target.temporal is not None and simulated.temporal is not None:
        temporal = (temporal + (target.temporal - simulated.temporal)).clamp(0.0, 0.99)
    return SpectralParameters(covariances=covariances, curve=parameters.curve * ratio, temporal=temporal)


def average(statistics: list[SpectralStatistics]) -> SpectralStatistics:
    """The mean of the statistics of several simulations (knots measured in all of them)."""
    temporal = None
    if statistics[0].temporal is not None:
        temporal = torch.stack([s.temporal for s in statistics if s.temporal is not None]).mean(0)
    return SpectralStatistics(
        torch.stack([s.cross_power for s in statistics]).mean(0),
        torch.stack([s.knot_variance for s in statistics]).mean(0),
        temporal,
    )


def mismatch(target: SpectralStatistics, simulated: SpectralStatistics) -> float:
    """Mean squared log ratio of the simulated to the target band powers (each component's) and knot variances:
    0 for a perfect match."""
    ratios = [
        (simulated.cross_power.diagonal(dim1=-2, dim2=-1) / target.cross_power.diagonal(dim1=-2, dim2=-1)).flatten(),
        (simulated.knot_variance / target.knot_variance).flatten(),
    ]
    logs = torch.cat(ratios).clamp_min(1e-12).log()
    return float(logs[torch.isfinite(logs)].square().mean())


def fit_by_resynthesis(
    target: SpectralStatistics,
    simulate_and_measure: Callable[[SpectralParameters, int], SpectralStatistics],
    *,
    start: SpectralParameters | None = None,
    iterations: int = 4,
    draws: int = 2,
    constrain: Callable[[SpectralParameters], SpectralParameters] | None = None,
    first: SpectralStatistics | None = None,
) -> tuple[SpectralParameters, float]:
    """Indirect inference: from ``start`` (the measurement itself by default), ``iterations`` corrections, each
    from the mean statistics of ``draws`` simulations (``simulate_and_measure(parameters, seed)``). Returns the
    parameters and the :func:`mismatch` of the simulations of the last step (before its correction).
    ``constrain`` is applied to the start and after every correction (a prior holding what the statistics
    cannot move, e.g. :func:`continue_octaves`). ``first``: the first step's mean statistics, when the caller has
    simulated them already (the constrained start, the same draws)."""
    parameters = start if start is not None else initial_parameters(target)
    if constrain is not None:
        parameters = constrain(parameters)
    left = math.inf
    for step in range(iterations):
        # The same draws at every step (common random numbers): the step is then a fixed map, which converges,
        # rather than chasing the sampling error of a new draw each time.
        if step == 0 and first is not None:
            simulated = first
        else:
            simulated = average([simulate_and_measure(parameters, d) for d in range(draws)])
        left = mismatch(target, simulated)
        parameters = corrected(parameters, target, simulated)
        if constrain is not None:
            parameters = constrain(parameters)
    return parameters, left


def continue_octaves(parameters: SpectralParameters, first_unmeasured: int) -> SpectralParameters:
    """The prior for octaves a reference cannot show: from ``first_unmeasured`` on (coarser), the colour
    components' power relative to white continues the last two measured octaves' roll-off, the brightness power,
    the correlations and the frame-to-frame correlation are those of the last measured octave (statistics that do
    not respond to an octave are not read: a band that holds mostly the still scene's leakage reads as noise
    persisting fully from frame to frame).

    The colour roll-off is that of white noise through a Gaussian low-pass, ``P(f) = A exp(-(f / f0)^2)``:
    cameras low-pass their colour noise (chroma denoising, 4:2:0 chroma, demosaicing), which is what leaves real
    sRGB noise with coarse colour mottle. ``f0`` is set per colour component by the last two measured octaves'
    powers; toward coarse scales the power rises at most by the cube root of their ratio over the last measured
    octave (the limit as f goes to 0, the octaves being a factor 2 apart), and where the measured power falls
    toward coarse scales the last value is held (a low-pass cannot make that). Brightness, which cameras filter
    far less, is held flat. On the real pairs (validation only; ``darksynth evaluate``, docs/spectral-noise.md) the
    coarse colour bands (16-32, 32-64 px) went from 0.97 / 0.86 to 1.10 / 1.09 of the real on SIDD and from 0.45 /
    0.33 to 0.72 / 0.53 on nam-cc15, the nam-cc15 FID from 76.0 to 63.7; held flat, brightness stays closer than
    with the same roll-off (1.28 / 1.26 against 1.37 / 1.27 on SIDD, 1.05 / 0.92 against 1.47 / 1.17 on
    nam-cc15)."""
    last = first_unmeasured - 1
    if first_unmeasured >= OCTAVES or last < 1:
        return parameters
    covariances = parameters.covariances.clone()
    power = covariances[last].diagonal().clamp_min(1e-30)
    previous = covariances[last - 1].diagonal().clamp_min(1e-30)
    frequency = torch.tensor(OCTAVE_FREQUENCIES, dtype=torch.float64, device=covariances.device)
    # 1 / f0^2 per component from the last two octaves, 0 (flat) where the power does not rise toward coarse scales,
    # and 0 for brightness, which cameras filter far less than colour.
    inverse_width = (power / previous).log().clamp_min(0.0) / (frequency[last - 1] ** 2 - frequency[last] ** 2)
    inverse_width[0] = 0.0
    std = power.sqrt()
    correlation = covariances[last] / (std[:, None] * std[None, :])
    for octave in range(first_unmeasured, OCTAVES):
        grown = power * torch.exp((frequency[last] ** 2 - frequency[octave] ** 2) * inverse_width)
        grown_std = grown.sqrt()
        covariances[octave] = correlation * grown_std[:, None] * grown_std[None, :]
    temporal = parameters.temporal.clone()
    temporal[first_unmeasured:] = temporal[last]
    return SpectralParameters(covariances=covariances, curve=parameters.curve, temporal=temporal)


def spectral_covariances_of(values: dict[str, torch.Tensor]) -> torch.Tensor:
    """(OCTAVES, 3, 3) covariances of the table's ``octave_power`` and ``octave_correlation``."""
    return octave_covariances(values["octave_power"], values["octave_correlation"])


_CENSORED_T = torch.linspace(-4.0, 8.0, 2401, dtype=torch.float64)
_CENSORED_MEAN = _CENSORED_T * 0.5 * torch.erfc(-_CENSORED_T / math.sqrt(2.0)) + torch.exp(
    -0.5 * _CENSORED_T.square()
) / math.sqrt(2.0 * math.pi)
"""E[max(0, t + z)] for z ~ N(0, 1) on a grid of t: the mean of unit noise about t cut off at 0."""


def _uncensor_low(observed: torch.Tensor, std: torch.Tensor) -> torch.Tensor:
    ratio = (observed / std.clamp_min(1e-6)).to(torch.float64)
    table, grid = _CENSORED_MEAN.to(ratio.device), _CENSORED_T.to(ratio.device)
    # Past the table's end clipping no longer moves the mean (t is the ratio itself): only the pixels within reach
    # of the cut are searched, which in the cut at full scale of a dark frame is next to none.
    censored = ratio < float(table[-1])
    t = ratio.clone()
    near = ratio[censored]
    index = torch.searchsorted(table, near.clamp_min(float(table[0]))).clamp(1, len(grid) - 1)
    fraction = (near - table[index - 1]) / (table[index] - table[index - 1])
    # Below the table's start the signal is 4 std under 0.
    t[censored] = grid[index - 1] + fraction.clamp(0.0, 1.0) * (grid[index] - grid[index - 1])
    return (t * std.to(torch.float64)).to(observed.dtype)


def uncensored_signal(observed: torch.Tensor, std: torch.Tensor) -> torch.Tensor:
    """The signal ``mu`` whose noise of std ``std``, clipped to [0, 1] as a camera writes it, has the local mean
    ``observed`` (a denoised frame): ``E[clip(mu + std z)] = observed``, per pixel, solved for the cut at 0 and at
    full scale (each where the other does not reach). A denoiser returns the clipped mean, which lies above the
    signal in crushed shadows; a simulation on it clips less than the camera did and reads its noise as weaker.
    Where ``observed`` is at or below 0, the signal is taken 4 std under it (the clipped mean no longer tells)."""
    low = _uncensor_low(observed, std)
    return 1.0 - _uncensor_low(1.0 - low, std)


def quantised(image: torch.Tensor) -> torch.Tensor:
    """An image on 8-bit levels, as a camera writes it and as the real maps are measured."""
    return (image.clamp(0.0, 1.0) * 255.0).round() / 255.0


def oracle_spectral_fit(
    noisy: torch.Tensor,
    clean: torch.Tensor,
    *,
    iterations: int = 4,
    draws: int = 2,
    seed: int = 0,
    compressions: tuple[float, ...] = COMPRESSION_CANDIDATES,
) -> dict[str, torch.Tensor]:
    """The spectral model's parameters fitted with the clean image: the statistics of ``noisy - clean`` reproduced
    by simulations on ``clean`` through the one composer.

    Args:
        noisy, clean: (C, H, W) images or (T, C, H, W) clips on the [0, 1] scale (8-bit levels).
        iterations, draws: see :func:`fit_by_resynthesis`.
        seed: the simulations' seeds start here.
        compressions: the JPEG stage's strengths tried (the model's output stage): each is fitted, the one whose
            last simulations match best (:func:`mismatch`) is kept and returned as ``compression``.

    Returns:
        The table's spectral parameters by name (for :meth:`NoiseValues.from_values`).
    """
    from darksynth.noise.simulate import add_noise
    from darksynth.noise.values import NoiseValues

    if clean.dim() == 3:
        noisy, clean = noisy[None], clean[None]
    target = measure(noisy - clean, clean)

    best: tuple[float, dict[str, torch.Tensor]] | None = None
    for compression in compressions:

        def simulate_and_measure(
            parameters: SpectralParameters, draw: int, strength: float = compression
        ) -> SpectralStatistics:
            values = NoiseValues.from_values(parameters.as_values() | {"compression": strength}, dtype=torch.float32)
            generator = torch.Generator(device=clean.device).manual_seed(seed * 1009 + draw)
            synthetic = quantised(add_noise(clean.to(torch.float32)[None], values, generator=generator)[0])
            return measure(synthetic - clean, clean)

        fitted, left = fit_by_resynthesis(target, simulate_and_measure, iterations=iterations, draws=draws)
        if best is None or left < best[0]:
            best = (left, fitted.as_values() | {"compression": torch.tensor([compression], dtype=torch.float64)})
    assert best is not None
    return best[1]
