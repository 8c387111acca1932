"""Pictures of real noise beside synthetic noise, for docs/srgb-noise.md.

Run: ``.venv/bin/python scripts/srgb_noise_pictures.py --pairs ../shared/data/real-pairs/polyu
--pairs ../shared/data/real-pairs/nam-cc15 --pairs ../shared/data/real-pairs/sidd [--lol]``; pictures go to
``--out`` (default /tmp/srgb_noise_pictures, outside the repository).

Licences decide what may be committed: the real-pair sets (polyu, nam-cc15: non-commercial; sidd: SIDD terms)
must not be copied into the repository, so none of these pictures is committed (docs/srgb-noise.md describes
them). For each ``--pairs DIR``, the first pair of the set gives three panels of noise (noisy - clean): real |
white heteroscedastic noise (the table's model with its structure and compression left out) fitted with the
clean image | the table's whole sRGB model fitted with the clean image
(:func:`~darksynth.evaluation.srgb_fit.fit_srgb_noise`), both drawn through the composer ``add_noise``.

``--lol`` adds the MIT-licensed LOL low-light images (``real-lowlight/images/lol``), which have no clean image
and could be committed; but the fit is then biased (see below), so they are not. For those, the clean image
is replaced by a
Gaussian blur (std BLUR pixels) of the dark image, the extended model is fitted against it with
:func:`~darksynth.evaluation.srgb_fit.fit_srgb_noise`, and every panel shows the same high-pass
``image - blur(image)`` of: the real dark image | white heteroscedastic noise on the blurred image | the whole
sRGB model's noise on the blurred image. Each panel is a CROP x CROP crop from the flattest part of the
image, amplified GAIN times around mid-grey. The blur removes the correlated part of the real noise from
the residual the model is fitted to, so the fitted gains and JPEG quality are wrong and the extended panel comes
out too strong: these pictures show the texture of real dark noise, not a validation of the model.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

from darksynth.evaluation.pairs import list_pair_set, load_pair
from darksynth.evaluation.srgb_fit import WHITE, fit_srgb_noise, synthesize_image
from darksynth.noise.correlated import gaussian_kernel1d

CROP = 96
GAIN = 5.0
BLUR = 2.0
LOL_IMAGES = ("1.png", "111.png", "146.png")


def blur(image: torch.Tensor, length: float = BLUR) -> torch.Tensor:
    kernel = gaussian_kernel1d(length, dtype=image.dtype)
    radius = kernel.numel() // 2
    padded = F.pad(image[:, None], (radius, radius, radius, radius), mode="reflect")
    padded = F.conv2d(padded, kernel.view(1, 1, 1, -1))
    return F.conv2d(padded, kernel.view(1, 1, -1, 1))[:, 0]


def flattest_crop(image: torch.Tensor) -> tuple[int, int]:
    """Top-left corner of the CROP x CROP window with the least local texture (gradient energy of the blur)
    among the windows brighter than the median window (the darkest ones are clipped at black)."""
    smooth = blur(image, 4.0).mean(0)
    texture = (smooth[1:, :-1] - smooth[:-1, :-1]).square() + (smooth[:-1, 1:] - smooth[:-1, :-1]).square()
    pooled = F.avg_pool2d(texture[None, None], CROP, stride=16)[0, 0]
    level = F.avg_pool2d(smooth[None, None, :-1, :-1], CROP, stride=16)[0, 0]
    pooled = torch.where(level >= level.median(), pooled, torch.inf)
    index = int(torch.argmin(pooled))
    return (index // pooled.shape[1]) * 16, (index % pooled.shape[1]) * 16


def panel(noise: torch.Tensor, top: int, left: int) -> np.ndarray:
    crop = noise[:, top : top + CROP, left : left + CROP]
    return ((0.5 + GAIN * crop).clamp(0, 1) * 255).round().to(torch.uint8).permute(1, 2, 0).numpy()


def save(panels: list[np.ndarray], path: Path) -> None:
    gap = np.full((CROP, 4, 3), 255, dtype=np.uint8)
    row = np.concatenate([p for pair in zip(panels, [gap] * len(panels), strict=True) for p in pair][:-1], axis=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(row).save(path, optimize=True)
    print(f"{path} ({path.stat().st_size // 1024} KB)")


def three_panels(noisy: torch.Tensor, clean: torch.Tensor, high_pass: bool, seed: int) -> list[torch.Tensor]:
    white = fit_srgb_noise(noisy, clean, WHITE)
    extended = fit_srgb_noise(noisy, clean)
    print(f"  fitted: {extended.to_json()}")
    images = [
        noisy,
        synthesize_image(clean, white, torch.Generator().manual_seed(seed)),
        synthesize_image(clean, extended, torch.Generator().manual_seed(seed)),
    ]
    return [image - blur(image) if high_pass else image - clean for image in images]


def load_rgb(path: Path) -> torch.Tensor:
    array = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    return torch.from_numpy(array).permute(2, 0, 1).contiguous()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    root = Path(__file__).resolve().parents[1]
    parser.add_argument("--data", type=Path, default=root.parent / "shared" / "data")
    parser.add_argument("--out", type=Path, default=Path("/tmp/srgb_noise_pictures"))
    parser.add_argument("--pairs", type=Path, action="append", default=[])
    parser.add_argument("--lol", action="store_true", help="also the LOL images (no clean image: biased fit)")
    args = parser.parse_args()
    for name in LOL_IMAGES if args.lol else ():
        noisy = load_rgb(args.data / "real-lowlight" / "images" / "lol" / name)
        print(f"lol/{name}")
        noises = three_panels(noisy, blur(noisy), high_pass=True, seed=0)
        top, left = flattest_crop(noisy)
        save([panel(n, top, left) for n in noises], args.out / f"srgb-noise-lol-{Path(name).stem}.png")
    for pairs in args.pairs:
        pair_set = list_pair_set(pairs)
        loaded = load_pair(pair_set.pairs[0])
        print(f"{pair_set.name}/{loaded.pair.name}")
        noises = three_panels(loaded.noisy, loaded.clean, high_pass=False, seed=0)
        top, left = flattest_crop(loaded.clean)
        save([panel(n, top, left) for n in noises], args.out / f"srgb-noise-{pair_set.name}.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
