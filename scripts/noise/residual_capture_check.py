"""How much of the noise the denoiser's residual holds, on real pairs and on the estimate's re-synthesis, per band,
on flat blocks: where the blind fit's correction by re-synthesis holds and where it does not.

Makes: docs/spectral-noise.md, "What falls short, and what was tried", its bullets on polyu's colour on flat blocks,
on the JPEG stage's base and (``--channels``) on green on the DSLR pairs.

Run from the repo root::

    .venv/bin/python scripts/noise/residual_capture_check.py --pairs ../shared/data/real-pairs/polyu --every 7

Options: ``--pairs DIR [--every K] [--strengths F,F,...] [--channels]``.

For each K-th pair in name order: the default ``estimate`` on the noisy image ``y``, its non-local means ``D(y)`` at
the estimate's strength, and on the 30% flattest 32-px blocks of the clean image ``x``
(``darksynth.noise.texture.block_detail``) the power of the three finest octave bands (1.4-4, 4-8, 8-16 px) of
brightness and colour (``evaluation.measures.structure``'s components and bands, each band-passed over the whole
image and averaged over the blocks) of:

* the real noise ``y - x`` and the real residual ``y - D(y)``: their ratio is how much of the real noise the
  residual holds (the capture of the real);
* the profile's noise on ``D(y)`` as the fit simulates it (``s = D(y) + n``, quantised) and its residual
  ``s - D(s)``: their ratio is the capture the fit assumes (the capture of the re-synthesis);
* the profile applied to ``x`` by ``apply --no-darken``, over the real noise (what ``benchmarks/real_data.py``
  judges, here on flat blocks);
* the re-synthesis's noise ``s - D(y)`` and the same draw put on ``x`` (``add_noise``, quantised), over the real
  noise: whether the simulated noise depends on the base it is put on (the JPEG stage's does: docs/spectral-noise.md).

With ``--strengths``, also the real residual over the re-synthesis's at the denoiser's strength times each factor:
whether a second denoiser would show the real noise behaving unlike the model's where the fit cannot (it does not:
docs/spectral-noise.md).

Also ``x - D(y)`` over the real noise: what the residual holds besides the noise (the scene the denoiser took off,
and, as less, the noise it left). With ``--channels`` every figure is per channel (red, green, blue) in place of
brightness and colour.

The fit makes the re-synthesis's residual match the real one, so where the re-synthesis captures more than the real,
the profile's noise comes out weaker than the real by about that factor. Printed: one line per pair (colour), then
the medians over pairs.
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path
from typing import Any

import numpy as np
import torch

from darksynth.apply import ApplyOptions, synthesize_image
from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.reference import load_reference
from darksynth.evaluation.measures.structure import COMPONENTS, band_index, brightness_colour_components
from darksynth.io.arrays import chw_to_hwc, hwc_to_chw
from darksynth.noise.simulate import add_noise
from darksynth.noise.texture import TEXTURE_BLOCK, block_detail, textured_and_flat
from darksynth.recipe import ClipRecipe
from darksynth.training.weights import default_weights_path, load_weights

FINE_BANDS = 3


def band_powers(noise: torch.Tensor, mask: np.ndarray[Any, Any], channels: bool = False) -> np.ndarray[Any, Any]:
    """(2, FINE_BANDS): brightness and colour (the mean of the two colour components) power per band of ``noise``
    (3, H, W), band-passed over the whole image and averaged over ``mask``; with ``channels``, (3, FINE_BANDS): red,
    green and blue."""
    if channels:
        planes = noise.double().numpy()
        planes = planes - planes.mean(axis=(1, 2), keepdims=True)
    else:
        planes = np.stack(brightness_colour_components(noise.permute(1, 2, 0).double().numpy()))
    index = band_index(*mask.shape)
    powers = np.zeros((len(planes), FINE_BANDS))
    for number, plane in enumerate(planes):
        spectrum = np.fft.fft2(plane)
        for band in range(FINE_BANDS):
            passed = np.real(np.fft.ifft2(spectrum * (index == band)))
            powers[number, band] = np.mean(passed[mask] ** 2)
    return powers if channels else np.stack([powers[0], powers[1:].mean(axis=0)])


def _flat_mask(clean: torch.Tensor) -> np.ndarray[Any, Any]:
    _, flat = textured_and_flat(block_detail(clean[None].double())[0])
    pixels = flat.repeat_interleave(TEXTURE_BLOCK, 0).repeat_interleave(TEXTURE_BLOCK, 1).numpy()
    mask = np.zeros(clean.shape[-2:], dtype=bool)
    mask[: pixels.shape[0], : pixels.shape[1]] = pixels
    return mask


def pair_ratios(
    noisy_path: Path, clean_path: Path, network: Any, strengths: tuple[float, ...] = (), channels: bool = False
) -> np.ndarray[Any, Any]:
    """(6 + len(strengths), 2 or 3 with ``channels``, FINE_BANDS): the real capture, the re-synthesis's capture, the
    applied profile over the real, the same draw of the profile's noise on ``D(y)`` and on ``x`` over the real,
    ``x - D(y)`` over the real (what the residual holds besides the noise: the scene the denoiser took off, and the
    noise it left, as less), then the real residual over the re-synthesis's at each factor of the denoiser's
    strength."""
    powers = functools.partial(band_powers, channels=channels)
    noisy, clean = load_reference(noisy_path)[0], load_reference(clean_path)[0]
    found = estimate(noisy[None], network, source=noisy_path.name)
    strength = found.profile.meta["spectrum"]["denoiser_strength_8bit"]
    denoised = nlm_denoise(noisy[None], strength)[0]
    mask = _flat_mask(clean)
    real = powers(noisy - clean, mask)
    real_residual = powers(noisy - denoised, mask)
    values = found.profile.noise.to(dtype=torch.float32)
    generator = torch.Generator().manual_seed(3)
    resynthesised = quantised(add_noise(denoised[None, None], values, generator=generator)[0, 0])
    resynthesis = powers(resynthesised - denoised, mask)
    resynthesis_residual = powers(resynthesised - nlm_denoise(resynthesised[None], strength)[0], mask)
    generator = torch.Generator().manual_seed(3)
    on_clean = powers(quantised(add_noise(clean[None, None], values, generator=generator)[0, 0]) - clean, mask)
    pixels = (clean * 255).round().clamp(0, 255).to(torch.uint8)
    options = ApplyOptions(recipe=ClipRecipe(found.profile, darkening=None), seed=0)
    applied = hwc_to_chw(synthesize_image(chw_to_hwc(pixels), clean_path.name, options)[0]).float() / 255
    synthetic = powers(applied - clean, mask)
    at_strengths = [
        powers(noisy - nlm_denoise(noisy[None], strength * factor)[0], mask)
        / powers(resynthesised - nlm_denoise(resynthesised[None], strength * factor)[0], mask)
        for factor in strengths
    ]
    return np.stack(
        [
            real_residual / real,
            resynthesis_residual / resynthesis,
            synthetic / real,
            resynthesis / real,
            on_clean / real,
            powers(clean - denoised, mask) / real,
            *at_strengths,
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=Path, required=True)
    parser.add_argument("--every", type=int, default=1)
    parser.add_argument("--strengths", type=lambda text: tuple(float(part) for part in text.split(",")), default=())
    parser.add_argument("--channels", action="store_true", help="red, green and blue in place of brightness, colour")
    arguments = parser.parse_args()
    torch.set_num_threads(1)
    network = load_weights(default_weights_path())
    rows = []
    for noisy_path in sorted((arguments.pairs / "noisy").iterdir())[:: arguments.every]:
        clean_path = arguments.pairs / "clean" / noisy_path.name
        ratios = pair_ratios(noisy_path, clean_path, network, arguments.strengths, arguments.channels)
        rows.append(ratios)
        shown = "green" if arguments.channels else "colour"
        print(
            f"{noisy_path.name[:36]:36s} {shown}: capture real {np.round(ratios[0, 1], 2)}, re-synthesis "
            f"{np.round(ratios[1, 1], 2)}; applied over real {np.round(ratios[2, 1], 2)}",
            flush=True,
        )
    median = np.median(np.stack(rows), axis=0)
    whats = ["capture of the real", "capture of the re-synthesis", "applied over real"]
    whats += ["noise on D(y) over real", "same draw on x over real", "x - D(y) over real"]
    whats += [f"real/re-synthesis residual x{factor:g}" for factor in arguments.strengths]
    names = ("red", "green", "blue") if arguments.channels else COMPONENTS
    for number, what in enumerate(whats):
        parts = " ".join(f"{name} {np.round(median[number, index], 2)}" for index, name in enumerate(names))
        print(f"median {what:28s} {parts}")


if __name__ == "__main__":
    main()
