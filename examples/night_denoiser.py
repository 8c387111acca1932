"""A denoiser for one camera's night images, trained on darksynth data made from a few of its night photos.

The user's workflow, end to end (docs/tutorial.md walks through it):

1. ``darksynth estimate`` on a few noisy photos of one camera (here: ``--references`` noisy images of the camera
   ``--camera`` in a real pair set; the set's other pairs of that camera are kept for the test);
2. a PyTorch ``Dataset`` of random crops of clean images, made noisy by ``darksynth.transforms.LowLight`` with one of
   those profiles at random, read through a ``DataLoader`` with workers (``torch.manual_seed`` fixes the whole run,
   workers included);
3. a small residual denoiser trained on it (a progress bar per method), and the same denoiser trained on the
   alternatives a user would reach for: blind Gaussian noise (DnCNN-B's 0-55 levels) and albumentations'
   ``GaussNoise``, ``ISONoise`` and ``GaussNoise`` + ``ImageCompression`` with their documented defaults;
4. every denoiser tested on the camera's real test pairs (PSNR, SSIM against the clean image, and the noisy input as
   it is), written to ``OUT/results.json`` and drawn beside each other in ``OUT/comparison.png``.

Run from the repository root (a CPU, a few minutes with the defaults)::

    .venv/bin/python examples/night_denoiser.py --out night-denoiser

With a GPU, a DnCNN-sized net and a longer training::

    .venv/bin/python examples/night_denoiser.py --device cuda --width 64 --depth 17 --steps 20000 --batch 16 \\
        --out night-denoiser-gpu

Options: ``--pairs DIR`` (a real pair set: ``noisy/NAME``, ``clean/NAME``; default the shared ``sidd-phones``),
``--camera TEXT`` (the pairs whose name holds it: one camera; default ``_GP_``, the Google Pixel),
``--references N`` (its noisy images the profiles come from; default 3), ``--pick spread|first`` (those spread evenly
over the camera's pairs in name order, the default, or its first N), ``--clean DIR``
(repeatable; clean training images, default the shared Kodak and CBSD68), ``--methods``, ``--steps``, ``--batch``,
``--crop``, ``--width``, ``--depth``, ``--workers``, ``--seed``, ``--device``.
"""

from __future__ import annotations

import argparse
import json
import random
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from darksynth.io.atomic import atomic_output, write_text_atomic

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DEFAULT_PAIRS = SHARED / "real-pairs" / "sidd-phones"
DEFAULT_CLEAN = (SHARED / "clean" / "images" / "kodak24", SHARED / "clean" / "images" / "cbsd68")
METHODS = ("darksynth", "gaussian", "albu-gauss", "albu-iso", "albu-gauss-jpeg")
"""What the denoiser is trained on: darksynth's noise from the estimated profiles; Gaussian noise of 0-55 levels
(a blind DnCNN's range); albumentations' GaussNoise, ISONoise and GaussNoise + ImageCompression at their documented
default ranges (the methods of `darksynth evaluate` of those names)."""

Noise = Callable[[torch.Tensor, int], torch.Tensor]
"""A training noise: a clean crop (3, H, W) float in [0, 1] and the sample's seed -> its noisy version."""


class ExampleError(Exception):
    """Bad input: one line for the user, exit status 2."""


def camera_pairs(pairs_root: Path, camera: str, references: int, pick: str) -> tuple[list[Path], list[Any]]:
    """``references`` noisy images of the camera (the user's night photos) and its other pairs (the test): spread
    evenly over its pairs in name order (``pick="spread"``), or its first ones (``"first"``)."""
    from darksynth.errors import DarksynthError
    from darksynth.evaluation.pairs import list_pair_set

    try:
        listed = list_pair_set(pairs_root).pairs
    except DarksynthError as error:
        raise ExampleError(f"{pairs_root}: {error}") from None
    chosen = [pair for pair in listed if camera in pair.name]
    if len(chosen) <= references:
        raise ExampleError(
            f"{pairs_root}: {len(chosen)} pairs name {camera!r}; {references} references and at least one test pair "
            "are needed"
        )
    if pick == "first":
        indices = list(range(references))
    else:
        indices = sorted({int((k + 0.5) * len(chosen) / references) for k in range(references)})
    return [chosen[i].noisy_path for i in indices], [pair for i, pair in enumerate(chosen) if i not in indices]


def estimate_profiles(references: list[Path], folder: Path, device: str) -> list[Path]:
    """``darksynth estimate REFERENCE --out PROFILE`` for each reference, as a user runs it."""
    profiles = []
    for reference in references:
        profile = folder / f"{reference.stem}.json"
        command = [sys.executable, "-m", "darksynth", "estimate", str(reference), "--out", str(profile)]
        finished = subprocess.run([*command, "--device", device], capture_output=True, text=True, check=False)
        if finished.returncode != 0:
            raise ExampleError(f"{reference}: darksynth estimate failed: {finished.stderr.strip().splitlines()[-1]}")
        profiles.append(profile)
    return profiles


def read_clean_images(folders: list[Path], crop: int) -> list[torch.Tensor]:
    """Every image of the folders with both sides at least ``crop``, as uint8 tensors (3, H, W)."""
    from darksynth.io.images import read_image

    images = []
    for folder in folders:
        if not folder.is_dir():
            raise ExampleError(f"{folder}: no such folder of clean images")
        for path in sorted(folder.iterdir()):
            if path.suffix.lower() in (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"):
                pixels = np.asarray(read_image(path).pixels)
                if pixels.ndim == 3 and pixels.shape[2] == 3 and min(pixels.shape[:2]) >= crop:
                    images.append(torch.from_numpy(np.ascontiguousarray(pixels.transpose(2, 0, 1))))
    if not images:
        raise ExampleError(f"{', '.join(map(str, folders))}: no RGB image with both sides of at least {crop} px")
    return images


class NoisyCrops(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """``length`` random crops of the clean images, each made noisy by ``noise``; sample ``i`` is the same in every
    worker and run of a seed (its crop and its noise come from ``seed`` and ``i`` alone)."""

    def __init__(self, images: list[torch.Tensor], noise: Noise, crop: int, length: int, seed: int) -> None:
        self.images, self.noise, self.crop, self.length, self.seed = images, noise, crop, length, seed

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, index: int) -> tuple[torch.Tensor, torch.Tensor]:
        draw = random.Random(self.seed * 1_000_003 + index)
        image = self.images[draw.randrange(len(self.images))]
        top = draw.randrange(image.shape[1] - self.crop + 1)
        left = draw.randrange(image.shape[2] - self.crop + 1)
        clean = image[:, top : top + self.crop, left : left + self.crop].float() / 255.0
        if draw.random() < 0.5:
            clean = clean.flip(-1)
        return self.noise(clean, self.seed * 1_000_003 + index).float(), clean


def darksynth_noise(profiles: list[Path]) -> Noise:
    """darksynth's transform with one of the profiles at random; no darkening (the test pairs share brightness)."""
    from darksynth.transforms import LowLight

    transforms = [LowLight(path, darkening=None) for path in profiles]

    def noise(clean: torch.Tensor, seed: int) -> torch.Tensor:
        return transforms[seed % len(transforms)](clean, seed=seed)

    return noise


def gaussian_noise(clean: torch.Tensor, seed: int) -> torch.Tensor:
    """Gaussian noise of a std drawn in 0-55 8-bit levels per crop, rounded to 8-bit levels."""
    generator = torch.Generator().manual_seed(seed)
    std = float(torch.rand((), generator=generator)) * 55.0 / 255.0
    noisy = clean + std * torch.randn(clean.shape, generator=generator)
    return (noisy.clamp(0.0, 1.0) * 255.0).round() / 255.0


def albumentations_noise(name: str) -> Noise:
    """albumentations' transforms of the `darksynth evaluate` method ``name``, at their default ranges."""
    from darksynth.evaluation.methods.catalogue import build_method

    method = build_method(name)

    def noise(clean: torch.Tensor, seed: int) -> torch.Tensor:
        noisy: torch.Tensor = method.synthesize(clean.double(), None, torch.Generator().manual_seed(seed))
        return noisy.float()

    return noise


def training_noise(method: str, profiles: list[Path]) -> Noise:
    if method == "darksynth":
        return darksynth_noise(profiles)
    if method == "gaussian":
        return gaussian_noise
    if method.startswith("albu-"):
        return albumentations_noise(method)
    raise ExampleError(f"unknown method {method!r}: one of {', '.join(METHODS)}")


def train(dataset: NoisyCrops, arguments: argparse.Namespace, label: str) -> torch.nn.Module:
    """The residual denoiser of ``--width`` x ``--depth`` trained with Adam and an L1 loss, cosine-decayed, one pass
    over ``dataset`` in batches of ``--batch``; the same initial weights for every method."""
    from rich.progress import Progress

    from darksynth.evaluation.measures.denoiser import ResidualDenoiser

    model = ResidualDenoiser(arguments.width, arguments.depth, seed=arguments.seed).to(arguments.device)
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, arguments.steps)
    loader = DataLoader(dataset, batch_size=arguments.batch, num_workers=arguments.workers, shuffle=False)
    with Progress(transient=True) as progress:
        task = progress.add_task(f"training on {label}", total=arguments.steps)
        for noisy, clean in loader:
            loss: torch.Tensor = torch.nn.functional.l1_loss(
                model(noisy.to(arguments.device)), clean.to(arguments.device)
            )
            optimiser.zero_grad()
            loss.backward()  # type: ignore[no-untyped-call]
            optimiser.step()
            schedule.step()
            progress.update(task, advance=1, description=f"training on {label}: loss {loss.detach().item():.4f}")
    return model


def test(model: torch.nn.Module | None, test_pairs: list[Any]) -> dict[str, float]:
    """Mean PSNR and SSIM over the test pairs of the model's output (None: the noisy input as it is)."""
    from darksynth.evaluation.measures.denoiser import denoise
    from darksynth.evaluation.measures.downstream import image_scores
    from darksynth.evaluation.pairs import load_pair

    rows = []
    for pair in test_pairs:
        loaded = load_pair(pair)
        output = loaded.noisy if model is None else denoise(model, loaded.noisy)
        rows.append(image_scores(output, loaded.clean))
    return {key: float(np.mean([row[key] for row in rows])) for key in ("psnr", "ssim")}


def plot(results: dict[str, dict[str, float]], path: Path, title: str) -> None:
    """PSNR and SSIM per training noise, as bars, the noisy input as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = [name for name in results if name != "noisy input"]
    figure, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for axis, key, unit in ((axes[0], "psnr", "PSNR (dB)"), (axes[1], "ssim", "SSIM")):
        axis.bar(methods, [results[name][key] for name in methods], color="#4c72b0")
        axis.axhline(results["noisy input"][key], color="#c44e52", linestyle="--", label="noisy input")
        low = min(results[name][key] for name in results)
        axis.set_ylim(low - (2.0 if key == "psnr" else 0.05), None)
        axis.set_ylabel(unit)
        axis.tick_params(axis="x", rotation=20)
        axis.legend(loc="lower right", fontsize=8)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    with atomic_output(path) as temporary:
        figure.savefig(temporary, dpi=120, format="png")
    plt.close(figure)


def run(arguments: argparse.Namespace) -> dict[str, Any]:
    references, test_pairs = camera_pairs(arguments.pairs, arguments.camera, arguments.references, arguments.pick)
    arguments.out.mkdir(parents=True, exist_ok=True)
    (arguments.out / "profiles").mkdir(exist_ok=True)
    profiles = estimate_profiles(references, arguments.out / "profiles", arguments.device)
    images = read_clean_images(arguments.clean, arguments.crop)
    results: dict[str, dict[str, float]] = {"noisy input": test(None, test_pairs)}
    for method in arguments.methods:
        torch.manual_seed(arguments.seed)
        dataset = NoisyCrops(
            images, training_noise(method, profiles), arguments.crop, arguments.steps * arguments.batch, arguments.seed
        )
        results[method] = test(train(dataset, arguments, method), test_pairs)
        print(f"{method:22s} PSNR {results[method]['psnr']:6.2f} dB  SSIM {results[method]['ssim']:.4f}", flush=True)
    record = {
        "pairs": str(arguments.pairs),
        "camera": arguments.camera,
        "pick": arguments.pick,
        "references": [str(path) for path in references],
        "test_pairs": [pair.name for pair in test_pairs],
        "settings": {
            key: getattr(arguments, key) for key in ("steps", "batch", "crop", "width", "depth", "seed", "device")
        },
        "results": results,
    }
    write_text_atomic(arguments.out / "results.json", json.dumps(record, indent=2) + "\n")
    title = f"{arguments.camera.strip('_')} of {arguments.pairs.name}: {len(test_pairs)} real test pairs"
    plot(results, arguments.out / "comparison.png", title)
    return record


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=Path, default=DEFAULT_PAIRS)
    parser.add_argument("--camera", default="_GP_")
    parser.add_argument("--references", type=int, default=3)
    parser.add_argument("--pick", choices=("spread", "first"), default="spread")
    parser.add_argument("--clean", type=Path, action="append", default=None)
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--crop", type=int, default=64)
    parser.add_argument("--width", type=int, default=16)
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, required=True)
    arguments = parser.parse_args(argv)
    arguments.clean = arguments.clean or list(DEFAULT_CLEAN)
    arguments.methods = [name for name in arguments.methods.split(",") if name]
    unknown = [name for name in arguments.methods if name not in METHODS]
    if unknown or arguments.steps < 1 or arguments.batch < 1 or arguments.references < 1:
        parser.error(f"methods are {', '.join(METHODS)}; steps, batch and references at least 1")
    return arguments


def main(argv: list[str] | None = None) -> int:
    arguments = parse(argv)
    try:
        run(arguments)
    except ExampleError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {arguments.out / 'results.json'} and {arguments.out / 'comparison.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
