"""The structure of noise, beyond its histogram: spatial frequency bands and persistence over time.

Pure numpy functions, no I/O.

* :func:`band_powers` measures how a noise map's power is spread over five octave bands of spatial frequency,
  separately for its brightness and its colour. White (pixel-independent) noise has the same power in every band;
  the noise of a phone or camera pipeline (demosaicing, denoising, compression) has much more power at coarse
  scales than white noise of the same variance, and more so in colour than in brightness.
* :func:`band_ratios` and :func:`band_summary` compare a method's synthetic noise with the real noise band by band:
  per pair the ratio synthetic / real, per set the median over pairs and one number, the RMS log error.
* :func:`temporal_lag_correlation` measures how much of a clip's fine noise persists from one frame to the next
  (the video counterpart: real low-light phone clips give 0.2-0.9, independent noise per frame about 0).

Bands are always ordered **fine to coarse**: index 0 is the finest band (periods of 1.4 to 4 pixels), index 4 the
coarsest (32 to 64 pixels), as in :data:`BAND_LABELS`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "BANDS",
    "BAND_LABELS",
    "COMPONENTS",
    "band_medians",
    "band_powers",
    "band_ratios",
    "band_summary",
    "gaussian_blur",
    "prior_band_shares",
    "prior_bands",
    "relative_to_white",
    "temporal_lag_correlation",
]

BANDS = ((1 / 4, 0.71), (1 / 8, 1 / 4), (1 / 16, 1 / 8), (1 / 32, 1 / 16), (1 / 64, 1 / 32))
"""Radial spatial frequency bands ``[low, high)`` in cycles per pixel, fine to coarse. 0.71 is above the corner of
the spectrum (sqrt(0.5^2 + 0.5^2) = 0.707), so the finest band holds every frequency from 1/4 up."""

BAND_LABELS = ("1.4-4 px", "4-8 px", "8-16 px", "16-32 px", "32-64 px")
"""The period (1 / frequency) of each band of :data:`BANDS`, in pixels."""

COMPONENTS = ("brightness", "colour")

RESIDUAL_SIGMA = 2.0
"""Gaussian blur (pixels) whose difference to the frame is the fine residual of :func:`temporal_lag_correlation`."""

FLAT_QUANTILE = 0.30
"""Pixels whose blurred mean frame has a gradient magnitude, and a curvature, in this lowest fraction of the frame's
count as flat."""

STATIC_ROBUST_SIGMAS = 3.0
"""A pixel is static between two frames when the change of its blurred value is within this many robust standard
deviations (1.4826 x the median absolute deviation) of the typical change."""

_Array = np.ndarray[Any, np.dtype[np.float64]]


def _rgb_noise(noise: np.ndarray, name: str = "noise") -> _Array:
    array = np.asarray(noise, dtype=np.float64)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError(f"{name} must be an (H, W, 3) RGB array, got shape {array.shape}")
    return array


def brightness_colour_components(noise: _Array) -> tuple[_Array, _Array, _Array]:
    """Brightness (R+G+B)/sqrt3 and the two colour components (R-B)/sqrt2, (R-2G+B)/sqrt6, each zero-mean.

    The three are an orthonormal basis of RGB: white noise of variance v per channel gives each of them variance v.
    """
    red, green, blue = noise[..., 0], noise[..., 1], noise[..., 2]
    brightness = (red + green + blue) / np.sqrt(3.0)
    colour_a = (red - blue) / np.sqrt(2.0)
    colour_b = (red - 2 * green + blue) / np.sqrt(6.0)
    return brightness - brightness.mean(), colour_a - colour_a.mean(), colour_b - colour_b.mean()


def band_index(height: int, width: int) -> np.ndarray[Any, np.dtype[np.intp]]:
    """Per FFT coefficient, its band's index in :data:`BANDS` (0 fine ... 4 coarse), or -1 outside every band."""
    radius = np.hypot(np.fft.fftfreq(height)[:, None], np.fft.fftfreq(width)[None, :])
    index = np.full(radius.shape, -1, dtype=np.intp)
    for band, (low, high) in enumerate(BANDS):
        index[(radius >= low) & (radius < high)] = band
    return index


def _component_band_powers(component: _Array, index: np.ndarray[Any, np.dtype[np.intp]]) -> _Array:
    power = np.abs(np.fft.fft2(component)) ** 2 / component.size
    inside = index >= 0
    sums = np.bincount(index[inside], weights=power[inside], minlength=len(BANDS))
    counts = np.bincount(index[inside], minlength=len(BANDS))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)


def band_powers(noise: np.ndarray) -> dict[str, Any]:
    """Mean power of a noise map's brightness and colour in five bands of spatial frequency.

    Each component (brightness (R+G+B)/sqrt3; colour (R-B)/sqrt2 and (R-2G+B)/sqrt6) loses its mean; its power
    spectrum is P = |FFT2|^2 / pixels and a band's power is the mean of P over the frequencies r = sqrt(fx^2 + fy^2)
    (cycles per pixel, ``np.fft.fftfreq`` on both axes) in that band of :data:`BANDS`. The colour bands are the mean
    of the two colour components'. By Parseval, white noise of variance v per channel has band power v in every band
    of both; noise correlated over a few pixels has more power in the coarse bands and less in the fine ones.

    Args:
        noise: ``(H, W, 3)`` RGB noise map (noisy - clean), [0, 1] scale.

    Returns:
        ``"brightness"`` and ``"colour"`` -> float64 arrays of 5 band powers, **fine to coarse** (see
        :data:`BAND_LABELS`), in squared [0, 1] units, NaN for a band with no frequency (an image of at most 32
        pixels on both sides has none in the coarsest; under 64 it has few there, so that band scatters);
        ``"brightness_variance"`` and ``"colour_variance"`` -> the components' variance (colour: mean of the two),
        the band power of white noise of the same variance.

    Raises:
        ValueError: ``noise`` is not ``(H, W, 3)``.
    """
    array = _rgb_noise(noise)
    brightness, colour_a, colour_b = brightness_colour_components(array)
    index = band_index(*array.shape[:2])
    return {
        "brightness": _component_band_powers(brightness, index),
        "colour": (_component_band_powers(colour_a, index) + _component_band_powers(colour_b, index)) / 2.0,
        "brightness_variance": float(np.mean(brightness**2)),
        "colour_variance": float((np.mean(colour_a**2) + np.mean(colour_b**2)) / 2.0),
    }


def relative_to_white(powers: Mapping[str, Any]) -> dict[str, _Array]:
    """Band powers over those of white noise of the same variance (1 in every band for white noise).

    Args:
        powers: The result of :func:`band_powers`.

    Returns:
        ``"brightness"`` and ``"colour"`` -> 5 ratios, fine to coarse; NaN for a component of zero variance.
    """
    relative = {}
    for component in COMPONENTS:
        variance = float(powers[f"{component}_variance"])
        bands = np.asarray(powers[component], dtype=np.float64)
        relative[component] = bands / variance if variance > 0 else np.full(bands.shape, np.nan)
    return relative


def band_ratios(synthetic: Mapping[str, Any], real: Mapping[str, Any]) -> dict[str, _Array]:
    """Per band, synthetic band power over real band power (1: the right power at that scale).

    Args:
        synthetic, real: Results of :func:`band_powers` for one pair's synthetic and real noise.

    Returns:
        ``"brightness"`` and ``"colour"`` -> 5 ratios, fine to coarse; NaN where the real band power is 0 or NaN.
    """
    ratios = {}
    for component in COMPONENTS:
        numerator = np.asarray(synthetic[component], dtype=np.float64)
        denominator = np.asarray(real[component], dtype=np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratios[component] = np.where(denominator > 0, numerator / denominator, np.nan)
    return ratios


def _median(rows: Sequence[np.ndarray]) -> list[float | None]:
    """Per band, the median of the finite values over the rows; None where no row has one."""
    table = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(BANDS))
    medians: list[float | None] = []
    for column in table.T:
        finite = column[np.isfinite(column)]
        medians.append(float(np.median(finite)) if finite.size else None)
    return medians


def band_medians(rows: Sequence[Mapping[str, Any]]) -> dict[str, list[float | None]]:
    """Per component and band, the median over rows (pairs) of a band quantity; None where no row has a value."""
    return {component: _median([row[component] for row in rows]) for component in COMPONENTS}


def band_summary(ratios: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """A method's band ratios over a set: the median per band, and their RMS log error.

    The RMS log error is ``sqrt(mean over the 10 bands (5 brightness, 5 colour) of ln(median ratio)^2)``: 0 when
    every band has the real power, ln 2 = 0.69 when every band is off by a factor of two either way. Bands without a
    finite positive median are left out of the mean.

    Args:
        ratios: Per pair, the result of :func:`band_ratios`.

    Returns:
        ``"band_ratio"`` -> ``{"brightness": [5], "colour": [5]}`` medians fine to coarse (None: no value), and
        ``"band_rms_log_error"`` -> the RMS log error (None without any usable band); empty without pairs.
    """
    if not ratios:
        return {}
    medians = band_medians(ratios)
    logs = [np.log(v) for c in COMPONENTS for v in medians[c] if v is not None and v > 0 and np.isfinite(v)]
    error = float(np.sqrt(np.mean(np.square(logs)))) if logs else None
    return {"band_ratio": medians, "band_rms_log_error": error}


def prior_bands(read_octaves: Mapping[str, int]) -> dict[str, list[bool]]:
    """Per component, which of :data:`BANDS` an estimate took from its prior rather than read on its reference.

    Band ``k`` is centred on octave ``k`` of the spectral model (its nodes at periods of ``2 ** (k + 1.5)`` px: 2.8,
    5.7, 11, 23, 45; the bands' centres 2.4, 5.7, 11, 23, 45), so a band is the prior's where that octave is.

    Args:
        read_octaves: per component, how many octaves from the finest the reference set (the estimate's
            ``meta.spectrum.read_octaves``).
    """
    return {c: [band >= int(read_octaves[c]) for band in range(len(BANDS))] for c in COMPONENTS if c in read_octaves}


def prior_band_shares(flags: Sequence[Mapping[str, Sequence[bool]]]) -> dict[str, list[float]]:
    """Per component and band, the share of pairs whose estimate took that band from its prior
    (:func:`prior_bands` per pair); empty without pairs."""
    if not flags:
        return {}
    return {
        c: [float(np.mean([bool(row[c][band]) for row in flags if c in row])) for band in range(len(BANDS))]
        for c in COMPONENTS
        if any(c in row for row in flags)
    }


def _gaussian_kernel(sigma: float) -> _Array:
    radius = max(1, int(np.ceil(4.0 * sigma)))
    offsets = np.arange(-radius, radius + 1, dtype=np.float64)
    kernel = np.exp(-0.5 * (offsets / sigma) ** 2)
    return kernel / kernel.sum()  # type: ignore[no-any-return]


def gaussian_blur(image: np.ndarray, sigma: float, axes: tuple[int, int] = (-3, -2)) -> _Array:
    """Separable Gaussian blur over two axes (the image's rows and columns), borders reflected.

    Args:
        image: Any array, e.g. ``(H, W, 3)`` or ``(T, H, W, 3)``.
        sigma: Standard deviation of the Gaussian in pixels, > 0; the kernel reaches 4 sigma.
        axes: The row and column axes.

    Raises:
        ValueError: ``sigma`` is not positive.
    """
    if not sigma > 0:
        raise ValueError(f"blur sigma must be positive pixels, got {sigma}")
    kernel = _gaussian_kernel(sigma)
    radius = len(kernel) // 2
    result = np.asarray(image, dtype=np.float64)
    for axis in axes:
        axis %= result.ndim
        if result.shape[axis] <= radius:
            raise ValueError(f"image of {result.shape[axis]} pixels along axis {axis} is too small to blur by {sigma}")
        pad = [(0, 0)] * result.ndim
        pad[axis] = (radius, radius)
        padded = np.pad(result, pad, mode="reflect")
        length = result.shape[axis]
        blurred = np.zeros_like(result)
        for offset, weight in enumerate(kernel):
            blurred += weight * np.take(padded, np.arange(offset, offset + length), axis=axis)
        result = blurred
    return result


def _gradient_magnitude(image: _Array) -> _Array:
    """Per pixel, the largest gradient magnitude over the channels of an ``(H, W, C)`` image."""
    rows, columns = np.gradient(image, axis=(0, 1))
    return np.sqrt(rows**2 + columns**2).max(axis=-1)  # type: ignore[no-any-return]


def _curvature(image: _Array) -> _Array:
    """Per pixel, the largest absolute Laplacian over the channels of an ``(H, W, C)`` image."""
    rows = np.gradient(np.gradient(image, axis=0), axis=0)
    columns = np.gradient(np.gradient(image, axis=1), axis=1)
    return np.abs(rows + columns).max(axis=-1)  # type: ignore[no-any-return]


def temporal_lag_correlation(frames: np.ndarray, lag: int = 1) -> float:
    """How much of a clip's fine noise persists ``lag`` frames later: 0 for independent noise per frame.

    Each frame's fine residual is the frame minus its Gaussian blur (:data:`RESIDUAL_SIGMA` = 2 px, per channel):
    mostly noise, with the picture's fine detail. It is compared only on pixels where that detail is absent and the
    picture does not move:

    * flat: the gradient magnitude of the blurred temporal mean frame (largest over channels) is in the lowest
      :data:`FLAT_QUANTILE` (30%) of the frame's, and so is its curvature (absolute Laplacian, largest over
      channels): the gradient alone is zero on the crests of a texture, where its residual is largest;
    * static for the pair (t, t + lag), per channel: the change of the blurred frames,
      ``blur(frame[t + lag]) - blur(frame[t])``, is within :data:`STATIC_ROBUST_SIGMAS` robust standard deviations
      of its median over the flat pixels (a global change of brightness is allowed, motion is not).

    The result is the Pearson correlation of residual t with residual t + lag over those pixels, pooled over every
    frame pair and channel. For noise n_t = rho n_(t-1) + sqrt(1 - rho^2) e_t it is rho. A static textured scene
    with independent noise reads about 0 as long as a third of the frame is flat or textured coarsely enough for the
    blur to see it: a sinusoid of 16 px over half the frame reads 0 +- 0.02. Texture over the whole frame, or finer
    than the blur sees (periods under about 6 px), passes as flat and is read as persistent noise (a static
    pattern and fully persistent noise are the same thing to a single clip).

    Args:
        frames: ``(T, H, W, 3)`` clip, [0, 1] scale, ``T > lag``; H and W above 8 pixels.
        lag: Frames between the two residuals compared, >= 1.

    Returns:
        The correlation in [-1, 1]; NaN when no pixel qualifies or a residual is constant.

    Raises:
        ValueError: ``frames`` is not ``(T, H, W, 3)`` with ``T > lag``, or ``lag < 1``.
    """
    clip = np.asarray(frames, dtype=np.float64)
    if clip.ndim != 4 or clip.shape[3] != 3:
        raise ValueError(f"frames must be a (T, H, W, 3) clip, got shape {clip.shape}")
    if lag < 1 or clip.shape[0] <= lag:
        raise ValueError(f"lag must be at least 1 and below the clip's {clip.shape[0]} frames, got {lag}")
    blurred = gaussian_blur(clip, RESIDUAL_SIGMA, axes=(1, 2))
    residual = clip - blurred
    mean_blurred = blurred.mean(axis=0)
    gradient = _gradient_magnitude(mean_blurred)
    # The gradient is zero on the crests of a texture, where its residual is largest: the curvature sees those.
    curvature = _curvature(mean_blurred)
    flat = (gradient <= np.quantile(gradient, FLAT_QUANTILE)) & (curvature <= np.quantile(curvature, FLAT_QUANTILE))
    # Running sums of x, y, x^2, y^2, xy and the count, so long clips never hold every pixel pair at once.
    sums = np.zeros(6)
    for start in range(clip.shape[0] - lag):
        change = blurred[start + lag] - blurred[start]
        for channel in range(3):
            values = change[..., channel][flat]
            centre = np.median(values)
            spread = 1.4826 * np.median(np.abs(values - centre))
            static = flat & (np.abs(change[..., channel] - centre) <= STATIC_ROBUST_SIGMAS * spread)
            x = residual[start, ..., channel][static]
            y = residual[start + lag, ..., channel][static]
            sums += (x.sum(), y.sum(), (x * x).sum(), (y * y).sum(), (x * y).sum(), x.size)
    return _correlation_of_sums(sums)


def _correlation_of_sums(sums: np.ndarray) -> float:
    """Pearson's correlation from the running sums (x, y, x^2, y^2, xy, count); NaN without two pairs or with a
    constant side."""
    sum_x, sum_y, sum_xx, sum_yy, sum_xy, count = sums
    if count < 2:
        return float("nan")
    covariance = sum_xy - sum_x * sum_y / count
    variance_x = sum_xx - sum_x**2 / count
    variance_y = sum_yy - sum_y**2 / count
    if variance_x <= 0 or variance_y <= 0:
        return float("nan")
    return float(covariance / np.sqrt(variance_x * variance_y))
