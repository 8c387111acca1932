"""Speed of darkening + f(v) on one 1080p RGB frame against the random-number floor and albumentations.

Run: ``.venv/bin/python benchmarks/bench_apply.py [--rounds N] [--block K]``. Each round times K consecutive
frames of each method in turn (a stream of frames, as in a video), so that a slow moment of the machine hits
all of them alike; medians over all timed frames are printed. The first line is the CPU and its vector
extensions. The last line is ``apply_ms=<a> floor_ms=<b> albumentations_gauss_ms=<c> default_ms=<d>
network_ms=<d3> srgb_floor_ms=<e> albumentations_chain_ms=<f> synthesize_ms=<s> synthesize_float_ms=<sf>
spectral_floor_ms=<g> default_eager_ms=<de> irfft2_ms=<i>``:

- a: the paper's model, every component on, darkening on, compiled kernel; b: ``torch.randn`` + ``torch.rand`` of
  the frame; c: albumentations ``GaussNoise``;
- d: the default path: the profile ``estimate`` writes for the shipped demo reference (the spectral model,
  profile version 4, compression included when it has one), darkening on, through ``ClipSynthesizer`` compiled,
  as ``apply`` runs a stream (:mod:`darksynth.noise.spectral_kernel`); de: the same eagerly, as ``apply`` runs a
  short clip or one image (:mod:`darksynth.noise.spectral_8bit`);
- d3: the network's values alone for the same reference (``estimate --no-refine``, the sRGB vocabulary drawn as the
  spectral model), compiled, for comparison; e: the floor of a JPEG path, ``torch.randn`` + ``torch.rand`` of the
  frame and a Pillow JPEG encode and decode of it at quality 75; f: albumentations
  ``Compose([GaussNoise, ImageCompression])`` at quality 75;
- s: one image (uint8 tensor) through ``darksynth.synthesize`` with the default profile, no compile step, what a
  training transform runs on 8-bit input in a DataLoader worker (drawing the parameters and a new synthesizer per
  call); sf: the same image as float in [0, 1] (on the 8-bit levels, as ``ToTensor`` gives it);
- g: the eager spectral path's floor, ``normal_`` of its FFT grid, the ``irfft2`` and the quantization bytes of
  the frame; i: the ``irfft2`` alone, which both paths run (the compiled one draws in its own kernels).

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

from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.estimation.reference import load_reference
from darksynth.light.darkening import Darkening
from darksynth.noise.components import noise_component
from darksynth.noise.spectral import SpectralGrid, octave_covariances, spectral_tables
from darksynth.noise.structure_translation import spectral_tensors
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer, synthesize
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


def demo_profile(*, measured: bool) -> Profile:
    """The profile ``estimate`` writes for the demo reference: ``measured``, the default (the spectral model),
    else the network's values alone (``estimate --no-refine``)."""
    reference = load_reference(DEMO_REFERENCE, clip=False, max_frames=1)
    return estimate(
        reference, load_weights(default_weights_path()), options=NoiseEstimateOptions(refine=measured)
    ).profile


def demo_parameters(profile: Profile) -> ClipParameters:
    """A demo profile's values, as a clip draws them, with the paper example's darkening: the path a user's
    ``apply`` takes."""
    return ClipParameters(noise=NoiseValues(spectral_tensors(profile.noise)), darkening=ALL_COMPONENTS.darkening)


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
    default_profile, network_profile = demo_profile(measured=True), demo_profile(measured=False)
    default, network = demo_parameters(default_profile), demo_parameters(network_profile)
    print(
        f"default profile (estimate): spectral model "
        f"{'active' if default.noise.is_active(noise_component('spectral')) else 'NOT active'}, compression "
        f"{default.noise.scalar('compression'):.2f}, temporal correlation "
        f"{max(default.noise['temporal_correlation'].tolist()):.2f}; the network's values (estimate --no-refine): "
        f"compression {network.noise.scalar('compression'):.2f}"
    )

    started = time.perf_counter()
    compiled = ClipSynthesizer(ALL_COMPONENTS, generator=generator, compile=True, device=args.device)
    compiled(frame)
    first_call_s = time.perf_counter() - started
    eager = ClipSynthesizer(ALL_COMPONENTS, generator=generator, compile=False, device=args.device)
    started = time.perf_counter()
    default_synthesizer = ClipSynthesizer(default, generator=generator, compile=True, device=args.device)
    default_synthesizer(frame)
    default_first_call_s = time.perf_counter() - started
    default_eager = ClipSynthesizer(default, generator=generator, compile=False, device=args.device)
    network_synthesizer = ClipSynthesizer(network, generator=generator, compile=True, device=args.device)
    network_single = ClipSynthesizer(network, generator=generator, compile=False, device=args.device)
    frame_float = frame.to(torch.float32) / 255.0
    darkening = ALL_COMPONENTS.darkening
    gauss = albumentations.GaussNoise(std_range=(0.05, 0.05), p=1.0)
    chain = albumentations.Compose(
        [
            albumentations.GaussNoise(std_range=(0.05, 0.05), p=1.0),
            albumentations.ImageCompression(quality_range=(75, 75), p=1.0),
        ]
    )

    shape = (3, HEIGHT, WIDTH)
    # The spectral path's own floor: the normals of its FFT grid, the inverse transform and the quantization
    # bytes, which it cannot draw with less work.
    covariances = octave_covariances(default.noise["octave_power"], default.noise["octave_correlation"])
    tables = spectral_tables(covariances, default.noise["temporal_correlation"], 3, HEIGHT, WIDTH, device=args.device)
    grid = SpectralGrid(tables, 3, HEIGHT, WIDTH)
    grid_white = torch.empty((3, grid.grid_height, grid.grid_width // 2 + 1, 2), device=args.device)
    quantization_bytes = torch.empty(shape, dtype=torch.uint8, device=args.device)

    def irfft2() -> object:
        return torch.fft.irfft2(torch.view_as_complex(grid_white), s=(grid.grid_height, grid.grid_width))

    def spectral_floor() -> object:
        grid_white.normal_(generator=generator)
        field = torch.fft.irfft2(torch.view_as_complex(grid_white), s=(grid.grid_height, grid.grid_width))
        return field, quantization_bytes.random_(generator=generator)

    methods: dict[str, Callable[[], object]] = {
        "apply": lambda: compiled(frame),
        "floor": lambda: (torch.randn(shape, generator=generator), torch.rand(shape, generator=generator)),
        "gauss": lambda: gauss(image=frame_hwc),
        "eager": lambda: eager(frame),
        "default": lambda: default_synthesizer(frame),
        "default_eager": lambda: default_eager(frame),
        "irfft2": irfft2,
        "network": lambda: network_synthesizer(frame),
        "srgb_floor": lambda: (
            torch.randn(shape, generator=generator),
            torch.rand(shape, generator=generator),
            jpeg_round_trip(frame_hwc),
        ),
        "chain": lambda: chain(image=frame_hwc),
        "spectral_floor": spectral_floor,
        "network_single": lambda: network_single(frame),
        "synthesize": lambda: synthesize(frame, default_profile, generator=generator, darkening=darkening),
        "synthesize_float": lambda: synthesize(frame_float, default_profile, generator=generator, darkening=darkening),
    }
    for _ in range(3):
        for method in methods.values():
            method()
    results: dict[str, list[float]] = {name: [] for name in methods}
    for _ in range(args.rounds):
        for name, method in methods.items():
            results[name].extend(timed(method, args.device) for _ in range(args.block))
    median = {name: statistics.median(values) for name, values in results.items()}
    apply_ms, floor_ms, gauss_ms = median["apply"], median["floor"], median["gauss"]
    default_ms, network_ms, srgb_floor_ms, chain_ms = (
        median["default"],
        median["network"],
        median["srgb_floor"],
        median["chain"],
    )
    synthesize_ms, synthesize_float_ms = median["synthesize"], median["synthesize_float"]
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, frame {WIDTH}x{HEIGHT} RGB uint8")
    print(
        f"first compiled call (compile or cache load): paper kernel {first_call_s:.2f} s, spectral kernels "
        f"{default_first_call_s:.2f} s"
    )
    print(f"paper model, every component: compiled {apply_ms:.2f} ms, eager {median['eager']:.2f} ms")
    print(
        f"default path (spectral profile, ClipSynthesizer compiled, as apply runs a stream): {default_ms:.2f} ms; "
        f"albumentations GaussNoise + ImageCompression: {chain_ms:.2f} ms; "
        f"chain / default = {chain_ms / default_ms:.2f} (target >= 1.2); eagerly (a short clip, one image) "
        f"{median['default_eager']:.2f} ms (chain / it = {chain_ms / median['default_eager']:.2f}); the irfft2 "
        f"both run {median['irfft2']:.2f} ms"
    )
    print(
        f"one image through synthesize, no compile step: uint8 {synthesize_ms:.2f} ms "
        f"({synthesize_ms / chain_ms:.2f}x the chain; target <= 2), float {synthesize_float_ms:.2f} ms "
        f"({synthesize_float_ms / chain_ms:.2f}x the chain)"
    )
    print(
        f"the network's values alone: compiled {network_ms:.2f} ms (chain / it = {chain_ms / network_ms:.2f}), "
        f"single image without compiling {median['network_single']:.2f} ms"
    )
    print(
        f"floors: randn + rand {floor_ms:.2f} ms; randn + rand + Pillow JPEG q75 {srgb_floor_ms:.2f} ms "
        f"(default / that floor = {default_ms / srgb_floor_ms:.2f}); the eager spectral path's own (normals of its "
        f"FFT grid, irfft2, quantization bytes) {median['spectral_floor']:.2f} ms "
        f"(eager default / it = {median['default_eager'] / median['spectral_floor']:.2f}, chain / it = "
        f"{chain_ms / median['spectral_floor']:.2f})"
    )
    print(f"ratios: apply/floor = {apply_ms / floor_ms:.3f}, albumentations_gauss/apply = {gauss_ms / apply_ms:.2f}")
    print(
        f"apply_ms={apply_ms:.2f} floor_ms={floor_ms:.2f} albumentations_gauss_ms={gauss_ms:.2f} "
        f"default_ms={default_ms:.2f} network_ms={network_ms:.2f} srgb_floor_ms={srgb_floor_ms:.2f} "
        f"albumentations_chain_ms={chain_ms:.2f} synthesize_ms={synthesize_ms:.2f} "
        f"synthesize_float_ms={synthesize_float_ms:.2f} spectral_floor_ms={median['spectral_floor']:.2f} "
        f"default_eager_ms={median['default_eager']:.2f} irfft2_ms={median['irfft2']:.2f}"
    )


if __name__ == "__main__":
    main()
