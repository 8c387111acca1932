"""Distances between real and synthetic noise: histogram KL divergences, FID, KID and confidence intervals.

Pure functions on numpy arrays or torch tensors; every result is a Python float.

* :func:`kl_divergence_noise_flow` follows the recipe of Noise Flow (Abdelhamed, Brubaker and Brown,
  "Noise Flow: Noise Modeling with Conditional Normalizing Flows", ICCV 2019), the usual raw-domain KL of
  the noise-modelling literature.
* :func:`kl_divergence_srgb` follows the sRGB recipe of Kousha, Maleky, Brown and Brubaker, "Modeling sRGB
  Camera Noise with Normalizing Flows", CVPR 2022.
* :func:`kl_divergence_naflow` is the wide-range histogram KL reported on SIDD by NAFlow (Kim, Lee and Cho,
  "sRGB Real Noise Modeling via Noise-Aware Sampling with Normalizing Flows", ICLR 2024) and the papers it
  compares with (NeCA, PNGAN...).
* :func:`average_kl_divergence` is the AKLD of Yue, Zhao, Zhang, Meng and Zhang, "Dual Adversarial Network: Toward
  Real-world Noise Removal and Noise Generation" (DANet), ECCV 2020.
* :func:`channel_moments` and :func:`channel_correlations` give the per-channel noise level and the cross-channel
  correlation of a noise map.
* :func:`frechet_distance` is the FID formula of Heusel et al., "GANs Trained by a Two Time-Scale Update Rule
  Converge to a Local Nash Equilibrium", NeurIPS 2017.
* :func:`kernel_inception_distance` is the KID of Bińkowski, Sutherland, Arbel and Gretton, "Demystifying MMD
  GANs", ICLR 2018.

KL divergences are in nats (natural logarithm), as in both reference implementations.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.linalg
import scipy.stats
import torch

ArrayLike = np.ndarray[Any, Any] | torch.Tensor
"""A numpy array or a torch tensor; tensors are detached and moved to the CPU."""

_Array = np.ndarray[Any, np.dtype[np.float64]]

NOISE_FLOW_LIMIT = 0.1
"""Noise Flow histograms cover [-0.1, 0.1] on the [0, 1] scale, plus one overflow bin on each side."""

NOISE_FLOW_BINS = 64
"""Bins of width 0.2 / 64 between -0.1 and 0.1."""

SRGB_BIN_EDGES = np.arange(-260.0, 261.0, 4.0)
"""Kousha et al. 2022: bins of width 4 in 8-bit units from -260 to 260 (130 bins)."""

NAFLOW_LIMIT = 1.0
"""The NAFlow-recipe histogram covers the whole possible range of [0, 1]-scale noise, [-1, 1]."""

NAFLOW_BINS = 256
"""Bins of width 2 / 256 (about half an 8-bit level) between -1 and 1."""

NAFLOW_EPS = 1e-10
"""Added to every bin probability of both histograms (then renormalised) so that empty bins stay finite."""

AKLD_WINDOW = 7
"""Side of DANet's Gaussian window for the local noise variance."""

AKLD_WINDOW_SIGMA = 0.3 * ((AKLD_WINDOW - 1) * 0.5 - 1.0) + 0.8
"""Standard deviation of that window, 1.4 pixels: DANet builds it with ``cv2.getGaussianKernel(7, -1)``, and OpenCV
computes a non-positive sigma as 0.3 ((ksize - 1) / 2 - 1) + 0.8."""

AKLD_VARIANCE_FLOOR = 1e-10
"""Local variances are clamped to at least this (as DANet): a window of exactly zero noise stays finite."""

AKLD_RATIO_RANGE = (0.1, 10.0)
"""The ratio of the two local variances is clamped to this range (as DANet), bounding one pixel's divergence."""

CHANNEL_PAIRS = ("rg", "gb", "rb")
"""The channel pairs of :func:`channel_correlations`, in its order."""

KID_MAX_SUBSET = 1000
"""KID subsets hold at most this many vectors from each set (Bińkowski et al. 2018 used 1000)."""

FID_EPS = 1e-6
"""Added to the covariance diagonals when the square root of their product is not finite (as pytorch-fid)."""

FID_IMAGINARY_TOLERANCE = 1e-3
"""Largest imaginary part tolerated on the diagonal of sqrtm(S_a S_b) before it is called a numerical failure."""


def _flat(values: ArrayLike) -> _Array:
    array = values.detach().cpu().double().numpy() if isinstance(values, torch.Tensor) else np.asarray(values)
    flat = np.asarray(array, dtype=np.float64).reshape(-1)
    if flat.size == 0:
        raise ValueError("empty sample: a histogram needs at least one value")
    if np.isnan(flat).any():
        raise ValueError("sample contains NaN")
    return flat


def _matrix(features: ArrayLike, name: str, width: int | None = None) -> _Array:
    """Feature vectors as a float64 (N, D) matrix, checked; ``width``: the D of the other set, which it must share."""
    array = features.detach().cpu().double().numpy() if isinstance(features, torch.Tensor) else np.asarray(features)
    matrix = np.asarray(array, dtype=np.float64)
    if matrix.ndim != 2:
        raise ValueError(f"{name} must be a (N, D) array of feature vectors, got shape {matrix.shape}")
    if matrix.shape[0] < 2:
        raise ValueError(f"{name} needs at least 2 feature vectors, got {matrix.shape[0]}")
    if not np.isfinite(matrix).all():
        raise ValueError(f"{name} contains non-finite values")
    if width is not None and matrix.shape[1] != width:
        raise ValueError(f"feature dimensions differ: {width} and {matrix.shape[1]}")
    return matrix


def _kl(p: _Array, q: _Array) -> float:
    """sum p log(p / q) over the bins where both p and q are non-zero."""
    both = (p > 0) & (q > 0)
    return float(np.sum(p[both] * np.log(p[both] / q[both])))


def noise_flow_histogram(noise: ArrayLike) -> _Array:
    """The 66-bin probability histogram of the Noise Flow recipe, for [0, 1]-scale noise of any shape.

    Bin 0 holds the values below -0.1, bins 1..64 split [-0.1, 0.1] into 64 bins of width 0.2 / 64 (each
    closed on the left, the last also on the right, as ``numpy.histogram``), bin 65 holds the values above 0.1.
    """
    values = _flat(noise)
    edges = np.linspace(-NOISE_FLOW_LIMIT, NOISE_FLOW_LIMIT, NOISE_FLOW_BINS + 1)
    inside, _ = np.histogram(values, bins=edges)
    below = np.count_nonzero(values < -NOISE_FLOW_LIMIT)
    above = np.count_nonzero(values > NOISE_FLOW_LIMIT)
    counts = np.concatenate(([below], inside, [above])).astype(np.float64)
    probabilities: _Array = counts / counts.sum()
    return probabilities


def kl_divergence_noise_flow(real: ArrayLike, synthetic: ArrayLike) -> float:
    """KL(real || synthetic) between noise histograms, by the recipe of Noise Flow (Abdelhamed et al. 2019).

    Noise is on the [0, 1] scale (noisy - clean). Both samples are binned into 64 bins of width 0.2 / 64 over
    [-0.1, 0.1] plus one overflow bin on each side (values below -0.1, values above 0.1), the counts are
    normalised to probabilities p (real) and q (synthetic), and sum p log(p / q) is taken over the bins where
    BOTH are non-zero, in nats. Bins that only one histogram fills are ignored, as in the reference code: the
    value is therefore blind to mass one sample puts where the other has none, and it can even be slightly
    negative. Identical samples give exactly 0.
    """
    return _kl(noise_flow_histogram(real), noise_flow_histogram(synthetic))


def srgb_histogram(noise: ArrayLike) -> _Array:
    """The add-one smoothed probability histogram of Kousha et al. 2022 for [0, 1]-scale noise of any shape.

    The noise is multiplied by 255 (8-bit units) and binned with the edges -260, -256, ..., 260; every bin
    count gets 1 added before normalising. Values outside [-260, 260] (impossible for 8-bit noise) are dropped.
    """
    values = _flat(noise) * 255.0
    counts, _ = np.histogram(values, bins=SRGB_BIN_EDGES)
    smoothed = counts.astype(np.float64) + 1.0
    probabilities: _Array = smoothed / smoothed.sum()
    return probabilities


def kl_divergence_srgb(real: ArrayLike, synthetic: ArrayLike) -> float:
    """KL(real || synthetic) between noise histograms, by the sRGB recipe of Kousha et al. 2022.

    Noise on the [0, 1] scale is converted to 8-bit units (x 255) and binned with bins of width 4 from -260 to
    260; add-one smoothing (1 added to every bin count before normalising) makes every bin non-zero, so the
    divergence is finite even where the synthetic sample leaves bins empty. Result in nats.
    """
    return _kl(srgb_histogram(real), srgb_histogram(synthetic))


def naflow_histogram(noise: ArrayLike) -> _Array:
    """The 256-bin probability histogram of the NAFlow recipe, for [0, 1]-scale noise of any shape.

    The bins split [-1, 1] into 256 bins of width 2 / 256 (each closed on the left, the last also on the right, as
    ``numpy.histogram``); [0, 1]-scale noise can never leave that range. :data:`NAFLOW_EPS` is added to every
    probability and the histogram renormalised.
    """
    values = _flat(noise)
    counts, _ = np.histogram(values, bins=NAFLOW_BINS, range=(-NAFLOW_LIMIT, NAFLOW_LIMIT))
    smoothed = counts.astype(np.float64) / values.size + NAFLOW_EPS
    probabilities: _Array = smoothed / smoothed.sum()
    return probabilities


def kl_divergence_naflow(real: ArrayLike, synthetic: ArrayLike) -> float:
    """KL(real || synthetic) between noise histograms, by the recipe reported on SIDD by NAFlow, NeCA and PNGAN.

    Noise is on the [0, 1] scale (noisy - clean). Both samples are binned into 256 bins of width 2 / 256 over
    [-1, 1], normalised to probabilities, and a small epsilon (:data:`NAFLOW_EPS`) is added to every bin of both
    histograms before renormalising, so bins that only one sample fills count (sum p log(p / q) over all bins, in
    nats) and the value is never negative. Identical samples give exactly 0.

    How it differs from :func:`kl_divergence_noise_flow`: Noise Flow's bins are 8 times finer (0.2 / 64) but only
    cover [-0.1, 0.1], everything beyond going to two overflow bins, and it drops the bins where either histogram
    is empty. Here the bins are about half an 8-bit level wide, the tails are resolved up to the full range, and
    mass one sample puts where the other has none is penalised (by up to log(1 / eps) per unit of mass) instead
    of ignored; on 8-bit noise both recipes see whole levels, so the finer Noise Flow bins alternate between
    full and empty.
    """
    return _kl(naflow_histogram(real), naflow_histogram(synthetic))


def _noise_tensor(noise: ArrayLike, name: str) -> torch.Tensor:
    tensor = noise.detach().cpu() if isinstance(noise, torch.Tensor) else torch.from_numpy(np.asarray(noise))
    tensor = tensor.to(torch.float64)
    if tensor.ndim != 3:
        raise ValueError(f"{name} must be a (C, H, W) noise map, got shape {tuple(tensor.shape)}")
    if torch.isnan(tensor).any():
        raise ValueError(f"{name} contains NaN")
    return tensor


def local_noise_variance(noise: ArrayLike) -> torch.Tensor:
    """Per pixel and channel, the Gaussian-weighted mean of the squared noise in a 7 x 7 window (DANet).

    Args:
        noise: ``(C, H, W)`` noise (noisy - clean), [0, 1] scale.

    Returns:
        ``(C, H, W)`` float64 local variances, at least :data:`AKLD_VARIANCE_FLOOR`. The window is the separable
        Gaussian of side :data:`AKLD_WINDOW` and standard deviation :data:`AKLD_WINDOW_SIGMA`, normalised to sum
        1; the borders are reflected, as in DANet's ``gaussblur``.
    """
    tensor = _noise_tensor(noise, "noise")
    if min(tensor.shape[-2:]) <= AKLD_WINDOW // 2:
        raise ValueError(f"noise must be more than {AKLD_WINDOW // 2} pixels on each side, got {tuple(tensor.shape)}")
    offsets = torch.arange(AKLD_WINDOW, dtype=torch.float64) - (AKLD_WINDOW - 1) / 2
    weights = torch.exp(-(offsets**2) / (2 * AKLD_WINDOW_SIGMA**2))
    weights = weights / weights.sum()
    channels = tensor.shape[0]
    pad = AKLD_WINDOW // 2
    squared = torch.nn.functional.pad((tensor**2).unsqueeze(0), (pad, pad, pad, pad), mode="reflect")
    rows = torch.nn.functional.conv2d(squared, weights.view(1, 1, -1, 1).repeat(channels, 1, 1, 1), groups=channels)
    local = torch.nn.functional.conv2d(rows, weights.view(1, 1, 1, -1).repeat(channels, 1, 1, 1), groups=channels)
    return local.squeeze(0).clamp_min(AKLD_VARIANCE_FLOOR)


def average_kl_divergence(real: ArrayLike, synthetic: ArrayLike) -> float:
    """AKLD (Yue et al. 2020, DANet): the mean over pixels and channels of a KL divergence of local Gaussians.

    Each noise map's local variance s² is taken with :func:`local_noise_variance` (7 x 7 Gaussian window of
    standard deviation 1.4 over the squared noise), and per pixel and channel

        KL(N(0, s_real²) || N(0, s_syn²)) = log(s_syn / s_real) + s_real² / (2 s_syn²) - 1/2,

    with the variance ratio s_real² / s_syn² clamped to [0.1, 10] as in DANet's code. The direction is the one of
    the histogram divergences here (real first); DANet's code takes KL(synthetic || real). 0 for identical noise.

    Args:
        real, synthetic: ``(C, H, W)`` noise maps of the same shape, [0, 1] scale.

    Returns:
        The mean divergence in nats.
    """
    real_variance = local_noise_variance(real)
    synthetic_variance = local_noise_variance(synthetic)
    if real_variance.shape != synthetic_variance.shape:
        shapes = f"{tuple(real_variance.shape)} and {tuple(synthetic_variance.shape)}"
        raise ValueError(f"real and synthetic noise maps differ in shape: {shapes}")
    ratio = (real_variance / synthetic_variance).clamp(*AKLD_RATIO_RANGE)
    return float((0.5 * (ratio - 1.0 - torch.log(ratio))).mean())


def channel_moments(noise: ArrayLike) -> _Array:
    """Per channel, the count, sum and sum of squares of a noise map: pooled over pairs, they give a pooled std.

    Args:
        noise: ``(C, H, W)`` noise map.

    Returns:
        ``(C, 3)`` float64: count, sum, sum of squares.
    """
    tensor = _noise_tensor(noise, "noise")
    tensor = tensor.reshape(tensor.shape[0], -1)
    count = torch.full((tensor.shape[0],), float(tensor.shape[1]), dtype=torch.float64)
    return torch.stack((count, tensor.sum(dim=1), (tensor**2).sum(dim=1)), dim=1).numpy()


def pooled_std(moments: _Array) -> _Array:
    """Per channel, the (population) standard deviation of all values behind summed :func:`channel_moments`."""
    count, total, squares = moments[:, 0], moments[:, 1], moments[:, 2]
    mean = total / count
    std: _Array = np.sqrt(np.maximum(squares / count - mean**2, 0.0))
    return std


def channel_correlations(noise: ArrayLike) -> dict[str, float]:
    """Pearson correlation of the noise between the channels of an RGB noise map, over its pixels.

    Args:
        noise: ``(3, H, W)`` noise map (R, G, B).

    Returns:
        ``"rg"``, ``"gb"``, ``"rb"`` -> the correlation coefficient; NaN where a channel is constant.
    """
    tensor = _noise_tensor(noise, "noise")
    if tensor.shape[0] != 3:
        raise ValueError(f"channel correlations need an RGB (3, H, W) noise map, got shape {tuple(tensor.shape)}")
    centred = tensor.reshape(3, -1)
    centred = centred - centred.mean(dim=1, keepdim=True)
    norms = torch.sqrt((centred**2).sum(dim=1))
    indices = {"rg": (0, 1), "gb": (1, 2), "rb": (0, 2)}
    correlations = {}
    for pair in CHANNEL_PAIRS:
        first, second = indices[pair]
        denominator = float(norms[first] * norms[second])
        numerator = float((centred[first] * centred[second]).sum())
        correlations[pair] = numerator / denominator if denominator > 0 else math.nan
    return correlations


def mean_and_interval(values: Sequence[float] | ArrayLike, confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean of ``values`` and the two ends of its Student-t confidence interval (95% by default).

    The interval is mean ± t(1 - (1 - confidence) / 2, n - 1) · s / sqrt(n), with s the sample standard deviation
    (ddof = 1). For a single value, or values that are all equal, the interval is (mean, mean).
    Returns ``(mean, low, high)``.
    """
    if isinstance(values, torch.Tensor):
        array = values.detach().cpu().double().numpy().reshape(-1)
    else:
        array = np.asarray(values, dtype=np.float64).reshape(-1)
    if array.size == 0:
        raise ValueError("mean_and_interval needs at least one value")
    if not np.isfinite(array).all():
        raise ValueError("mean_and_interval got non-finite values")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    mean = float(array.mean())
    if array.size == 1:
        return mean, mean, mean
    sem = float(array.std(ddof=1)) / math.sqrt(array.size)
    half = float(scipy.stats.t.ppf(0.5 + confidence / 2.0, df=array.size - 1)) * sem
    return mean, mean - half, mean + half


def _trace_sqrt_product_sqrtm(sigma_a: _Array, sigma_b: _Array) -> float:
    """tr sqrt(S_a S_b) with scipy.linalg.sqrtm, handled as pytorch-fid does.

    When the square root is not finite (singular product) it is recomputed with ``FID_EPS`` on both diagonals;
    small imaginary parts from rounding are dropped, large ones raise.
    """
    covmean = scipy.linalg.sqrtm(sigma_a @ sigma_b)
    if not np.isfinite(covmean).all():
        offset = np.eye(sigma_a.shape[0]) * FID_EPS
        covmean = scipy.linalg.sqrtm((sigma_a + offset) @ (sigma_b + offset))
    if np.iscomplexobj(covmean):
        imaginary = float(np.max(np.abs(np.diagonal(covmean).imag)))
        if imaginary > FID_IMAGINARY_TOLERANCE:
            raise ValueError(f"sqrtm of the covariance product has an imaginary component {imaginary:.3g}")
        covmean = covmean.real
    return float(np.trace(covmean))


def _trace_sqrt_product_factors(a: _Array, b: _Array) -> float:
    """tr sqrt(S_a S_b) from the feature vectors themselves, exactly, when N < D.

    With A and B the mean-centred features, S_a = AᵀA / (n_a - 1) and S_b = BᵀB / (n_b - 1). The non-zero
    eigenvalues of S_a S_b are those of (A Bᵀ)(A Bᵀ)ᵀ / ((n_a - 1)(n_b - 1)), so tr sqrt(S_a S_b) is the sum of
    the singular values of A Bᵀ divided by sqrt((n_a - 1)(n_b - 1)): an (n_a, n_b) SVD instead of the square
    root of a singular (D, D) matrix.
    """
    centred_a = a - a.mean(axis=0)
    centred_b = b - b.mean(axis=0)
    singular = np.linalg.svd(centred_a @ centred_b.T, compute_uv=False)
    return float(singular.sum()) / math.sqrt((a.shape[0] - 1) * (b.shape[0] - 1))


def frechet_distance(features_a: ArrayLike, features_b: ArrayLike) -> float:
    """Fréchet distance between Gaussians fitted to two sets of feature vectors (the FID formula).

    ``features_a`` and ``features_b`` are (N, D) arrays (e.g. InceptionV3 pool features), N >= 2, computed in
    float64: ||mu_a - mu_b||² + tr(S_a + S_b - 2 sqrt(S_a S_b)), with unbiased covariances (Heusel et al. 2017).

    tr sqrt(S_a S_b) is taken with ``scipy.linalg.sqrtm`` as in pytorch-fid (eps on the diagonals if the root
    is not finite, tiny imaginary parts dropped) when both sets have more vectors than dimensions. When either
    has N <= D (e.g. a few hundred crops against 2048 Inception dimensions) the covariances are singular, sqrtm
    would need the eps workaround and takes seconds at D = 2048; the same trace is then computed exactly from
    the singular values of the centred cross-product (see ``_trace_sqrt_product_factors``), in milliseconds.
    """
    a = _matrix(features_a, "features_a")
    b = _matrix(features_b, "features_b", width=a.shape[1])
    mean_term = float(np.sum((a.mean(axis=0) - b.mean(axis=0)) ** 2))
    # tr S = the sum of the per-dimension variances: no need to form the (D, D) matrices for it.
    trace_term = float(a.var(axis=0, ddof=1).sum() + b.var(axis=0, ddof=1).sum())
    if min(a.shape[0], b.shape[0]) <= a.shape[1]:
        trace_sqrt = _trace_sqrt_product_factors(a, b)
    else:
        sigma_a = np.atleast_2d(np.cov(a, rowvar=False))
        sigma_b = np.atleast_2d(np.cov(b, rowvar=False))
        trace_sqrt = _trace_sqrt_product_sqrtm(sigma_a, sigma_b)
    return mean_term + trace_term - 2.0 * trace_sqrt


def _polynomial_mmd2(x: _Array, y: _Array) -> float:
    """Unbiased MMD² between equal-size samples with the kernel k(u, v) = (u·v / D + 1)³."""
    m, dim = x.shape
    k_xx = (x @ x.T / dim + 1.0) ** 3
    k_yy = (y @ y.T / dim + 1.0) ** 3
    k_xy = (x @ y.T / dim + 1.0) ** 3
    within = (k_xx.sum() - np.trace(k_xx) + k_yy.sum() - np.trace(k_yy)) / (m * (m - 1))
    return float(within - 2.0 * k_xy.sum() / (m * m))


def kernel_inception_distance(
    features_a: ArrayLike,
    features_b: ArrayLike,
    *,
    subsets: int = 50,
    subset_size: int | None = None,
    seed: int = 0,
) -> tuple[float, float]:
    """Kernel Inception Distance (Bińkowski et al. 2018): mean and standard deviation over random subsets.

    Each of ``subsets`` rounds draws ``subset_size`` vectors without replacement from each set and computes the
    unbiased MMD² with the cubic polynomial kernel k(x, y) = (x·y / D + 1)³. ``subset_size`` defaults to
    min(1000, len(a), len(b)). The estimate is unbiased, so for two samples of one distribution it scatters
    around 0 and can be slightly negative. ``seed`` fixes the subsets. Returns ``(mean, std)`` of the rounds.
    When the subset size equals both set sizes every round sees the same vectors and the std is 0: it measures
    subset-to-subset spread only, not the uncertainty of the sets themselves.
    """
    a = _matrix(features_a, "features_a")
    b = _matrix(features_b, "features_b", width=a.shape[1])
    if subsets < 1:
        raise ValueError(f"subsets must be at least 1, got {subsets}")
    size = min(KID_MAX_SUBSET, a.shape[0], b.shape[0]) if subset_size is None else subset_size
    if not 2 <= size <= min(a.shape[0], b.shape[0]):
        raise ValueError(f"subset_size must be in [2, {min(a.shape[0], b.shape[0])}], got {size}")
    rng = np.random.default_rng(seed)
    values = np.empty(subsets)
    for index in range(subsets):
        x = a[rng.choice(a.shape[0], size, replace=False)]
        y = b[rng.choice(b.shape[0], size, replace=False)]
        values[index] = _polynomial_mmd2(x, y)
    return float(values.mean()), float(values.std())
