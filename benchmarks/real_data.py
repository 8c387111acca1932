"""One command that judges an estimation change on all real data: every shared real pair set, every real low-light
photo without a clean image, every real clip and video, measured as a user measures them, written as a record and
compared with the last committed record.

Run from the repo root: ``.venv/bin/python benchmarks/real_data.py`` (or ``make real-data``), options
``[--data ../shared/data] [--only pairs,photos,clips] [--limit N] [--seed S] [--out PATH] [--no-compare]``.

Every reference gets the default ``estimate`` (``darksynth.estimation.assemble.estimate`` with the shipped weights);
its profile is then applied as ``apply --no-darken`` applies it.

1. **Pairs** (``real-pairs/{sidd,sidd-phones,nam-cc15,nam-cc60,polyu}``): ``darksynth evaluate``'s method ``den``
   (the estimate on the noisy image, its noise added to the clean one), without FID: per set, synthetic over real
   noise level per channel, the channel correlations (synthetic and real), the octave-band power ratios of brightness
   and colour (5 bands each, fine to coarse, medians over pairs), their RMS log error, NAFlow KLD and AKLD.
2. **Photos** (``real-lowlight/images/{lime,lol,dicm}``): the self-consistency ratio
   (``darksynth.estimation.noise.self_check.self_consistency``): the reference's first frame denoised by non-local means
   with the estimate's strength, the profile applied to that 8-bit denoised image by the library call ``apply
   --no-darken`` makes (``darksynth.apply.synthesize_image``), synthetic over real std on the 10% flattest 32-px
   blocks with means 8-247. Per folder the median ratio, the share within 0.8-1.25 and the photos beyond 0.5-2; per
   photo its ratio and the estimate's number of warnings.
3. **Clips** (``real-lowlight/clips/clip*``, 4 frames each, as ``--clip``; ``videos/starlight_submillilux.mov``,
   its first 16 frames): lag-1 correlation of the fine residual, the real one against that of the profile applied
   to a static clip (the protocol of ``scripts/noise/spectral_temporal_check.py``: one Kodak image, 8 frames).
   Compared only where the clip's lag-1 can show persistence: ``lag1_response``, how far the lag-1 of the clip's own
   denoised frames with the profile's noise rises from independent frames to a coefficient of 0.9 (the same draw),
   is at least :data:`MIN_LAG1_RESPONSE` (0.3). On a clip that pans under weak noise no pixel stays still for the
   measure, and on a letterbox crushed to black the profile's noise rounds to nothing: there the real lag-1 reads
   the same whatever the noise does (clip142 and clip159 pan, up to 9 and 1.3 px a frame, and respond 0.03 and
   0.02; the letterboxes clip450, clip474 and clip512 respond 0), and a static synthetic clip is compared with
   nothing.

Targets: printed after the record as ``OFF TARGET`` lines and their count (``real_data_record.target_misses``).

No subsample: every pair, photo, clip and the video (the work, about 21 processor minutes on one thread, is
under the 45 minutes a run may take on a 2-core machine; see Time). ``--limit N`` keeps the first N pairs of each
set, photos of each folder and clips (the video too), in name order, for a quick run: its set and folder figures
summarise other pairs or photos than the record's and are left out of the comparison; each photo's and clip's own
figures are still compared.

``--sets nam-cc15,dicm --out FILE`` runs some pair sets and photo folders only (a look while developing; the committed
record holds them all). ``--seed`` seeds the noise draws (each pair's synthesis, ``apply``'s draw, the static clip),
not the estimate.
Record: one per processor (:func:`record_path`), ``benchmarks/records/real_data.json`` for the first (an AMD EPYC)
and ``real_data.<processor>.json`` beside it for each other (``--out`` to write elsewhere), with the commit
measured, the tracked files that differed from it, the CPU, torch's threads and the run time (wall and processor
seconds). The same code reads differently on another processor (FFT and reduction bits differ; docs/spectral-noise.md,
"The same code on two processors"), so a run is compared with the record committed at HEAD for this machine's CPU
line, or, where none is, with the first record, said to be another processor's; every figure that moved further
from its target by more than the draws' own spread is printed, then their count (the exit code stays 0: it is a
report; how far from its target a figure lies, and the tolerances: ``real_data_record.py``).

Time: the first record (be4adab, every pair, photo, clip and the video) took 22.8 minutes of wall time and 21.5
processor minutes (pairs 13.5, photos 3.4, clips 4.6) on one thread (``OMP_NUM_THREADS=1``, ``nice -n 5``) of the
shared 2-core AMD EPYC (AVX-512) while other work kept its load average near 12: processor time is the measure that
other work does not inflate. The default 2 threads give the same figures (checked on the ``--limit 3`` subset);
on a loaded machine they spend several times the processor time waiting for each other. Measuring each clip's
response (a non-local means of its frames at full size, two syntheses) took the clips from 4.6 to 12.2 processor
minutes: the record of c4322b6 took 27.8 minutes of wall time and 42.8 processor minutes at 2 threads on the quiet
machine (pairs 15.8, photos 2.9, clips 9.1 minutes of wall time).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import resource
import statistics
import sys
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

import torch

from darksynth.apply import ApplyOptions, synthesize_image
from darksynth.errors import DarksynthError
from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.block_check import CONSISTENT_RANGE, self_consistency
from darksynth.estimation.noise.flat_blocks import stated_denoiser_strength
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.reference import load_reference
from darksynth.evaluation.measures.structure import COMPONENTS
from darksynth.evaluation.pairs import list_pair_set
from darksynth.evaluation.run.options import EvaluationOptions
from darksynth.evaluation.run.runner import evaluate_pairs
from darksynth.io.arrays import chw_to_hwc, hwc_to_chw
from darksynth.models.den import DEN
from darksynth.recipe import ClipRecipe
from darksynth.training.weights import default_weights_path, load_weights
from machine import cpu_summary
from real_data_record import (
    FIRST_RECORD,
    RECORDS,
    ROOT,
    clip_measurable,
    committed_records,
    git_output,
    not_compared,
    prior_band,
    record_path,
    regressions,
    target_misses,
    unmeasurable_clips,
)

DEFAULT_DATA = ROOT.parent / "shared" / "data"
TEMPORAL_CHECK = ROOT / "scripts" / "noise" / "spectral_temporal_check.py"

PARTS = ("pairs", "photos", "clips")
PAIR_SETS = ("sidd", "sidd-phones", "nam-cc15", "nam-cc60", "polyu")
PHOTO_FOLDERS = ("lime", "lol", "dicm")
VIDEO = Path("videos") / "starlight_submillilux.mov"
VIDEO_FRAMES = 16
"""Frames of the video read, as ``estimate`` reads a video."""
STATIC_FRAMES = 8
"""Frames of the static synthetic clip (the temporal check's default)."""
OUTLIER_RANGE = (0.5, 2.0)
"""A photo whose self-consistency ratio lies outside it is named."""

# --- measuring ---------------------------------------------------------------------------------------------------


def _rounded(value: float | None, digits: int = 4) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), digits)


def _rounded_map(values: dict[str, float | None] | None) -> dict[str, float | None]:
    return {key: _rounded(value) for key, value in (values or {}).items()}


def _say(line: str) -> None:
    print(line, flush=True)


def _or_nan(value: float | None) -> float:
    return math.nan if value is None else value


def _mean(values: Iterable[float | None]) -> float:
    known = [value for value in values if value is not None]
    return statistics.fmean(known) if known else math.nan


def _numbers(values: list[float | None]) -> str:
    return " ".join("  -  " if value is None else f"{value:5.2f}" for value in values)


def _linked_subset(root: Path, names: list[str], scratch: Path) -> Path:
    """A folder of links to the set's chosen pairs, named as the set, so that each pair draws the noise it draws in
    the whole set (the evaluation seeds each pair by its set's and its own name)."""
    subset = scratch / root.name
    for side in ("noisy", "clean"):
        (subset / side).mkdir(parents=True)
        for name in names:
            (subset / side / name).symlink_to(root / side / name)
    if (root / "cameras.csv").is_file():
        (subset / "cameras.csv").symlink_to(root / "cameras.csv")
    return subset


def measure_pair_set(root: Path, limit: int | None, seed: int, scratch: Path) -> dict[str, Any]:
    """The method ``den`` of ``darksynth evaluate`` on the set's chosen pairs, against their real noise."""
    started = time.perf_counter()
    listed = list_pair_set(root)
    chosen = [pair.name for pair in listed.pairs][:limit]
    source = root if len(chosen) == len(listed.pairs) else _linked_subset(root, chosen, scratch)
    options = EvaluationOptions(methods=("den",), seed=seed, inception=False, examples_per_set=0)
    outcome = evaluate_pairs([source], options, progress=lambda message: _say(f"  {message}"))
    report = outcome.results["sets"][root.name]
    den = report["methods"].get("den", {})
    bands = den.get("band_ratio") or {}
    return {
        "pairs": report["pairs"],
        "level_ratio": _rounded_map(den.get("level_ratio")),
        "channel_correlation": {
            "synthetic": _rounded_map(den.get("channel_correlation")),
            "real": _rounded_map(report["real"].get("channel_correlation")),
        },
        "band_ratio": {component: [_rounded(value) for value in bands.get(component, [])] for component in COMPONENTS},
        "band_prior_share": {
            component: [_rounded(share, 3) for share in shares]
            for component, shares in (den.get("band_prior_share") or {}).items()
        },
        "band_rms_log_error": _rounded(den.get("band_rms_log_error")),
        "kld_naflow": _rounded(den.get("kld_naflow"), 5),
        "akld": _rounded(den.get("akld"), 5),
        "problems": outcome.results["problems"],
        "seconds": round(time.perf_counter() - started, 1),
    }


PAIR_HEADER = (
    f"{'set':12s} {'pairs':>5s}  {'level r/g/b':17s} | {'brightness bands, fine to coarse':29s} | "
    f"{'colour bands, fine to coarse':29s} | {'corr syn/real':13s} | {'naflow':>7s} {'akld':>6s}"
)


def _bands(entry: dict[str, Any], component: str) -> str:
    # A band most estimates took from their prior is marked with *.
    return " ".join(
        f"{_or_nan(value):5.2f}{'*' if prior_band(entry, component, band) else ''}"
        for band, value in enumerate(entry["band_ratio"][component])
    )


def pair_set_line(name: str, entry: dict[str, Any]) -> str:
    level = [entry["level_ratio"].get(channel) for channel in ("r", "g", "b")]
    synthetic, real = (_mean(entry["channel_correlation"][side].values()) for side in ("synthetic", "real"))
    return (
        f"{name:12s} {entry['pairs']:5d}  {_numbers(level)} | {_bands(entry, 'brightness')} | "
        f"{_bands(entry, 'colour')} | {synthetic:5.2f}/{real:5.2f}   | "
        f"{_or_nan(entry['kld_naflow']):7.4f} {_or_nan(entry['akld']):6.3f}"
    )


def _estimate(frames: torch.Tensor, network: DEN, path: Path) -> tuple[Any, int]:
    found = estimate(frames, network, source=str(path))
    return found.profile, len(found.warnings)


def measure_photo(path: Path, network: DEN, seed: int) -> dict[str, Any]:
    """The self-consistency of the default estimate of one photo: its profile applied with ``apply --no-darken`` to
    the photo's denoised version, against the photo, on the flattest in-range blocks."""
    frames = load_reference(path)
    profile, warnings = _estimate(frames, network, path)
    denoised_frame = nlm_denoise(frames[:1], stated_denoiser_strength(profile.meta, frames))[0]
    denoised = (denoised_frame * 255.0).round().clamp(0, 255).to(torch.uint8)
    options = ApplyOptions(recipe=ClipRecipe(profile, darkening=None), seed=seed)
    synthetic, _ = synthesize_image(chw_to_hwc(denoised), path.name, options)
    check = self_consistency(frames[0], denoised.float() / 255.0, hwc_to_chw(synthetic).float() / 255.0)
    return {"ratio": _rounded(check.ratio), "blocks": check.blocks, "warnings": warnings}


def photo_folder_summary(per_photo: dict[str, dict[str, Any]]) -> dict[str, Any]:
    ratios = {name: entry["ratio"] for name, entry in per_photo.items() if entry.get("ratio") is not None}
    within = [name for name, ratio in ratios.items() if CONSISTENT_RANGE[0] <= ratio <= CONSISTENT_RANGE[1]]
    beyond = [name for name, ratio in ratios.items() if not OUTLIER_RANGE[0] <= ratio <= OUTLIER_RANGE[1]]
    return {
        "photos": len(per_photo),
        "median_ratio": _rounded(statistics.median(ratios.values())) if ratios else None,
        "share_consistent": _rounded(len(within) / len(ratios), 3) if ratios else None,
        "beyond": beyond,
    }


def measure_photo_folder(folder: Path, limit: int | None, network: DEN, seed: int) -> dict[str, Any]:
    started = time.perf_counter()
    per_photo: dict[str, dict[str, Any]] = {}
    for path in sorted(p for p in folder.iterdir() if not p.name.startswith("."))[:limit]:
        began = time.perf_counter()
        try:
            per_photo[path.name] = measure_photo(path, network, seed)
        except DarksynthError as error:
            per_photo[path.name] = {"error": str(error)}
            _say(f"  {folder.name}/{path.name}: {error}")
            continue
        entry = per_photo[path.name]
        _say(
            f"  {folder.name}/{path.name}: ratio {_or_nan(entry['ratio']):.3f}, {entry['warnings']} warnings "
            f"({time.perf_counter() - began:.0f} s)"
        )
    summary = photo_folder_summary(per_photo)
    summary["per_photo"] = per_photo
    summary["seconds"] = round(time.perf_counter() - started, 1)
    return summary


def photo_folder_line(name: str, entry: dict[str, Any]) -> str:
    beyond = ", ".join(f"{photo} {entry['per_photo'][photo]['ratio']:.2f}" for photo in entry["beyond"]) or "none"
    return (
        f"{name}: {entry['photos']} photos, median ratio {_or_nan(entry['median_ratio']):.2f}, "
        f"{100 * _or_nan(entry['share_consistent']):.0f}% within 0.8-1.25, beyond 0.5-2: {beyond}"
    )


def _load_temporal_check() -> ModuleType:
    """``scripts/noise/spectral_temporal_check.py`` as a module (scripts are no package): its static-clip
    protocol is the one measured."""
    spec = importlib.util.spec_from_file_location("spectral_temporal_check", TEMPORAL_CHECK)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def measure_clip(
    path: Path, folder: bool, network: DEN, temporal: ModuleType, scene: torch.Tensor, seed: int
) -> dict[str, Any]:
    """Lag-1 of the real clip's fine residual against that of its profile applied to a static clip, and how far
    persistent noise moves the real clip's lag-1 on its own frames (whether it can be compared)."""
    frames = load_reference(path, clip=folder, max_frames=VIDEO_FRAMES)
    real = temporal.lag1_correlation(frames)
    profile, warnings = _estimate(frames, network, path)
    synthetic = temporal.static_clip_correlation(profile, profile.noise, scene, STATIC_FRAMES, seed=seed)
    response = temporal.lag1_response(frames, profile.noise, stated_denoiser_strength(profile.meta, frames), seed=seed)
    return {
        "real": _rounded(real),
        "synthetic": _rounded(synthetic),
        "gap": _rounded(synthetic - real),
        "lag1_response": _rounded(response),
        "video_prior": "persistence_prior" in profile.meta.get("spectrum", {}),
        "warnings": warnings,
    }


def measure_clips(data: Path, limit: int | None, network: DEN, seed: int) -> dict[str, Any]:
    temporal = _load_temporal_check()
    scene = temporal.static_scene(data)
    low = data / "real-lowlight"
    references = [(path, True) for path in sorted((low / "clips").glob("clip*"))][:limit]
    references.append((low / VIDEO, False))
    measured: dict[str, Any] = {}
    for path, folder in references:
        began = time.perf_counter()
        try:
            entry = measure_clip(path, folder, network, temporal, scene, seed)
        except DarksynthError as error:
            measured[path.name] = {"error": str(error)}
            _say(f"  {path.name}: {error}")
            continue
        entry["seconds"] = round(time.perf_counter() - began, 1)
        measured[path.name] = entry
        measurable = "" if clip_measurable(entry) else "  not compared: its lag-1 cannot show persistence"
        _say(
            f"  {path.name:28s} real {_or_nan(entry['real']):6.3f}  synthetic {_or_nan(entry['synthetic']):6.3f}  "
            f"gap {_or_nan(entry['gap']):+.3f}  response {_or_nan(entry['lag1_response']):.2f}  "
            f"({entry['warnings']} warnings, {entry['seconds']:.0f} s){measurable}"
        )
    return measured


# --- the run -----------------------------------------------------------------------------------------------------


def _provenance() -> dict[str, Any]:
    status = git_output("status", "--porcelain", "--untracked-files=no") or ""
    changed = sorted(line[3:] for line in status.splitlines() if line.strip())
    return {
        "commit": (git_output("rev-parse", "--short", "HEAD") or "unknown").strip(),
        "dirty": bool(changed),
        "changed_files": changed,
    }


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--only", default=",".join(PARTS), help="comma-separated parts: pairs, photos, clips")
    parser.add_argument("--limit", type=int, default=None, help="pairs, photos per set or folder, clips")
    parser.add_argument("--seed", type=int, default=0, help="seed of the noise draws (not of the estimate)")
    parser.add_argument("--out", type=Path, default=None, help="default: this processor's record (record_path)")
    parser.add_argument("--no-compare", action="store_true", help="do not compare with the committed record")
    parser.add_argument(
        "--sets",
        default=None,
        help="comma-separated pair sets and photo folders to run (default all): a quick look while developing; the "
        "record that is committed holds them all",
    )
    arguments = parser.parse_args()
    parts = [part for part in arguments.only.split(",") if part]
    unknown = set(parts) - set(PARTS)
    if unknown or not parts:
        parser.error(f"--only takes {', '.join(PARTS)}; got {arguments.only!r}")
    if arguments.limit is not None and arguments.limit < 1:
        parser.error("--limit must be at least 1")
    arguments.parts = parts
    known = (*PAIR_SETS, *PHOTO_FOLDERS)
    arguments.sets = known if arguments.sets is None else tuple(n for n in arguments.sets.split(",") if n)
    if not arguments.sets or set(arguments.sets) - set(known):
        parser.error(f"--sets takes {', '.join(known)}; got {','.join(arguments.sets)!r}")
    records = committed_records()
    partial = set(arguments.sets) != set(known)
    if partial and (arguments.out is None or arguments.out.resolve() in {ROOT / path for path in records}):
        parser.error("--sets runs part of the record: name where it goes with --out (the committed record holds all)")
    if arguments.out is None:
        arguments.out = ROOT / record_path(records, cpu_summary())
    return arguments


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _compare(record: dict[str, Any]) -> None:
    records = committed_records()
    path = record_path(records, record["cpu"])
    before, other_processor = records.get(path), False
    if before is None and FIRST_RECORD in records:
        before, other_processor = records[FIRST_RECORD], True
    if before is None:
        _say(f"\nno committed record in {RECORDS}/ to compare with (the first record)")
        return
    _say(f"\ncompared with the committed record (measured at {before.get('commit')}, seed {before.get('seed')}):")
    if other_processor:
        _say(
            f"  made on another processor ({before.get('cpu')}): the same code reads differently on two processors, "
            f"so a WORSE below may be the processor's; commit this run as {path} to judge changes on this one"
        )
    for note in not_compared(before, record):
        _say(f"  not compared, other pairs or photos: {note}")
    for note in unmeasurable_clips(record):
        _say(f"  not compared, its lag-1 cannot show persistence: {note}")
    worse = regressions(before, record)
    for regression in worse:
        _say(f"  WORSE {regression.line()}")
    _say(f"{len(worse)} figures worse beyond seed noise")


def _measure_pairs(arguments: argparse.Namespace) -> dict[str, Any]:
    measured: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="real-data-") as scratch:
        for name in (n for n in PAIR_SETS if n in arguments.sets):
            _say(f"\npairs: {name}")
            root = arguments.data / "real-pairs" / name
            entry = measure_pair_set(root, arguments.limit, arguments.seed, Path(scratch))
            measured[name] = entry
            _say(f"{PAIR_HEADER}\n{pair_set_line(name, entry)}   ({entry['seconds']:.0f} s)")
    return measured


def _measure_photos(arguments: argparse.Namespace, network: DEN) -> dict[str, Any]:
    measured: dict[str, Any] = {}
    for name in (n for n in PHOTO_FOLDERS if n in arguments.sets):
        _say(f"\nphotos: {name}")
        folder = arguments.data / "real-lowlight" / "images" / name
        entry = measure_photo_folder(folder, arguments.limit, network, arguments.seed)
        measured[name] = entry
        _say(f"{photo_folder_line(name, entry)}   ({entry['seconds']:.0f} s)")
    return measured


def _measure_clips(arguments: argparse.Namespace, network: DEN) -> dict[str, Any]:
    _say("\nclips: lag-1 of the fine residual, real and of the profile applied to a static clip")
    return measure_clips(arguments.data, arguments.limit, network, arguments.seed)


def main() -> int:
    _say(cpu_summary())
    arguments = _arguments()
    import darksynth

    _say(f"darksynth from {Path(darksynth.__file__).parent}; data {arguments.data}")
    if not (arguments.data / "real-pairs").is_dir() or not (arguments.data / "real-lowlight").is_dir():
        print(f"{arguments.data}: no real-pairs/ and real-lowlight/ (the shared data)", file=sys.stderr)
        return 1
    started, cpu_started = time.perf_counter(), _cpu_seconds()
    record: dict[str, Any] = {
        "benchmark": "benchmarks/real_data.py",
        **_provenance(),
        "cpu": cpu_summary(),
        "seed": arguments.seed,
        "limit": arguments.limit,
        "threads": torch.get_num_threads(),
        "seconds": {},
        "cpu_seconds": {},
    }
    network = load_weights(default_weights_path())
    parts = {
        "pairs": lambda: _measure_pairs(arguments),
        "photos": lambda: _measure_photos(arguments, network),
        "clips": lambda: _measure_clips(arguments, network),
    }
    for part in arguments.parts:
        part_started, part_cpu = time.perf_counter(), _cpu_seconds()
        record[part] = parts[part]()
        record["seconds"][part] = round(time.perf_counter() - part_started, 1)
        # Process CPU time (all threads): on an idle 2-core machine the wall time is at most about this.
        record["cpu_seconds"][part] = round(_cpu_seconds() - part_cpu, 1)
    record["seconds"]["total"] = round(time.perf_counter() - started, 1)
    record["cpu_seconds"]["total"] = round(_cpu_seconds() - cpu_started, 1)
    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    arguments.out.write_text(json.dumps(record, indent=1) + "\n")
    minutes, cpu_minutes = record["seconds"]["total"] / 60, record["cpu_seconds"]["total"] / 60
    _say(f"\nwrote {arguments.out} ({minutes:.1f} min, {cpu_minutes:.1f} CPU min)")
    misses = target_misses(record)
    for miss in misses:
        _say(f"  OFF TARGET {miss}")
    _say(
        f"{len(misses)} figures off target (bands 0.8-1.25, * the prior's; photos 80% within 0.8-1.25, none beyond "
        "0.5-2; clips lag-1 within 0.15 or the video prior)"
    )
    if not arguments.no_compare:
        _compare(record)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
