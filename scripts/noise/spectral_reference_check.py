"""The blind spectral estimate on the shared real low-light references: level check and real-vs-synthetic crops.

Makes: docs/spectral-noise.md, "Measured" (the bullet "Level on the shared real references": real over synthetic
flat-block std per reference, and the picture docs/images/spectral-real-vs-synthetic.png), and the same figures
in "Dark, clipped and textured references" and "What the measurement now says it could not read".

Run from the repo root::

    .venv/bin/python scripts/noise/spectral_reference_check.py --data ../shared/data
    .venv/bin/python scripts/noise/spectral_reference_check.py --data ../shared/data --kinds lol,starlight \
        --picture docs/images/spectral-real-vs-synthetic.png

Options: ``[--data ../shared/data] [--picture OUT.png] [--kinds lol,starlight,lime,clips,dicm] [--only NAMES]``.

For every reference (LOL and LIME images, with ``--kinds dicm`` the DICM night photos, the phone clips' first 4
frames, the starlight video's first 16): the profile ``estimate`` writes (spectral, the default), then that profile
applied with ``--no-darken`` to the reference's own non-local-means denoised version (the denoiser and strength of
the estimate). Printed per
reference: the noise std of the 10% flattest 32-px blocks with at most 1% clipped pixels (crushed black holds no
noise to compare), real over synthetic (1.00: the same; above 1.25 the profile misses noise, below 0.8 it reads
texture as noise), and the same for the network's values alone (``estimate(..., refine=False)``; when the committed
picture was made, before the version-3 model was retired, that column was the version-3 profile). The picture puts
a 128-px crop of the real reference beside the same crop of both synthetic versions, all three brightened by one
gain (the real crop's 99th percentile to 0.9); ``--kinds lol,starlight`` limits it to permissively licensed
references (LOL: MIT; the starlight video: BSD-3), the picture that may be committed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image, ImageDraw

from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK, STRENGTH_CLIPPED_SHARE, clipped_share, denoiser_strength
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.reference import load_reference
from darksynth.noise.simulate import add_noise
from darksynth.training.weights import default_weights_path, load_weights

CROP = 128


def flattest_block_std(frame: torch.Tensor, usable: torch.Tensor | None = None) -> float:
    """Std in 8-bit levels of the 10% flattest 32-px blocks of ``frame`` (3, H, W) among the ``usable`` ones (all by
    default), flatness judged on a 5-px mean so that the noise itself does not decide it."""
    blocks = F.unfold(frame[:, None], FLAT_BLOCK, stride=FLAT_BLOCK).std(dim=1).mean(0)
    smooth = F.avg_pool2d(frame[None], 5, stride=1, padding=2)[0].mean(0)
    dx = (smooth[:, 1:] - smooth[:, :-1]).abs()[:-1]
    dy = (smooth[1:] - smooth[:-1]).abs()[:, :-1]
    gradient = F.avg_pool2d(F.pad(dx + dy, (0, 1, 0, 1))[None, None], FLAT_BLOCK)[0, 0].flatten()[: blocks.numel()]
    if usable is not None and bool(usable.any()):
        blocks, gradient = blocks[usable], gradient[usable]
    count = max(1, round(0.1 * gradient.numel()))
    return float(blocks[gradient.argsort()[:count]].median()) * 255.0


def references(data: Path, kinds: set[str]) -> list[tuple[str, Path, bool]]:
    found: list[tuple[str, Path, bool]] = []
    low = data / "real-lowlight"
    if "lol" in kinds:
        found += [("lol", p, False) for p in sorted((low / "images" / "lol").glob("*"))[:4]]
    if "lime" in kinds:
        found += [("lime", p, False) for p in sorted((low / "images" / "lime").glob("*"))[:4]]
    if "dicm" in kinds:
        found += [("dicm", p, False) for p in sorted((low / "images" / "dicm").glob("*"))]
    if "clips" in kinds:
        found += [("clip", p, True) for p in sorted((low / "clips").glob("clip*"))]
    if "starlight" in kinds:
        found += [("starlight", low / "videos" / "starlight_submillilux.mov", False)]
    return found


def crop_at_flattest(frame: torch.Tensor) -> tuple[int, int]:
    """Top-left of the CROP x CROP window of ``frame`` with the least mean gradient (on a 5-px mean)."""
    smooth = F.avg_pool2d(frame[None], 5, stride=1, padding=2)[0].mean(0)
    gradient = (smooth[:, 1:] - smooth[:, :-1]).abs()[:-1] + (smooth[1:] - smooth[:-1]).abs()[:, :-1]
    pooled = F.avg_pool2d(gradient[None, None], CROP, stride=CROP // 4)[0, 0]
    index = int(pooled.argmin())
    return (index // pooled.shape[1]) * (CROP // 4), (index % pooled.shape[1]) * (CROP // 4)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--picture", type=Path, default=None)
    parser.add_argument("--kinds", default="lol,starlight,lime,clips")
    parser.add_argument("--only", default=None, help="comma-separated reference names (file or folder) to check")
    arguments = parser.parse_args()
    network = load_weights(default_weights_path())
    rows: list[list[np.ndarray]] = []
    labels: list[str] = []
    chosen = references(arguments.data, set(arguments.kinds.split(",")))
    if arguments.only:
        chosen = [entry for entry in chosen if entry[1].name in arguments.only.split(",")]
    for kind, path, folder in chosen:
        frames = load_reference(path, clip=folder, max_frames=16)
        first = frames[:1]
        denoised = nlm_denoise(first, denoiser_strength(first))
        # Blocks the real camera clipped (crushed black, a lamp) hold no noise to compare: both sides are judged on
        # the blocks of the reference with at most 1 % clipped pixels.
        usable = (clipped_share(first[0]) <= STRENGTH_CLIPPED_SHARE).flatten()
        real_std = flattest_block_std(first[0], usable)
        line, row = [], []
        top, left = crop_at_flattest(first[0])
        real_crop = first[0, :, top : top + CROP, left : left + CROP]
        gain = 0.9 / max(float(real_crop.quantile(0.99)), 1e-3)
        row.append(real_crop)
        for measured in (True, False):
            profile = estimate(frames, network, source=str(path), options=NoiseEstimateOptions(refine=measured)).profile
            values = profile.noise.to(dtype=torch.float32)
            synthetic = quantised(add_noise(denoised[None], values, generator=torch.Generator().manual_seed(0))[0])
            ratio = real_std / max(flattest_block_std(synthetic[0], usable), 1e-6)
            line.append(f"{'spectral' if measured else 'network'} {ratio:.2f}")
            row.append(synthetic[0, :, top : top + CROP, left : left + CROP])
        print(f"{kind:9s} {path.name:28s} real std {real_std:5.2f}  real/synthetic: {'  '.join(line)}", flush=True)
        rows.append([(c * gain).clamp(0, 1).permute(1, 2, 0).numpy() for c in row])
        labels.append(f"{kind} {path.stem[:16]} x{gain:.1f}")
    if arguments.picture is not None and rows:
        write_picture(rows, labels, arguments.picture)


def write_picture(rows: list[list[np.ndarray]], labels: list[str], out: Path) -> None:
    gap, head = 6, 18
    width = 3 * CROP + 4 * gap
    sheet = Image.new("RGB", (width, head + len(rows) * (CROP + head)), "white")
    draw = ImageDraw.Draw(sheet)
    for column, title in enumerate(("real reference", "spectral (default)", "network alone")):
        draw.text((gap + column * (CROP + gap), 3), title, fill="black")
    for index, (row, label) in enumerate(zip(rows, labels, strict=True)):
        y = head + index * (CROP + head)
        draw.text((gap, y + 2), label, fill="black")
        for column, crop in enumerate(row):
            tile = Image.fromarray((crop * 255).round().astype(np.uint8))
            sheet.paste(tile, (gap + column * (CROP + gap), y + head - 4))
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
