"""What the camera prior costs on the default path: reading and fitting the prior, a clip's camera drawn by the
recipe, and a 1080p frame whose noise follows texture against the same frame without.

Run: ``.venv/bin/python benchmarks/bench_camera_prior.py [--rounds N]``. The first line is the CPU and its vector
extensions. Each round times each case in turn (a slow moment of the machine hits all alike); medians are printed.
The last line is ``prior_fit_ms=<a> choose_ms=<b> choose_camera_ms=<c> frame_ms=<d> frame_texture_ms=<e>``:

- a: :func:`darksynth.cameras.prior.shipped_prior` once, cold (the bank read and the prior fitted; a process pays it
  once);
- b, c: :meth:`darksynth.recipe.ClipRecipe.choose` for one clip with the default profile, without and with
  ``camera="prior"`` (a whole camera drawn per clip);
- d, e: one 1080p uint8 frame of the prior's central camera through the eager 8-bit spectral pass
  (``ClipSynthesizer``, as ``apply`` runs an image or a short clip), with ``texture_gain`` 0 and with the bank's
  median texture (the factor's detail read on the frame).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import torch

from darksynth.cameras import prior as prior_module
from darksynth.light.darkening import Darkening
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import ClipParameters, ClipRecipe
from darksynth.synthesize import ClipSynthesizer
from machine import cpu_summary

HEIGHT, WIDTH = 1080, 1920


def _median_ms(function: Callable[[], object], rounds: int) -> float:
    times = []
    for _ in range(rounds):
        started = time.perf_counter()
        function()
        times.append((time.perf_counter() - started) * 1000)
    return statistics.median(times)


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=15)
    args = parser.parse_args()
    torch.set_num_threads(2)
    started = time.perf_counter()
    camera_prior = prior_module.shipped_prior()
    prior_fit_ms = (time.perf_counter() - started) * 1000
    profile = load_profile(default_profile_path())
    plain, drawn = ClipRecipe(profile), ClipRecipe(profile, camera="prior")
    generator = torch.Generator().manual_seed(0)
    central = camera_prior.mean_values()
    flat = central.replace(texture_gain=0.0)
    darkening = Darkening(alpha=0.2, gamma=0.7)
    frame = torch.randint(0, 256, (3, HEIGHT, WIDTH), dtype=torch.uint8, generator=torch.Generator().manual_seed(1))
    cases: dict[str, Callable[[], object]] = {
        "choose": lambda: plain.choose(generator),
        "choose_camera": lambda: drawn.choose(generator),
        "frame": lambda: ClipSynthesizer(ClipParameters(flat, darkening), generator=generator, compile=False)(frame),
        "frame_texture": lambda: ClipSynthesizer(
            ClipParameters(central, darkening), generator=generator, compile=False
        )(frame),
    }
    for case in cases.values():
        case()
    results: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(args.rounds):
        for name, case in cases.items():
            results[name].append(_median_ms(case, 1))
    median = {name: statistics.median(values) for name, values in results.items()}
    print(
        f"central camera: texture gain {central.scalar('texture_gain'):.3f}, scale "
        f"{central.scalar('texture_scale'):.4f}; threads {torch.get_num_threads()}, frame {WIDTH}x{HEIGHT}"
    )
    print(
        f"camera drawn per clip adds {median['choose_camera'] - median['choose']:.2f} ms to a clip's choice; texture "
        f"makes a frame {median['frame_texture'] / median['frame']:.2f}x as long"
    )
    print(
        f"prior_fit_ms={prior_fit_ms:.1f} choose_ms={median['choose']:.2f} "
        f"choose_camera_ms={median['choose_camera']:.2f} frame_ms={median['frame']:.1f} "
        f"frame_texture_ms={median['frame_texture']:.1f}"
    )


if __name__ == "__main__":
    main()
