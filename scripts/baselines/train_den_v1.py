"""Train the paper's ablation v1 (a U-Net that makes the noisy image, no f) and write its weights and summary.

Makes: the shipped weights src/darksynth/data/den_v1.safetensors and the held-out figures of docs/results.md,
"The paper's ablation: den (v3) against den-v2 and v1" / "v1: a U-Net that makes the noisy image, without f" (the
summary is docs/den_v1_training.json).

Run from the repo root (the shipped weights, then their held-out figures again)::

    .venv/bin/python scripts/baselines/train_den_v1.py --seed 0 --max-minutes 20 \
        --out src/darksynth/data/den_v1.safetensors
    .venv/bin/python scripts/baselines/train_den_v1.py --out src/darksynth/data/den_v1.safetensors --evaluate-only

with the default data paths below, those of v2 and v3; ``--help`` lists the training settings.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import torch

from darksynth.baselines.den_v1 import load_den_v1
from darksynth.baselines.den_v1_training import V1TrainConfig, evaluate_v1, train_den_v1, validation_samples
from darksynth.errors import DarksynthError
from darksynth.training.corpus import load_corpus

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "clean"


def main(argv: list[str] | None = None) -> int:
    defaults = V1TrainConfig()
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--data",
        type=Path,
        nargs="+",
        default=[SHARED / "images" / name for name in ("cbsd68", "mcmaster", "mirflickr")],
        help="clean still images or folders of them (default: cbsd68, mcmaster, mirflickr of ../shared)",
    )
    parser.add_argument(
        "--clips", type=Path, nargs="*", default=[SHARED / "videos"], help="folders of clips (frame folders, videos)"
    )
    parser.add_argument(
        "--holdout", type=Path, nargs="*", default=[SHARED / "images" / "kodak24"], help="held-out clean images"
    )
    parser.add_argument("--out", type=Path, required=True, help="weights file to write (.safetensors)")
    parser.add_argument(
        "--evaluate-only", action="store_true", help="read OUT's weights and print its held-out figures, no training"
    )
    parser.add_argument("--steps", type=int, default=defaults.steps)
    parser.add_argument("--max-minutes", type=float, default=(defaults.max_seconds or 0) / 60 or None)
    parser.add_argument("--seed", type=int, default=defaults.seed)
    parser.add_argument("--crop", type=int, default=defaults.crop)
    parser.add_argument("--log-every", type=int, default=defaults.log_every)
    parser.add_argument("--validation-size", type=int, default=defaults.validation_size)
    parser.add_argument("--device", default=defaults.device)
    args = parser.parse_args(argv)
    config = dataclasses.replace(
        defaults,
        steps=args.steps,
        max_seconds=60 * args.max_minutes if args.max_minutes else None,
        seed=args.seed,
        crop=args.crop,
        log_every=args.log_every,
        validation_size=args.validation_size,
        device=args.device,
    )
    started = time.perf_counter()
    try:
        corpus = load_corpus(args.data, args.clips, minimum_side=config.crop)
        holdout = load_corpus(args.holdout, minimum_side=config.validation_crop) if args.holdout else None
    except DarksynthError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(
        f"corpus: {len(corpus.images)} images, {len(corpus.clips)} clips; holdout: {len(holdout) if holdout else 0} "
        f"({time.perf_counter() - started:.1f} s to load; torch threads {torch.get_num_threads()})",
        flush=True,
    )

    if args.evaluate_only:
        if holdout is None:
            print("error: --evaluate-only needs --holdout", file=sys.stderr)
            return 1
        try:
            model = load_den_v1(args.out, device=args.device)
        except DarksynthError as error:
            print(f"error: {error}", file=sys.stderr)
            return 1
        print(json.dumps(evaluate_v1(model, validation_samples(holdout, config), seed=config.seed), indent=2))
        return 0

    def progress(step: int, entry: dict[str, Any]) -> None:
        print(
            f"step {step:5d}  D {entry['discriminator']:.4f}  adv {entry['adversarial']:.4f}  "
            f"stat {entry['statistics']:.4f}  {entry['seconds']:.0f} s",
            flush=True,
        )

    _, summary = train_den_v1(corpus, config, holdout=holdout, out=args.out, progress=progress)
    print(f"training took {summary['training_seconds']:.0f} s, {summary['steps']} steps; wrote {args.out}")
    if "holdout" in summary:
        print(json.dumps({"trained": summary["holdout"], "untrained": summary["holdout_untrained"]}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
