"""Fitting the spectral model's parameters by re-synthesis of its statistics
(:mod:`darksynth.estimation.noise.spectral_statistics`).

Pure functions on tensors; the clean-aided fit (:func:`oracle_spectral_fit`) and the blind estimate
(:mod:`darksynth.estimation.noise.spectrum`) share them. The fit moves the parameters until a simulation measured
through the same operator shows the measured statistics (indirect inference): each octave's covariance by the matrix
that maps the simulated band cross-power onto the measured one, each knot's std by the ratio of the stds, each octave's
AR(1) coefficient by the gap of the correlations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

from darksynth.estimation.noise.spectral_statistics import SpectralStatistics, measure
from darksynth.estimation.noise.texture_fit import (
    TEXTURE_GAINS,
    TextureFit,
    block_power,
    fit_texture,
    interpolated_gain,
    normalised_ratio,
    texture_blocks,
)
from darksynth.noise.simulate import add_noise, apply_output_stages, noise_sum
from darksynth.noise.spectral import (
    OCTAVE_FREQUENCIES,
    OCTAVES,
    covariance_parameters,
    level_std,
)
from darksynth.noise.texture import local_detail
from darksynth.noise.values import NoiseValues

COMPRESSION_CANDIDATES: tuple[float, ...] = (0.0, 0.2, 0.4)
"""JPEG strengths a fit tries for the model's output stage: none, quality 80, quality 60. JPEG's 4:2:0 chroma takes
the fine colour out of noise, including the 8-bit rounding's, which no spectrum added before rounding can do."""


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
        The table's spectral parameters by name (for :meth:`NoiseValues.from_values`), with ``texture_gain`` and
        ``texture_scale`` fitted last (:func:`oracle_texture_fit`) and the level curve brought to flat regions.
    """
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
    values, _ = oracle_texture_fit(noisy, clean, best[1], seed=seed)
    return values


TEXTURE_PASSES = 3
"""Passes of the texture fit: each normalises the blocks by the level curve the previous one brought to flat regions
(the texture-free fit's curve holds texture's noise in the knots where textured pixels lie)."""


def oracle_texture_fit(
    noisy: torch.Tensor, clean: torch.Tensor, values: dict[str, torch.Tensor], *, seed: int = 0
) -> tuple[dict[str, torch.Tensor], TextureFit]:
    """``values`` (a texture-free fit on the clips ``noisy``, ``clean`` (T, C, H, W)) with ``texture_gain`` and
    ``texture_scale`` fitted (:func:`darksynth.estimation.noise.texture_fit.fit_texture`) and the level curve
    divided, knot by knot, by the std the texture adds to it, so that it describes flat regions and the whole map
    keeps its level. :data:`TEXTURE_PASSES` passes, each on the previous one's curve."""
    pooled = values["level_curve"].to(torch.float64)
    curve = pooled
    for _ in range(TEXTURE_PASSES):
        fit, added = _texture_pass(noisy, clean, values | {"level_curve": curve}, seed)
        curve = pooled / added
    texture = {
        "level_curve": curve,
        "texture_gain": torch.tensor([fit.gain], dtype=torch.float64),
        "texture_scale": torch.tensor([fit.scale], dtype=torch.float64),
    }
    return values | texture, fit


def _texture_pass(
    noisy: torch.Tensor, clean: torch.Tensor, values: dict[str, torch.Tensor], seed: int
) -> tuple[TextureFit, torch.Tensor]:
    """One texture fit with the level curve of ``values``: the fit and, per knot (24,), the factor the texture
    puts on the std (1 without texture).

    The simulations are one draw of the texture-free noise times each candidate's factor, clipped and rounded
    (what the composer draws with the same generator); JPEG, slow beside them, is run at gain 0 and at the fit, and
    the ratio it adds divides the real one for the search."""
    clean = clean.to(torch.float32)
    plain = NoiseValues.from_values(values, dtype=torch.float32)
    base = noise_sum(clean[None], plain, generator=torch.Generator(device=clean.device).manual_seed(seed * 1009 + 7))[0]
    blocks = texture_blocks(clean, level_std(clean, plain["level_curve"]))
    detail = local_detail(clean)

    def synthetic(gain: float, scale: float, *, compressed: bool = False) -> torch.Tensor:
        noise = base if gain == 0.0 else base * (1.0 + detail / scale).pow(gain)
        image = (clean + noise).clamp(0.0, 1.0)
        if compressed:
            image = apply_output_stages(image[None], plain)[0]
        return quantised(image) - clean

    def power(gain: float, scale: float) -> torch.Tensor:
        return block_power(synthetic(gain, scale))

    compressed = float(values["compression"].reshape(-1)[0]) > 0.0
    jpeg_factor = 1.0
    if compressed:
        jpeg_factor = normalised_ratio(block_power(synthetic(0.0, 1.0, compressed=True)), blocks) / normalised_ratio(
            power(0.0, 1.0), blocks
        )
    fit = fit_texture(block_power(noisy.to(torch.float32) - clean), blocks, power, correction=jpeg_factor)
    if compressed and fit.gain > 0.0:
        # JPEG's share of the ratio at the fitted gain, where it differs from its share without texture.
        jpeg_factor *= normalised_ratio(block_power(synthetic(fit.gain, fit.scale, compressed=True)), blocks) / (
            fit.simulated_ratio
        )
        ratios = [normalised_ratio(power(gain, fit.scale), blocks) for gain in TEXTURE_GAINS]
        gain = interpolated_gain(fit.real_ratio / jpeg_factor, ratios)
        fit = TextureFit(
            gain, fit.scale, fit.real_ratio, normalised_ratio(power(gain, fit.scale), blocks) * jpeg_factor
        )
    added = torch.ones(24, dtype=torch.float64)
    if fit.gain > 0.0:
        plain_variance = measure(synthetic(0.0, 1.0), clean).knot_variance
        textured_variance = measure(synthetic(fit.gain, fit.scale), clean).knot_variance
        ratio = (textured_variance / plain_variance.clamp_min(1e-30)).sqrt().expand(3, -1).reshape(-1)
        added = torch.where(torch.isfinite(ratio), ratio, torch.ones_like(ratio)).clamp_min(1.0).to(torch.float64)
    return fit, added
