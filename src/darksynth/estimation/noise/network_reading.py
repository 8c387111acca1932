"""Running the DEN on a reference: its values for every crop and their robust aggregate.

The estimate of every crop is a full v; the median over crops is robust to crops where content, clipping or a
light source misleads the network, and the 10th to 90th percentile across crops, the ``ranges``, lets ``apply``
reproduce the spread the reference shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from darksynth.estimation.reference import crop_grid
from darksynth.models.den import DEN
from darksynth.noise.components import model_parameters
from darksynth.noise.values import NoiseValues, stacked_values


@dataclass(frozen=True)
class NetworkEstimate:
    """What the network says of a reference.

    Attributes:
        per_crop: the network's values for each crop of :func:`crop_grid`, batched (N,), float64 on the CPU.
        noise: their median over crops, unbatched.
        ranges: for every parameter the network estimates, per element the 10th to 90th percentile over crops.
    """

    per_crop: NoiseValues
    noise: NoiseValues
    ranges: dict[str, tuple[tuple[float, float], ...]]


@torch.no_grad()
def run_network(
    reference: torch.Tensor, network: DEN, *, batch: int = 16, device: torch.device | str = "cpu"
) -> NetworkEstimate:
    """Run the network on the crops of a reference (T, 3, H, W) in [0, 1], ``batch`` crops per forward pass."""
    crops = crop_grid(reference)
    network = network.to(device).eval()
    per_crop = stacked_values(
        [network(crops[i : i + batch].to(device)).values.to("cpu") for i in range(0, len(crops), batch)]
    ).to(dtype=torch.float64)
    # quantile(0.5) averages the two middle crops of an even count, where Tensor.median takes the lower one.
    noise = per_crop.map(lambda t: torch.quantile(t, 0.5, dim=0))
    low = per_crop.map(lambda t: torch.quantile(t, 0.1, dim=0))
    high = per_crop.map(lambda t: torch.quantile(t, 0.9, dim=0))
    noise_model = network.noise_model
    # What the network does not estimate (the sRGB structure, for the paper's model) stays neutral, without a range.
    ranges = {
        p.name: tuple(zip(low[p.name].tolist(), high[p.name].tolist(), strict=True))
        for p in model_parameters(noise_model, network.config.profile_version)
    }
    return NetworkEstimate(per_crop=per_crop, noise=noise, ranges=ranges)
