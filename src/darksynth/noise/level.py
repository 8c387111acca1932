"""The noise level a clip would show: the mean variance of f(v) over its pixels, in closed form.

What a viewer (and a histogram metric) sees first is how strong the noise is on *this* picture, not how it
splits into shot and read terms: on a dark clip the two are hard to tell apart, and any split with the same
total looks alike. The DEN's training uses this quantity as a second target (``TrainConfig.lambda_level``).
"""

from __future__ import annotations

from collections.abc import Mapping

import torch

from darksynth.noise.components import noise_components


def mean_noise_variance(values: Mapping[str, torch.Tensor], dark: torch.Tensor) -> torch.Tensor:
    """Mean over pixels of the noise variance of each clip, before clipping and 8-bit rounding.

    The sum of the terms the components of the table declare (:attr:`NoiseComponent.variance`): for the
    heteroscedastic one ``g_c^2 (shot^2 x + read^2)`` with channel gains ``g`` = (red, 1, blue) (spatial and
    channel correlation keep the variance), ``q^2 / 12`` for quantization, the squared std of each column
    component. Output stages (compression) have no additive term. Differentiable in ``values``.

    Args:
        values: parameters by name, each (B, size): a batched :class:`~darksynth.noise.values.NoiseValues`,
            or the same as plain tensors where gradients flow through them.
        dark: the clips the noise is added to, (B, T, C, H, W) or (B, C, H, W).

    Returns:
        (B,) mean variances.
    """
    batch = dark.shape[0]
    channels = dark.shape[-3]
    channel_means = dark.reshape(batch, -1, channels, dark.shape[-2] * dark.shape[-1]).mean(dim=(1, 3))
    variance = torch.zeros_like(channel_means)
    for component in noise_components():
        # A model without a component's parameters (the network's ``srgb`` v has no spectrum) has it neutral.
        if component.variance is not None and all(p.name in values for p in component.parameters):
            variance = variance + component.variance(values, channel_means)
    return variance.mean(dim=1)


def channel_noise_std(values: Mapping[str, torch.Tensor], levels: torch.Tensor, channels: int = 3) -> torch.Tensor:
    """The noise std of each channel of a pixel at each of ``levels`` (L,), before clipping and 8-bit rounding:
    the square root of the components' variances (as :func:`mean_noise_variance` sums them) with every channel of
    the pixel at that level.

    Args:
        values: unbatched parameters by name, each (size,) (a :class:`~darksynth.noise.values.NoiseValues`).
        levels: intensities on the [0, 1] scale.
        channels: the channels of the pixel.

    Returns:
        (L, channels) standard deviations.
    """
    count = levels.shape[0]
    means = levels.to(torch.float64)[:, None].expand(count, channels)
    batched = {name: tensor.to(torch.float64).expand(count, tensor.shape[-1]) for name, tensor in values.items()}
    variance = torch.zeros_like(means)
    for component in noise_components():
        if component.variance is not None and all(p.name in batched for p in component.parameters):
            variance = variance + component.variance(batched, means)
    return variance.clamp_min(0.0).sqrt()
