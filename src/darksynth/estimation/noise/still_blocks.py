"""The blocks of a clip that stay still through its frames: where the frame-to-frame correlation of the noise can
be read (moving pixels carry the scene's change, not the noise's persistence)."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from darksynth.estimation.findings import Findings
from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK, blocks_to_mask
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import initial_parameters, quantised
from darksynth.estimation.noise.spectral_statistics import measure
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues

STILL_CHANGE = 2.0 / 255
"""A block is still when the mean absolute change of the denoised frames, from the first, is below this or below
:data:`STILL_NOISE_FACTOR` times the change the noise alone leaves in a still simulation, whichever is larger."""

STILL_NOISE_FACTOR = 1.5
"""How far above the noise-only change (the median over blocks of a still simulation's) a still block may go.
Strong noise leaves a change of its own in the denoised frames (the starlight video, 4 levels of noise: every
block above 2 levels, so no block was still and its persistence was not read)."""

MIN_STILL_BLOCKS = 4
"""Fewer still flat blocks than this: the clip's temporal correlation is not measured (the prior, 0)."""


def block_change(denoised: torch.Tensor) -> torch.Tensor:
    """Mean absolute change (H // FLAT_BLOCK, W // FLAT_BLOCK) of each block of denoised frames (T, 3, H, W) from
    the first frame, over the frames and channels, after each frame's median change per channel: a change of the whole
    frame's brightness (auto-exposure, flicker: the starlight video dims by 7 levels in 4 frames) moves nothing."""
    difference = denoised - denoised[:1]
    global_change = difference.flatten(-2).median(dim=-1).values[..., None, None]
    change = (difference - global_change).abs().mean(dim=(0, 1))[None, None]
    return F.avg_pool2d(change, FLAT_BLOCK)[0, 0]


def noise_only_change(
    denoised_first: torch.Tensor, values: NoiseValues, frames: int, strength: float, *, seed: int = 0
) -> float:
    """The median block change (see :func:`block_change`) of a still clip made of the first denoised frame
    (1, 3, H, W) and independent noise of ``values`` in each of ``frames`` frames, denoised like the reference."""
    # Its own stream of the estimate's seed (the fit's simulations use seed * 1009 + draw).
    generator = torch.Generator(device=denoised_first.device).manual_seed(7919 + seed * 1009)
    still = denoised_first.expand(frames, -1, -1, -1)
    synthetic = quantised(add_noise(still[None], values, generator=generator)[0])
    return float(block_change(nlm_denoise(synthetic, strength)).median())


def still_flat_mask(
    frames: torch.Tensor,
    denoised: torch.Tensor,
    mask: torch.Tensor,
    strength: float,
    seed: int,
    name: str,
) -> tuple[torch.Tensor | None, Findings]:
    """The measured blocks of a clip that stay still over its frames, as a pixel mask; None (with a warning) when
    fewer than :data:`MIN_STILL_BLOCKS` do. The findings hold the stillness threshold and the count."""
    height, width = frames.shape[-2:]
    first = initial_parameters(measure(frames[:1] - denoised[:1], denoised[:1], mask))
    first_values = NoiseValues.from_values(first.as_values(), dtype=torch.float32)
    threshold = max(
        STILL_CHANGE,
        STILL_NOISE_FACTOR * noise_only_change(denoised[:1], first_values, frames.shape[0], strength, seed=seed),
    )
    findings = Findings({"still_threshold_8bit": round(threshold * 255, 3)})
    still = block_change(denoised) < threshold
    flat = F.avg_pool2d(mask[None, None], FLAT_BLOCK)[0, 0] > 0.5
    both = still[: flat.shape[0], : flat.shape[1]] & flat
    findings.meta["still_flat_blocks"] = int(both.sum())
    if int(both.sum()) < MIN_STILL_BLOCKS:
        findings.warnings.append(
            f"{name}: only {int(both.sum())} flat blocks stay still over {frames.shape[0]} frames (the camera "
            "or the scene moves): the frame-to-frame correlation of the noise is the video prior (what the shared real "
            "night clips read; docs/spectral-noise.md)"
        )
        return None, findings
    if frames.shape[0] == 2:
        findings.warnings.append(
            f"{name}: 2 frames: the frame-to-frame correlation of the noise is read on one pair of frames "
            "(uncertain; give more frames)"
        )
    return blocks_to_mask(both, height, width), findings
