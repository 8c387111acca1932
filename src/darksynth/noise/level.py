"""The noise level a clip would show: the mean variance of f(v) over its pixels, in closed form.

What a viewer (and a histogram metric) sees first is how strong the noise is on *this* picture, not how it
splits into shot and read terms: on a dark clip the two are hard to tell apart, and any split with the same
total looks alike. The DEN's training uses this quantity as a second target (``TrainConfig.lambda_level``).
"""

from __future__ import annotations

from collections.abc import Mapping

import torch


def mean_noise_variance(values: Mapping[str, torch.Tensor], dark: torch.Tensor) -> torch.Tensor:
    """Mean over pixels of the noise variance of each clip, before clipping and 8-bit rounding.

    Sums the heteroscedastic term ``g_c^2 (shot^2 x + read^2)`` (channel gains ``g`` = red, 1, blue when the
    values hold ``channel_gain``; spatial and channel correlation keep the variance), ``banding^2`` and
    ``temporal_banding^2``. Quantization and periodic noise are left out: small next to these on real noise.
    Differentiable in ``values``.

    Args:
        values: parameters by name, each (B, size).
        dark: the clips the noise is added to, (B, T, C, H, W) or (B, C, H, W).

    Returns:
        (B,) mean variances.
    """
    batch = dark.shape[0]
    channels = dark.shape[-3]
    channel_means = dark.reshape(batch, -1, channels, dark.shape[-2] * dark.shape[-1]).mean(dim=(1, 3))
    shot, read = values["shot"][:, :1], values["read"][:, :1]
    per_channel = shot.square() * channel_means + read.square()
    if "channel_gain" in values and channels == 3:
        gains = values["channel_gain"]
        squares = torch.stack([gains[:, 0], torch.ones_like(gains[:, 0]), gains[:, 1]], dim=1).square()
        per_channel = per_channel * squares
    variance = per_channel.mean(dim=1)
    for name in ("banding", "temporal_banding"):
        if name in values:
            variance = variance + values[name][:, 0].square()
    return variance
