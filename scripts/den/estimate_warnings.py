"""What ``darksynth estimate`` says on every shared real reference: its warnings, the column decision, the noise.

Makes: docs/den.md, "What estimate says, on the shared references" (the before/after table of warnings and column
decisions over the 41 references, and the column ratios); with ``--confidence`` the table of tone-curve error per
confidence bin in docs/darkening-estimate.md, "In the profile (`estimate()`)", which
src/darksynth/estimation/darkening_reading.py quotes. docs/refine.md ("Version 3: the default") quotes a run of it too.

Run from the repo root::

    .venv/bin/python scripts/den/estimate_warnings.py                # every shared real reference
    .venv/bin/python scripts/den/estimate_warnings.py --confidence   # the darkening confidence table

Options: ``[--data ../shared/data] [--weights W] [--confidence]``.

The references are every file under ``real-lowlight``: the LIME and LOL images (one frame each), each folder of
``clips`` (as ``--clip``, up to 16 frames) and the Starlight video (its first 16 frames). For each one line:
the noise std the profile would add on this reference (``noise.level.mean_noise_variance``, in 8-bit levels),
whether the column components (banding, temporal banding, periodic) were kept or set absent with the measured
column ratio (``meta.columns``), the darkening (alpha, gamma, confidence, bound hit) and the warnings; then the
rate of each warning and of each column decision.

``--confidence``: how the darkening's confidence relates to its error, which sets the threshold of the
"darkening estimate is uncertain" warning: held-out Kodak images darkened with alpha ~ U(0.05, 0.3), gamma ~
U(0.1, 1) and noise from the DEN's training ranges (as ``scripts/light/evaluate_darkening.py evaluate``, seed 0, 4
draws each), the tone-curve error (mean absolute difference of the 5%-95% quantiles over the true mean level)
per confidence bin, and how often each threshold would fire.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np
import torch

from darksynth.errors import DarksynthError
from darksynth.estimation.assemble import EstimateOptions, estimate_file
from darksynth.estimation.darkening_reading import estimate_darkening
from darksynth.estimation.noise.noise_estimate import NOISE_FREE_STD
from darksynth.estimation.reference import load_reference
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening, darken
from darksynth.noise.level import mean_noise_variance
from darksynth.noise.sampling import random_noise_values
from darksynth.noise.simulate import add_noise
from darksynth.training.weights import default_weights_path, load_weights


def references(root: Path) -> list[tuple[Path, bool]]:
    """(path, is a frame folder) of every shared real reference, in a fixed order."""
    found: list[tuple[Path, bool]] = []
    for folder in ("images/lime", "images/lol"):
        found += [(path, False) for path in sorted((root / folder).glob("*.png"), key=lambda p: int(p.stem))]
    found += [(path, True) for path in sorted((root / "clips").iterdir()) if path.is_dir()]
    found += [(path, False) for path in sorted((root / "videos").iterdir())]
    return found


WARNING_KINDS = ("nearly noise-free", "darkening estimate is uncertain", "of its search range", "is bright")


CURVE_LEVELS = torch.linspace(0.05, 0.95, 19, dtype=torch.float64)


def _curve_error(clean: torch.Tensor, estimated: Darkening, true: Darkening) -> float:
    ours = torch.quantile(darken(clean, estimated.alpha, estimated.gamma).flatten().double(), CURVE_LEVELS)
    theirs = darken(clean, true.alpha, true.gamma).flatten().double()
    return float((ours - torch.quantile(theirs, CURVE_LEVELS)).abs().mean() / theirs.mean())


def confidence_table(data: Path, draws: int = 4, seed: int = 0) -> None:
    """Tone-curve error of the darkening estimate by confidence bin, on held-out Kodak images."""
    generator = torch.Generator().manual_seed(seed)
    baseline = Darkening(alpha=sum(ALPHA_RANGE) / 2, gamma=sum(GAMMA_RANGE) / 2)
    rows = []
    for path in sorted((data / "clean" / "images" / "kodak24").glob("*.png")):
        clean = load_reference(path)[0]
        for _ in range(draws):
            alpha = float(torch.empty(()).uniform_(*ALPHA_RANGE, generator=generator))
            gamma = float(torch.empty(()).uniform_(*GAMMA_RANGE, generator=generator))
            values = random_noise_values(generator=generator, noise_model="paper")
            noisy = add_noise(darken(clean, alpha, gamma)[None], values, generator=generator)[0]
            try:
                found = estimate_darkening((noisy * 255).round() / 255)
            except DarksynthError:
                continue
            true = Darkening(alpha, gamma)
            rows.append(
                (found.confidence, _curve_error(clean, found.darkening, true), _curve_error(clean, baseline, true))
            )
    table = np.asarray(rows)
    print(f"held-out kodak24: {len(table)} estimates; tone-curve error by confidence")
    for low, high in ((0.0, 0.1), (0.1, 0.2), (0.2, 0.3), (0.3, 0.5), (0.5, 1.01)):
        inside = (table[:, 0] >= low) & (table[:, 0] < high)
        chosen = table[inside, 1]
        if chosen.size:
            better = float(np.mean(chosen < table[inside, 2]))
            print(
                f"  [{low:.1f}, {min(high, 1.0):.1f}): n={chosen.size:3d} median {np.median(chosen):.3f} "
                f"90th percentile {np.percentile(chosen, 90):.3f}; better than the paper's mid-range {better:.0%}"
            )
    ranks = np.argsort(np.argsort(table[:, :2], axis=0), axis=0)
    print(f"  Spearman correlation of confidence and error: {np.corrcoef(ranks.T)[0, 1]:+.2f}")
    for threshold in (0.05, 0.1, 0.15, 0.2, 0.3):
        below = table[:, 0] < threshold
        print(f"  threshold {threshold}: fires on {below.mean():.2f} of the estimates")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3] / "shared" / "data")
    parser.add_argument("--weights", type=Path, default=default_weights_path())
    parser.add_argument("--confidence", action="store_true", help="the darkening confidence table instead")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.confidence:
        confidence_table(args.data)
        return 0
    network = load_weights(args.weights)
    root = args.data / "real-lowlight"
    kinds: Counter[str] = Counter()
    columns: Counter[str] = Counter()
    entries = references(root)
    below_one_level = 0
    for path, clip in entries:
        result = estimate_file(path, network, EstimateOptions(clip=clip))
        reference = load_reference(path, clip=clip)
        values = result.profile.noise.map(lambda t: t[None].to(torch.float32))
        std = float(mean_noise_variance(values, reference[None]).sqrt()) * 255
        below_one_level += std < 1.0
        decision = result.profile.meta.get("columns", {})
        column_text = (
            f"{decision.get('decision', '?')} ratio {decision.get('ratio', float('nan')):.2f}" if decision else "-"
        )
        darkening = result.profile.darkening
        meta_darkening = result.profile.meta.get("darkening")
        confidence = meta_darkening.get("confidence") if isinstance(meta_darkening, dict) else None
        tone = f"alpha {darkening.alpha:.3f} gamma {darkening.gamma:.2f} conf {confidence}" if darkening else "none"
        name = str(path.relative_to(root))
        # A check on "nearly noise-free" where frames exist: the share of 8-bit pixels equal in two frames.
        unchanged = (
            f"; {float((reference[1] - reference[0]).abs().lt(0.5 / 255).float().mean()):.0%} of pixels unchanged "
            "from frame 0 to 1"
            if reference.shape[0] > 1
            else ""
        )
        print(f"{name}: noise std {std:.2f}/255; columns {column_text}; darkening {tone}{unchanged}")
        for warning in result.warnings:
            print(f"    warning: {warning}")
        for kind in WARNING_KINDS:
            # The darkening's doubts are notes in meta since apply matches the reference's tones instead.
            said = [*result.warnings, *result.profile.meta.get("darkening", {}).get("notes", [])]
            kinds[kind] += any(kind in w for w in said)
        columns[decision.get("decision", "not tested") if decision else "not tested"] += 1
    total = len(entries)
    print(f"\n{total} references")
    for kind in WARNING_KINDS:
        print(f"  warning '{kind}': {kinds[kind]}/{total}")
    print(
        f"  profile noise std below {NOISE_FREE_STD * 255:.1f} level (the warning): {kinds[WARNING_KINDS[0]]}/{total}"
    )
    print(f"  profile noise std below 1 level: {below_one_level}/{total}")
    for decision, count in sorted(columns.items()):
        print(f"  columns {decision}: {count}/{total}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
