"""What ``darksynth estimate`` says on every shared real reference: its warnings, the column decision, the noise.

Run: ``.venv/bin/python scripts/estimate_warnings.py [--data ../shared/data] [--weights W]``.

The references are every file under ``real-lowlight``: the LIME and LOL images (one frame each), each folder of
``clips`` (as ``--clip``, up to 16 frames) and the Starlight video (its first 16 frames). For each one line:
the noise std the profile would add on this reference (``noise.level.mean_noise_variance``, in 8-bit levels),
whether the column components (banding, temporal banding, periodic) were kept or set absent with the measured
column ratio (``meta.columns``), the darkening (alpha, gamma, confidence, bound hit) and the warnings; then the
rate of each warning and of each column decision.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import torch

from darksynth.estimate import NOISE_FREE_STD, EstimateOptions, estimate_file, load_reference
from darksynth.noise.level import mean_noise_variance
from darksynth.training.weights import default_weights_path, load_weights


def references(root: Path) -> list[tuple[Path, bool]]:
    """(path, is a frame folder) of every shared real reference, in a fixed order."""
    found: list[tuple[Path, bool]] = []
    for folder in ("images/lime", "images/lol"):
        found += [(path, False) for path in sorted((root / folder).glob("*.png"), key=lambda p: int(p.stem))]
    found += [(path, True) for path in sorted((root / "clips").iterdir()) if path.is_dir()]
    found += [(path, False) for path in sorted((root / "videos").iterdir())]
    return found


WARNING_KINDS = ("nearly noise-free", "darkening estimate is uncertain", "bound of its search range", "bright")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    parser.add_argument("--weights", type=Path, default=default_weights_path())
    args = parser.parse_args()
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
        print(f"{name}: noise std {std:.1f}/255; columns {column_text}; darkening {tone}")
        for warning in result.warnings:
            print(f"    warning: {warning}")
        for kind in WARNING_KINDS:
            kinds[kind] += any(kind in w for w in result.warnings)
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
