"""Speed of darkening + f(v) on one 1080p RGB frame against the random-number floor and albumentations.

Run: ``.venv/bin/python benchmarks/bench_apply.py [--rounds N] [--block K]``. Each round times K consecutive
frames of each method in turn (a stream of frames, as in a video), so that a slow moment of the machine hits
all of them alike; medians over all timed frames are printed. The last line is
``apply_ms=<a> floor_ms=<b> albumentations_gauss_ms=<c>``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
import torch

from darksynth.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.synthesize import ClipParameters, ClipSynthesizer
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


def timed(function: Callable[[], object]) -> float:
    start = time.perf_counter()
    function()
    return (time.perf_counter() - start) * 1e3


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=12)
    parser.add_argument("--block", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(2)
    import albumentations  # development dependency, imported here to keep its start-up out of the timings

    rng = np.random.default_rng(0)
    ramp = np.linspace(0, 255, WIDTH, dtype=np.float32)[None, :, None]
    frame_hwc = np.clip(ramp + rng.normal(0, 20, (HEIGHT, WIDTH, 3)), 0, 255).astype(np.uint8)
    frame = torch.from_numpy(frame_hwc).permute(2, 0, 1).contiguous()
    generator = torch.Generator().manual_seed(0)

    started = time.perf_counter()
    compiled = ClipSynthesizer(ALL_COMPONENTS, generator=generator, compile=True)
    compiled(frame)
    first_call_s = time.perf_counter() - started
    eager = ClipSynthesizer(ALL_COMPONENTS, generator=generator, compile=False)
    gauss = albumentations.GaussNoise(std_range=(0.05, 0.05), p=1.0)
    for _ in range(3):
        compiled(frame), eager(frame), gauss(image=frame_hwc)

    shape = (3, HEIGHT, WIDTH)
    results: dict[str, list[float]] = {"apply": [], "eager": [], "floor": [], "gauss": []}
    methods: dict[str, Callable[[], object]] = {
        "apply": lambda: compiled(frame),
        "floor": lambda: (torch.randn(shape, generator=generator), torch.rand(shape, generator=generator)),
        "gauss": lambda: gauss(image=frame_hwc),
        "eager": lambda: eager(frame),
    }
    for _ in range(args.rounds):
        for name, method in methods.items():
            results[name].extend(timed(method) for _ in range(args.block))
    median = {name: statistics.median(values) for name, values in results.items()}
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, frame {WIDTH}x{HEIGHT} RGB uint8")
    print(f"first compiled call (compile or cache load): {first_call_s:.2f} s")
    print(f"eager (uncompiled) darksynth: {median['eager']:.2f} ms")
    apply_ms, floor_ms, gauss_ms = median["apply"], median["floor"], median["gauss"]
    print(f"ratios: apply/floor = {apply_ms / floor_ms:.3f}, albumentations_gauss/apply = {gauss_ms / apply_ms:.2f}")
    print(f"apply_ms={apply_ms:.2f} floor_ms={floor_ms:.2f} albumentations_gauss_ms={gauss_ms:.2f}")


if __name__ == "__main__":
    main()
