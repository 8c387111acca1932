"""A real moving region of a low-light clip beside darksynth's blur of a clean video with the clip's profile, with and
without blur, brightened by one common gain.

Makes: docs/images/motion-real-vs-synthetic.png, in docs/motion-blur.md, "Real scenes with a known blur".

Run from the repo root (P.json: ``darksynth estimate ../shared/data/real-lowlight/clips/clip1021 --clip``'s
profile)::

    PYTHONPATH=src .venv/bin/python scripts/light/motion_pictures.py --profile P.json \
        --clip ../shared/data/real-lowlight/clips/clip1021 --video ../shared/data/clean/videos/bikes.mp4

Options: ``--profile P.json --clip DIR --video V.mp4 [--out docs/images/motion-real-vs-synthetic.png]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw

import darksynth
from darksynth.estimation.reference import load_reference
from darksynth.io.video import iter_video_frames

SIDE = 256


def crop(frame: np.ndarray, side: int = SIDE) -> np.ndarray:
    top = (frame.shape[0] - side) // 2
    left = (frame.shape[1] - side) // 2
    return frame[top : top + side, left : left + side]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", type=Path, required=True)
    parser.add_argument("--clip", type=Path, required=True)
    parser.add_argument("--video", type=Path, required=True)
    parser.add_argument("--out", type=Path, default=Path("docs/images/motion-real-vs-synthetic.png"))
    args = parser.parse_args()
    profile = darksynth.load_profile(args.profile)
    real = (load_reference(args.clip, clip=True)[1].permute(1, 2, 0).numpy() * 255).round().astype(np.uint8)
    clean = [f for _, f in zip(range(6), iter_video_frames(args.video), strict=False)]
    clip = torch.from_numpy(np.stack(clean)).permute(0, 3, 1, 2).contiguous()
    panels = {}
    for label, light in (("synthetic, blurred", profile), ("synthetic, --no-blur", None)):
        chosen = light or darksynth.profile.without_light(profile, blur=True)
        result = darksynth.synthesize(clip, chosen, generator=torch.Generator().manual_seed(0))
        panels[label] = result.image[2].permute(1, 2, 0).numpy()
    real_crop = crop(real)
    gain = 0.9 * 255 / max(1.0, float(np.percentile(real_crop, 99)))
    sheet = Image.new("RGB", (3 * SIDE + 40, SIDE + 30), "white")
    draw = ImageDraw.Draw(sheet)
    fraction = profile.noise.scalar("exposure_fraction")
    for index, (label, image) in enumerate([("real " + args.clip.name, real_crop), *panels.items()]):
        picture = crop(image) if image.shape[0] >= SIDE else image
        bright = np.clip(picture.astype(np.float64) * gain, 0, 255).astype(np.uint8)
        sheet.paste(Image.fromarray(bright), (index * (SIDE + 20), 30))
        draw.text((index * (SIDE + 20), 8), f"{label} (x{gain:.1f})", fill="black")
    draw.text((SIDE + 20, 20), f"s = {fraction:.2f}", fill="black")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out)
    print(f"wrote {args.out}: gain {gain:.2f}, exposure fraction {fraction:.3f}")


if __name__ == "__main__":
    main()
