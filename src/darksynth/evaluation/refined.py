"""``den-refined``: the DEN's blind estimate refined on the noisy image itself (:mod:`darksynth.refine`).

A zero-shot method: its fit reads the noisy image only (the clean one is ignored), runs ``estimate`` with the
shipped DEN of the sRGB noise model, then :func:`~darksynth.refine.refine_profile` on the same image; the
synthesis is the DEN method's, f(v) through the composer on the clean image.
"""

from __future__ import annotations

from pathlib import Path

import torch

from darksynth.evaluation.methods import NoiseMethod, load_den_weights
from darksynth.evaluation.srgb_fit import synthesize_image
from darksynth.noise.values import NoiseValues
from darksynth.refine import analysis_crop, den_denoise, refine_profile


def refined_den_method(name: str, weights: Path, device: str, *, decoder_denoiser: bool = False) -> NoiseMethod:
    """The ``den-refined`` method with the DEN weights at ``weights``.

    Args:
        decoder_denoiser: take the DEN decoder's dark clean output as the denoised reference instead of the
            refinement's Gaussian filter.

    Raises:
        MethodUnavailableError: the weights do not exist or cannot be read.
    """
    from darksynth.estimate import estimate

    network = load_den_weights(name, weights, device)

    def fit(noisy: torch.Tensor, clean: torch.Tensor) -> NoiseValues:
        reference = noisy.to(torch.float32)[None]
        initial = estimate(reference, network, device=device).profile.noise
        denoised = den_denoise(network, analysis_crop(reference)) if decoder_denoiser else None
        return refine_profile(reference, initial, denoised=denoised)

    denoiser = "the DEN decoder's dark clean output" if decoder_denoiser else "a Gaussian filter"
    return NoiseMethod(
        name=name,
        summary=f"DEN {network.config.variant}, {network.noise_model} noise model ({weights.name}), refined on the "
        f"noisy image by analysis by synthesis ({denoiser} as the clean stand-in)",
        fit=fit,
        synthesize=synthesize_image,
        details={"weights": str(weights)},
    )
