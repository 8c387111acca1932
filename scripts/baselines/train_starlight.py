"""Train the Starlight baseline generator on the DEN's synthetic data and write its weights and summary.

Makes: the shipped weights src/darksynth/data/starlight.safetensors and their summary
src/darksynth/data/starlight_training.json, whose held-out figures docs/starlight.md, "Training" / "The shipped
weights" shows.

Run from the repo root::

    .venv/bin/python scripts/baselines/train_starlight.py --seed 0 --steps 1500 --threads 1 --max-minutes 14.5 \
        --out src/darksynth/data/starlight.safetensors

with the default data paths below; ``--help`` lists the training settings.
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

from darksynth.baselines.starlight import StarlightConfig, StarlightTrainConfig, summary_path, train_starlight
from darksynth.errors import DarksynthError
from darksynth.training.corpus import load_corpus

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "clean"


def main(argv: list[str] | None = None) -> int:
    defaults = StarlightTrainConfig()
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
    parser.add_argument("--steps", type=int, default=defaults.steps)
    parser.add_argument("--seed", type=int, default=defaults.seed)
    parser.add_argument("--batch", type=int, default=defaults.batch)
    parser.add_argument("--frames", type=int, default=defaults.frames)
    parser.add_argument("--crop", type=int, default=defaults.crop)
    parser.add_argument("--width", type=int, default=defaults.generator.width, help="U-Net width")
    parser.add_argument("--depth", type=int, default=defaults.generator.depth, help="U-Net depth")
    parser.add_argument("--lambda-statistics", type=float, default=defaults.lambda_statistics)
    parser.add_argument("--lambda-adversarial", type=float, default=defaults.lambda_adversarial)
    parser.add_argument("--physics-lr", type=float, default=defaults.physics_learning_rate)
    parser.add_argument("--lr", type=float, default=defaults.learning_rate, help="U-Net learning rate")
    parser.add_argument("--d-lr", type=float, default=defaults.discriminator_learning_rate)
    parser.add_argument("--max-minutes", type=float, default=None, help="stop training early after this long")
    parser.add_argument("--log-every", type=int, default=defaults.log_every)
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--device", default=defaults.device)
    args = parser.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)

    config = dataclasses.replace(
        defaults,
        generator=dataclasses.replace(StarlightConfig(), width=args.width, depth=args.depth),
        steps=args.steps,
        seed=args.seed,
        batch=args.batch,
        frames=args.frames,
        crop=args.crop,
        lambda_statistics=args.lambda_statistics,
        lambda_adversarial=args.lambda_adversarial,
        physics_learning_rate=args.physics_lr,
        learning_rate=args.lr,
        discriminator_learning_rate=args.d_lr,
        max_seconds=60 * args.max_minutes if args.max_minutes else None,
        log_every=args.log_every,
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
        f"corpus: {len(corpus.images)} images, {len(corpus.clips)} clips; "
        f"holdout: {len(holdout) if holdout else 0} ({time.perf_counter() - started:.1f} s to load)",
        flush=True,
    )

    def progress(step: int, entry: dict[str, Any]) -> None:
        physics = ", ".join(
            f"{k} {v:.4f}" if isinstance(v, float) else f"{k} " + "/".join(f"{x:.4f}" for x in v)
            for k, v in entry["physics"].items()
        )
        print(
            f"step {step:5d}  D {entry['discriminator']:.4f}  adv {entry['adversarial']:.4f}  "
            f"stat {entry['statistics']:.4f}  {entry['seconds']:.0f} s  [{physics}]",
            flush=True,
        )

    _, summary = train_starlight(corpus, config, holdout=holdout, out=args.out, progress=progress)
    print(f"training took {summary['training_seconds']:.0f} s; wrote {args.out} and {summary_path(args.out)}")
    if "holdout" in summary:
        print(json.dumps(summary["holdout"], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
