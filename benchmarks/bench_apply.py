"""Speed of darkening + f(v) on one 1080p RGB frame against the random-number floor and albumentations.

Run: ``.venv/bin/python benchmarks/bench_apply.py [--rounds N] [--block K]``. Each round times K consecutive
frames of each method in turn (a stream of frames, as in a video), so that a slow moment of the machine hits
all of them alike; medians over all timed frames are printed. The last line is
``apply_ms=<a> floor_ms=<b> albumentations_gauss_ms=<c> srgb_ms=<d> srgb_floor_ms=<e> albumentations_chain_ms=<f>``:

- a: the paper's model, every component on, darkening on, compiled kernel; b: ``torch.randn`` + ``torch.rand`` of
  the frame; c: albumentations ``GaussNoise``;
- d: the default path, the sRGB profile ``estimate`` writes for the shipped demo reference (compression included),
  darkening on, as ``apply`` runs it; e: its floor, ``torch.randn`` + ``torch.rand`` of the frame and a Pillow JPEG
  encode and decode of it at quality 75; f: albumentations ``Compose([GaussNoise, ImageCompression])`` at quality 75.

``--device cuda`` runs the darksynth figures on that device (the floors and albumentations stay on the CPU).
"""

from __future__ import annotations

import argparse
import io
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from darksynth.darkening import Darkening
from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.noise.values import NoiseValues
from darksynth.synthesize import ClipParameters, ClipSynthesizer
from darksynth.training.weights import default_weights_path, load_weights
from machine import cpu_summary

HEIGHT, WIDTH = 1080, 1920
ALL_COMPONENTS = ClipParameters(
    noise=NoiseValues.from_values(
        {
            "shot": 0.06,
            "read": 0.012,
            "quantization": 0.004,
            "banding": 0.004,
            "temporal_banding": 0.003,
            "periodic": 0.002,
        }
    ),
    darkening=Darkening(alpha=0.2, gamma=0.7),
)


DEMO_REFERENCE = Path(__file__).resolve().parents[1] / "src" / "darksynth" / "data" / "sample" / "reference.png"


def demo_srgb_parameters() -> ClipParameters:
    """The profile ``estimate`` writes for the demo reference (default model, refined), with the paper example's
    darkening: the path a user's ``apply`` takes."""
    found = estimate(load_reference(DEMO_REFERENCE, clip=False, max_frames=1), load_weights(default_weights_path()))
    return ClipParameters(noise=found.profile.noise, darkening=ALL_COMPONENTS.darkening)


def jpeg_round_trip(frame_hwc: np.ndarray, quality: int = 75) -> np.ndarray:
    buffer = io.BytesIO()
    Image.fromarray(frame_hwc).save(buffer, format="JPEG", quality=quality)
    buffer.seek(0)
    return np.asarray(Image.open(buffer).convert("RGB"))


def timed(function: Callable[[], object], device: str = "cpu") -> float:
    start = time.perf_counter()
    function()
    if device.startswith("cuda"):
        torch.cuda.synchronize()  # CUDA work is asynchronous: wait for it before reading the clock
    return (time.perf_counter() - start) * 1e3


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=12)
    parser.add_argument("--block", type=int, default=5)
    parser.add_argument("--device", default="cpu", help="torch device of the darksynth figures")
    args = parser.parse_args()
    torch.set_num_threads(2)
    import albumentations  # development dependency, imported here to keep its start-up out of the timings

    rng = np.random.default_rng(0)
    ramp = np.linspace(0, 255, WIDTH, dtype=np.float32)[None, :, None]
    frame_hwc = np.clip(ramp + rng.normal(0, 20, (HEIGHT, WIDTH, 3)), 0, 255).astype(np.uint8)
    frame = torch.from_numpy(frame_hwc).permute(2, 0, 1).contiguous().to(args.device)
    generator = torch.Generator().manual_seed(0)
    srgb = demo_srgb_parameters()
    print(f"demo profile: compression {srgb.noise.scalar('compression'):.2f}, shot {srgb.noise.scalar('shot'):.4f}")

    started = time.perf_counter()
    compiled = ClipSynthesizer(ALL_COMPONENTS, generator=generator, compile=True, device=args.device)
    compiled(frame)
    first_call_s = time.perf_counter() - started
    eager = ClipSynthesizer(ALL_COMPONENTS, generator=generator, compile=False, device=args.device)
    srgb_synthesizer = ClipSynthesizer(srgb, generator=generator, compile=True, device=args.device)
    # What a single image gets: no compilation (apply compiles only for long streams), the general composer.
    srgb_single = ClipSynthesizer(srgb, generator=generator, compile=False, device=args.device)
    gauss = albumentations.GaussNoise(std_range=(0.05, 0.05), p=1.0)
    chain = albumentations.Compose(
        [
            albumentations.GaussNoise(std_range=(0.05, 0.05), p=1.0),
            albumentations.ImageCompression(quality_range=(75, 75), p=1.0),
        ]
    )
    for _ in range(3):
        compiled(frame), eager(frame), gauss(image=frame_hwc), srgb_synthesizer(frame), chain(image=frame_hwc)
        srgb_single(frame)

    shape = (3, HEIGHT, WIDTH)
    methods: dict[str, Callable[[], object]] = {
        "apply": lambda: compiled(frame),
        "floor": lambda: (torch.randn(shape, generator=generator), torch.rand(shape, generator=generator)),
        "gauss": lambda: gauss(image=frame_hwc),
        "eager": lambda: eager(frame),
        "srgb": lambda: srgb_synthesizer(frame),
        "srgb_floor": lambda: (
            torch.randn(shape, generator=generator),
            torch.rand(shape, generator=generator),
            jpeg_round_trip(frame_hwc),
        ),
        "chain": lambda: chain(image=frame_hwc),
        "srgb_single": lambda: srgb_single(frame),
    }
    results: dict[str, list[float]] = {name: [] for name in methods}
    for _ in range(args.rounds):
        for name, method in methods.items():
            results[name].extend(timed(method, args.device) for _ in range(args.block))
    median = {name: statistics.median(values) for name, values in results.items()}
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, frame {WIDTH}x{HEIGHT} RGB uint8")
    print(f"first compiled call (compile or cache load): {first_call_s:.2f} s")
    print(f"eager (uncompiled) darksynth: {median['eager']:.2f} ms")
    print(
        f"single image, sRGB profile, no compile: {median['srgb_single']:.2f} ms"
        f" ({median['srgb_single'] / median['srgb']:.2f}x the compiled srgb_ms; target <= 2)"
    )
    apply_ms, floor_ms, gauss_ms = median["apply"], median["floor"], median["gauss"]
    srgb_ms, srgb_floor_ms, chain_ms = median["srgb"], median["srgb_floor"], median["chain"]
    print(f"ratios: apply/floor = {apply_ms / floor_ms:.3f}, albumentations_gauss/apply = {gauss_ms / apply_ms:.2f}")
    print(
        f"ratios: srgb/srgb_floor = {srgb_ms / srgb_floor_ms:.3f}, albumentations_chain/srgb = {chain_ms / srgb_ms:.2f}"
        " (targets: apply <= 1.3 floor, gauss/apply >= 3, srgb <= srgb_floor, chain/srgb >= 1.2)"
    )
    print(
        f"apply_ms={apply_ms:.2f} floor_ms={floor_ms:.2f} albumentations_gauss_ms={gauss_ms:.2f} "
        f"srgb_ms={srgb_ms:.2f} srgb_floor_ms={srgb_floor_ms:.2f} albumentations_chain_ms={chain_ms:.2f}"
    )


if __name__ == "__main__":
    main()
