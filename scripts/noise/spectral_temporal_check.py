"""Frame-to-frame persistence of the noise: each shared real clip and video against a static clean clip made with
the profile estimated from it.

Makes: docs/spectral-noise.md, "Measured" (the bullet "Frame to frame": the table of real, synthetic (gap), AR
coefficients and floor per reference); src/darksynth/estimation/persistence_fit.py quotes it.

Run from the repo root::

    .venv/bin/python scripts/noise/spectral_temporal_check.py --data ../shared/data

Options: ``[--data ../shared/data] [--frames 8]``.

For every phone clip (``real-lowlight/clips/clipN``, 4 frames) and the starlight video (first 16 frames): the lag-1
correlation of the reference's fine residual (``evaluation.structure.temporal_lag_correlation``), then the profile
``estimate`` writes for it, applied by the streaming synthesizer (as ``apply`` runs it) to one Kodak image repeated
``--frames`` times, and the same correlation of that synthetic clip; also with the profile's
``temporal_correlation`` set to 0 (independent frames), which shows the protocol's own floor: a static image's
8-bit rounding is the same in every frame, so with noise under about one level the measure reads it as
persistence. Printed per reference: real, synthetic, gap, independent-frames floor, the still flat blocks the
estimate read, its AR coefficients per octave and its noise std.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.evaluation.measures.structure import temporal_lag_correlation
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import read_image
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer
from darksynth.training.weights import default_weights_path, load_weights


def static_clip_correlation(profile: Profile, noise: NoiseValues, clean: torch.Tensor, frames: int) -> float:
    synthesizer = ClipSynthesizer(ClipParameters(noise, profile.darkening), generator=torch.Generator().manual_seed(0))
    clip = torch.stack([synthesizer(clean) for _ in range(frames)]).float() / 255.0
    return temporal_lag_correlation(clip.permute(0, 2, 3, 1).double().numpy())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--frames", type=int, default=8)
    arguments = parser.parse_args()
    network = load_weights(default_weights_path())
    low = arguments.data / "real-lowlight"
    clean = hwc_to_chw(read_image(sorted((arguments.data / "clean" / "images" / "kodak24").glob("*"))[2]).pixels)
    references = [(path, True) for path in sorted((low / "clips").glob("clip*"))]
    references.append((low / "videos" / "starlight_submillilux.mov", False))
    for path, folder in references:
        frames = load_reference(path, clip=folder, max_frames=16)
        real = temporal_lag_correlation(frames.permute(0, 2, 3, 1).double().numpy())
        profile = estimate(frames, network, source=str(path)).profile
        synthetic = static_clip_correlation(profile, profile.noise, clean, arguments.frames)
        persistence = profile.noise["temporal_correlation"]
        independent = profile.noise.replace(temporal_correlation=torch.zeros_like(persistence))
        floor = static_clip_correlation(profile, independent, clean, arguments.frames)
        spectrum = profile.meta.get("spectrum", {})
        print(
            f"{path.name:28s} real {real:6.3f} synthetic {synthetic:6.3f} gap {synthetic - real:+.3f} "
            f"independent-frames floor {floor:6.3f} still blocks {spectrum.get('still_flat_blocks')} "
            f"AR {np.round(profile.noise['temporal_correlation'].numpy(), 2).tolist()} "
            f"noise std {profile.meta.get('noise_std_8bit')}",
            flush=True,
        )


if __name__ == "__main__":
    main()
