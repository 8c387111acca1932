"""Distances between real and synthetic noise: histogram KL divergences, FID, KID and confidence intervals.

Pure functions on numpy arrays or torch tensors; every result is a Python float.

* :func:`kl_divergence_noise_flow` follows the recipe of Noise Flow (Abdelhamed, Brubaker and Brown,
  "Noise Flow: Noise Modeling with Conditional Normalizing Flows", ICCV 2019), the usual raw-domain KL of
  the noise-modelling literature.
* :func:`kl_divergence_srgb` follows the sRGB recipe of Kousha, Maleky, Brown and Brubaker, "Modeling sRGB
  Camera Noise with Normalizing Flows", CVPR 2022.
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

NOISE_FLOW_LIMIT = 0.1
"""Noise Flow histograms cover [-0.1, 0.1] on the [0, 1] scale, plus one overflow bin on each side."""

NOISE_FLOW_BINS = 64
"""Bins of width 0.2 / 64 between -0.1 and 0.1."""

SRGB_BIN_EDGES = np.arange(-260.0, 261.0, 4.0)
"""Kousha et al. 2022: bins of width 4 in 8-bit units from -260 to 260 (130 bins)."""

KID_MAX_SUBSET = 1000
"""KID subsets hold at most this many vectors from each set (Bińkowski et al. 2018 used 1000)."""

FID_EPS = 1e-6
"""Added to the covariance diagonals when the square root of their product is not finite (as pytorch-fid)."""

FID_IMAGINARY_TOLERANCE = 1e-3
"""Largest imaginary part tolerated on the diagonal of sqrtm(S_a S_b) before it is called a numerical failure."""


def _flat(values: ArrayLike) -> np.ndarray[Any, np.dtype[np.float64]]:
    array = values.detach().cpu().double().numpy() if isinstance(values, torch.Tensor) else np.asarray(values)
    flat = np.asarray(array, dtype=np.float64).reshape(-1)
    if flat.size == 0:
        raise ValueError("empty sample: a histogram needs at least one value")
    if np.isnan(flat).any():
        raise ValueError("sample contains NaN")
    return flat


def _matrix(features: ArrayLike, name: str) -> np.ndarray[Any, np.dtype[np.float64]]:
    array = features.detach().cpu().double().numpy() if isinstance(features, torch.Tensor) else np.asarray(features)
    matrix = np.asarray(array, dtype=np.float64)
    if matrix.ndim != 2:
        raise ValueError(f"{name} must be a (N, D) array of feature vectors, got shape {matrix.shape}")
    if matrix.shape[0] < 2:
        raise ValueError(f"{name} needs at least 2 feature vectors, got {matrix.shape[0]}")
    if not np.isfinite(matrix).all():
        raise ValueError(f"{name} contains non-finite values")
    return matrix


def _kl(p: np.ndarray[Any, np.dtype[np.float64]], q: np.ndarray[Any, np.dtype[np.float64]]) -> float:
    """sum p log(p / q) over the bins where both p and q are non-zero."""
    both = (p > 0) & (q > 0)
    return float(np.sum(p[both] * np.log(p[both] / q[both])))


def noise_flow_histogram(noise: ArrayLike) -> np.ndarray[Any, np.dtype[np.float64]]:
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
    probabilities: np.ndarray[Any, np.dtype[np.float64]] = counts / counts.sum()
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


def srgb_histogram(noise: ArrayLike) -> np.ndarray[Any, np.dtype[np.float64]]:
    """The add-one smoothed probability histogram of Kousha et al. 2022 for [0, 1]-scale noise of any shape.

    The noise is multiplied by 255 (8-bit units) and binned with the edges -260, -256, ..., 260; every bin
    count gets 1 added before normalising. Values outside [-260, 260] (impossible for 8-bit noise) are dropped.
    """
    values = _flat(noise) * 255.0
    counts, _ = np.histogram(values, bins=SRGB_BIN_EDGES)
    smoothed = counts.astype(np.float64) + 1.0
    probabilities: np.ndarray[Any, np.dtype[np.float64]] = smoothed / smoothed.sum()
    return probabilities


def kl_divergence_srgb(real: ArrayLike, synthetic: ArrayLike) -> float:
    """KL(real || synthetic) between noise histograms, by the sRGB recipe of Kousha et al. 2022.

    Noise on the [0, 1] scale is converted to 8-bit units (x 255) and binned with bins of width 4 from -260 to
    260; add-one smoothing (1 added to every bin count before normalising) makes every bin non-zero, so the
    divergence is finite even where the synthetic sample leaves bins empty. Result in nats.
    """
    return _kl(srgb_histogram(real), srgb_histogram(synthetic))


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


def _trace_sqrt_product_sqrtm(
    sigma_a: np.ndarray[Any, np.dtype[np.float64]], sigma_b: np.ndarray[Any, np.dtype[np.float64]]
) -> float:
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


def _trace_sqrt_product_factors(
    a: np.ndarray[Any, np.dtype[np.float64]], b: np.ndarray[Any, np.dtype[np.float64]]
) -> float:
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
    b = _matrix(features_b, "features_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"feature dimensions differ: {a.shape[1]} and {b.shape[1]}")
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


def _polynomial_mmd2(x: np.ndarray[Any, np.dtype[np.float64]], y: np.ndarray[Any, np.dtype[np.float64]]) -> float:
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
    b = _matrix(features_b, "features_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"feature dimensions differ: {a.shape[1]} and {b.shape[1]}")
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
