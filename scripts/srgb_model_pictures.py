"""Pictures of the sRGB model's components, and of real low-light noise beside what the DEN makes of it.

Run: ``.venv/bin/python scripts/srgb_model_pictures.py [--data ../shared/data] [--out docs/images]``.

Two PNG files, both made only from permissively licensed material, so both may be committed:

- ``srgb-components.png``: one crop per step of the model, each adding one component to the last, on a flat
  grey patch (level 0.3) with the noise amplified GAIN times around mid-grey: the paper's white noise, then
  per-channel gains, spatial correlation, channel correlations and JPEG compression, each titled with its
  parameter. Synthetic only.
- ``lol-real-vs-synthetic.png``: per LOL image (MIT licence; real dark photographs without a clean image),
  a crop of the real image | the profile ``estimate`` writes from that image (sRGB DEN refined on the reference,
  the default) applied to a clean Set8 frame (MIT) as ``apply`` does | the sRGB network's values alone
  (``--no-refine``) | the paper's DEN. All are
  brightened by the same factor (BRIGHTEN) so the noise shows
  as it does when a dark image is viewed brightened; the scenes differ, the noise's look is what to compare.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.io.images import read_image
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.synthesize import synthesize
from darksynth.training.weights import default_weights_path, load_weights

CROP = 96
GAIN = 4.0
BRIGHTEN = 4.0
LOL_IMAGES = ("1.png", "111.png", "146.png")
CLEAN_FRAME = Path("clean/videos/rafting/01.png")

STEPS: tuple[tuple[str, dict[str, list[float]]], ...] = (
    ("paper: white, read 0.03", {"read": [0.03]}),
    ("+ channel_gain [1.8, 1.8]", {"channel_gain": [1.8, 1.8]}),
    ("+ correlation_length 1.5 px", {"correlation_length": [1.5]}),
    ("+ channel_correlation 0.7", {"channel_correlation": [0.7, 0.7, 0.7]}),
    ("+ compression 0.6 (JPEG q 40)", {"compression": [0.6]}),
)


def component_panels() -> list[tuple[str, np.ndarray]]:
    values = NoiseValues.neutral(dtype=torch.float32)
    panels = []
    for title, change in STEPS:
        values = values.replace(**change)
        signal = torch.full((1, 3, CROP, CROP), 0.3)
        noisy = add_noise(signal, values, generator=torch.Generator().manual_seed(0))[0]
        shown = (0.5 + GAIN * (noisy - 0.3)).clamp(0, 1)
        panels.append((title, shown.permute(1, 2, 0).numpy()))
    return panels


def _crop(image: np.ndarray) -> np.ndarray:
    top, left = (image.shape[0] - CROP * 2) // 2, (image.shape[1] - CROP * 2) // 2
    return image[top : top + CROP * 2, left : left + CROP * 2]


def lol_rows(data: Path) -> list[list[tuple[str, np.ndarray]]]:
    models = {name: load_weights(default_weights_path("v3", name)) for name in ("srgb", "paper")}
    clean = read_image(data / CLEAN_FRAME).pixels
    rows = []
    for name in LOL_IMAGES:
        reference = load_reference(data / "real-lowlight/images/lol" / name)
        real = reference[0].permute(1, 2, 0).numpy()
        row = [(f"real LOL {name}", _crop(np.clip(real * BRIGHTEN, 0, 1)))]
        variants: list[tuple[str, Profile]] = [
            ("estimate (srgb, refined)", estimate(reference, models["srgb"]).profile),
            ("srgb network alone", estimate(reference, models["srgb"], refine=False).profile),
            ("paper DEN", estimate(reference, models["paper"]).profile),
        ]
        for title, chosen in variants:
            result = synthesize(clean, chosen, generator=torch.Generator().manual_seed(0))
            image = np.asarray(result.image, dtype=np.float64) / 255.0
            row.append((f"{title} on a clean frame", _crop(np.clip(image * BRIGHTEN, 0, 1))))
        rows.append(row)
    return rows


def save_grid(rows: list[list[tuple[str, np.ndarray]]], path: Path) -> None:
    columns = max(len(row) for row in rows)
    figure, axes = plt.subplots(len(rows), columns, figsize=(2.4 * columns, 2.7 * len(rows)), squeeze=False)
    for r, row in enumerate(rows):
        for c in range(columns):
            axis = axes[r][c]
            axis.axis("off")
            if c < len(row):
                title, image = row[c]
                axis.imshow(image, interpolation="nearest")
                axis.set_title(title, fontsize=8)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=80)
    plt.close(figure)
    print(f"wrote {path}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "images")
    parser.add_argument("--skip-lol", action="store_true", help="only the synthetic component picture")
    args = parser.parse_args()
    save_grid([component_panels()], args.out / "srgb-components.png")
    if not args.skip_lol:
        save_grid(lol_rows(args.data), args.out / "lol-real-vs-synthetic.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
