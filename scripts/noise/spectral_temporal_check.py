"""Frame-to-frame persistence of the noise: each shared real clip and video against a static clean clip made with
the profile estimated from it.

Makes: docs/spectral-noise.md, "Measured" (the bullet "Frame to frame": the table of real, synthetic (gap), AR
coefficients and floor per reference); src/darksynth/estimation/noise/persistence_fit.py quotes it.

Run from the repo root::

    .venv/bin/python scripts/noise/spectral_temporal_check.py --data ../shared/data

Options: ``[--data ../shared/data] [--frames 8] [--references NAME ...] [--profiles DIR]``.

For every phone clip (``real-lowlight/clips/clipN``, 4 frames) and the starlight video (first 16 frames): the lag-1
correlation of the reference's fine residual (``evaluation.structure.temporal_lag_correlation``), then the profile
``estimate`` writes for it, applied by the streaming synthesizer (as ``apply`` runs it) to one Kodak image repeated
``--frames`` times, and the same correlation of that synthetic clip; also with the profile's
``temporal_correlation`` set to 0 (independent frames), which shows the protocol's own floor: a static image's
8-bit rounding is the same in every frame, so with noise under about one level the measure reads it as
persistence. Printed per reference: real, synthetic, gap, independent-frames floor, the still flat blocks the
estimate read, its AR coefficients per octave, its noise std, how the persistence was found (``meta.spectrum.
persistence_source``: read, frames repeated or the video prior) and the share of still blocks a codec repeated.

Then the video prior (``estimation.noise.persistence_fit.VIDEO_PRIOR``) judged leave-one-out: per octave the median
of the coefficients read on every other reference whose persistence was read (not a prior), and each reference's
synthetic with that in place of its own coefficients (``prior (loo)``), against its real; the medians over all the read
references are printed too (what ``VIDEO_PRIOR`` should be, rounded to 0.05).
Also printed: the real lag-1 with each frame moved back by the scene's whole-pixel shift
(:func:`aligned_lag1_correlation`: the persistence of noise that moves with the scene, on a clip that pans) and the
clip's ``response`` (:func:`lag1_response`: how far persistent noise of the profile's level moves the lag-1 on the
clip's own frames; near 0 the real lag-1 says nothing of the noise, and ``benchmarks/real_data.py`` does not compare
it).
``--references clip101 clip11 ...`` runs only those (names as printed); ``--profiles DIR`` keeps each estimated
profile there and reuses it on the next run (several runs on parts of the references, then one on all for the
leave-one-out figures).
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import cv2
import numpy as np
import torch

from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.flat_blocks import stated_denoiser_strength
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import quantised
from darksynth.estimation.reference import load_reference
from darksynth.evaluation.measures.structure import temporal_lag_correlation
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import read_image
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, load_profile, save_profile
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer
from darksynth.training.weights import default_weights_path, load_weights


def static_scene(data: Path) -> torch.Tensor:
    """The clean image (3, H, W) uint8 repeated as the static clip: the third Kodak image of the shared data."""
    return hwc_to_chw(read_image(sorted((data / "clean" / "images" / "kodak24").glob("*"))[2]).pixels)


def lag1_correlation(frames: torch.Tensor) -> float:
    """Lag-1 correlation of the fine residual of frames (T, 3, H, W) in [0, 1]."""
    return temporal_lag_correlation(frames.permute(0, 2, 3, 1).double().numpy())


def aligned_lag1_correlation(frames: torch.Tensor) -> float:
    """:func:`lag1_correlation` of the clip with each frame moved back by the whole-pixel shift of the scene since
    the first frame (OpenCV's phase correlation of consecutive frames' blurred grey, rounded and summed), cropped to
    the part every frame holds: the persistence of noise that moves with the scene (a codec's motion compensation,
    temporal denoising) on a clip that pans, which the unaligned reading cannot see."""
    grey = [cv2.GaussianBlur(frame.mean(dim=0).numpy().astype(np.float32), (0, 0), 2.0) for frame in frames]
    shifts = [(0, 0)]
    for earlier, later in itertools.pairwise(grey):
        (across, down), _ = cv2.phaseCorrelate(earlier, later)
        shifts.append((shifts[-1][0] + round(down), shifts[-1][1] + round(across)))
    downs, acrosses = [shift[0] for shift in shifts], [shift[1] for shift in shifts]
    height = frames.shape[-2] - (max(downs) - min(downs))
    width = frames.shape[-1] - (max(acrosses) - min(acrosses))
    tops, lefts = [down - min(downs) for down in downs], [across - min(acrosses) for across in acrosses]
    aligned = [
        frame[:, top : top + height, left : left + width] for frame, top, left in zip(frames, tops, lefts, strict=True)
    ]
    return lag1_correlation(torch.stack(aligned))


PERSISTENCE_PROBE = 0.9
"""The AR(1) coefficient, on every octave, of the probe :func:`lag1_response` puts on a clip's own frames."""


def lag1_response(frames: torch.Tensor, noise: NoiseValues, strength: float, seed: int = 0) -> float:
    """How far the lag-1 of :func:`lag1_correlation` moves on this clip when its noise persists: the clip's own
    frames (T, 3, H, W) in [0, 1], denoised by non-local means of ``strength`` 8-bit levels (the estimate's), with
    ``noise`` (the profile's) drawn with the coefficient :data:`PERSISTENCE_PROBE` on every octave and with 0
    (independent frames), 8-bit rounded; the difference of the two readings (the same draw). Near 0 the clip's
    lag-1 says nothing of its noise's persistence at the level the estimate reads: its scene moves under that noise
    (no pixel stays still for the measure) or its flat pixels are black, where that noise rounds to nothing. The
    profile sets only the probe's level and spectrum; its own coefficients are not used."""
    denoised = nlm_denoise(frames, strength)
    persistence = noise["temporal_correlation"]

    def read(coefficient: float) -> float:
        probe = noise.replace(temporal_correlation=torch.full_like(persistence, coefficient))
        generator = torch.Generator().manual_seed(seed)
        return lag1_correlation(quantised(add_noise(denoised[None], probe, generator=generator)[0]))

    return read(PERSISTENCE_PROBE) - read(0.0)


def static_clip_correlation(
    profile: Profile, noise: NoiseValues, clean: torch.Tensor, frames: int, seed: int = 0
) -> float:
    """Lag-1 of ``clean`` repeated ``frames`` times through the streaming synthesizer with ``noise`` and the profile's
    darkening, its draws seeded by ``seed`` (``benchmarks/real_data.py`` varies it to measure the draws' spread)."""
    synthesizer = ClipSynthesizer(
        ClipParameters(noise, profile.darkening), generator=torch.Generator().manual_seed(seed)
    )
    return lag1_correlation(torch.stack([synthesizer(clean) for _ in range(frames)]).float() / 255.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--references", nargs="*", default=None, help="only these references (names as printed)")
    parser.add_argument("--profiles", type=Path, default=None, help="keep (and reuse) each estimated profile here")
    arguments = parser.parse_args()
    network = load_weights(default_weights_path())
    low = arguments.data / "real-lowlight"
    clean = static_scene(arguments.data)
    references = [(path, True) for path in sorted((low / "clips").glob("clip*"))]
    references.append((low / "videos" / "starlight_submillilux.mov", False))
    if arguments.references:
        references = [(path, folder) for path, folder in references if path.name in arguments.references]
    results: list[tuple[str, float, Profile, bool]] = []
    for path, folder in references:
        frames = load_reference(path, clip=folder, max_frames=16)
        real = lag1_correlation(frames)
        cached = arguments.profiles / f"{path.name}.json" if arguments.profiles else None
        if cached is not None and cached.exists():
            profile, warnings = load_profile(cached), []
        else:
            found = estimate(frames, network, source=str(path))
            profile, warnings = found.profile, found.warnings
            if cached is not None:
                cached.parent.mkdir(parents=True, exist_ok=True)
                save_profile(cached, profile)
        synthetic = static_clip_correlation(profile, profile.noise, clean, arguments.frames)
        persistence = profile.noise["temporal_correlation"]
        independent = profile.noise.replace(temporal_correlation=torch.zeros_like(persistence))
        floor = static_clip_correlation(profile, independent, clean, arguments.frames)
        spectrum = profile.meta.get("spectrum", {})
        source = str(spectrum.get("persistence_source", "none (no still blocks)"))
        skipped = spectrum.get("persistence_skipped_share")
        response = lag1_response(frames, profile.noise, stated_denoiser_strength(profile.meta, frames))
        print(
            f"{path.name:28s} real {real:6.3f} synthetic {synthetic:6.3f} gap {synthetic - real:+.3f} "
            f"real aligned to the scene's motion {aligned_lag1_correlation(frames):6.3f} response {response:.2f} "
            f"independent-frames floor {floor:6.3f} still blocks {spectrum.get('still_flat_blocks')} "
            f"AR {np.round(persistence.numpy(), 2).tolist()} noise std {profile.meta.get('noise_std_8bit')} "
            f"| {source} | skipped {skipped}",
            flush=True,
        )
        for warning in warnings:
            if "frame" in warning:
                print(f"    {warning}", flush=True)
        results.append((path.name, real, profile, source.startswith("read")))
    read = {name: profile.noise["temporal_correlation"] for name, _, profile, was_read in results if was_read}
    if read:
        print(f"median over the {len(read)} read references: {_median_coefficients(list(read.values()))}")
    for name, real, profile, _ in results:
        others = [coefficient for other, coefficient in read.items() if other != name]
        if not others:
            continue
        prior = torch.tensor(_median_coefficients(others), dtype=profile.noise["temporal_correlation"].dtype)
        synthetic = static_clip_correlation(
            profile, profile.noise.replace(temporal_correlation=prior), clean, arguments.frames
        )
        print(f"{name:28s} real {real:6.3f} prior (loo) {prior.tolist()} synthetic {synthetic:6.3f}", flush=True)


def _median_coefficients(coefficients: list[torch.Tensor]) -> list[float]:
    """Per octave the median of the coefficients, rounded to 0.05 (the precision a prior is stated with)."""
    median = torch.quantile(torch.stack(coefficients).to(torch.float64), 0.5, dim=0)
    return [round(float(v) * 20) / 20 for v in median]


if __name__ == "__main__":
    main()
