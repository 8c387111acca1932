"""Peak memory and throughput of ``darksynth apply`` streaming a long 1080p video, against a short one.

Run: ``.venv/bin/python benchmarks/bench_video_memory.py [--seconds 120] [--short-seconds 10] [--fps 30]
[--width 1920 --height 1080] [--codec C] [--workdir DIR] [--profile-stages N]``.

A synthetic clean source video (a few distinct frames of a moving gradient and pattern, cycled) is encoded
cheaply (libx264 ultrafast, yuv420p, CRF 23) in this process and timed on its own. ``darksynth apply`` then runs
as a child process (``sys.executable -m darksynth``, default profile, seed 0): first on a 2-second clip as a
warm-up (long enough for ``apply`` to compile its kernel, it fills torch.compile's on-disk cache so that neither
measured run pays a cold compile), then on the short video, then on the long one. If the peak resident memory of
the long run is no larger than that of the short one, memory does not grow with the length of the video. With
``--profile-stages N`` the time per frame of decoding, synthesis and encoding is measured in this process on N
frames, after the children have finished.

The last line is ``video_seconds=<n> frames=<n> apply_s=<t> fps=<f> peak_rss_mib=<m> peak_rss_short_mib=<m2>``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import av
import numpy as np

from machine import cpu_summary

REPO = Path(__file__).resolve().parents[1]
PROFILE = REPO / "src" / "darksynth" / "data" / "default_profile.json"
DISTINCT_FRAMES = 15
"""Distinct source frames, cycled: enough motion for the decoder and encoder, cheap to generate."""
POLL_S = 0.25
WARMUP_SECONDS = 3.0
"""At 1080p and 30 fps, 90 frames are 5.6e8 values: above the stream size (5e8) from which ``apply`` compiles."""
MIB = 1024.0


def source_frames(width: int, height: int, count: int) -> list[av.VideoFrame]:
    """``count`` distinct yuv420p frames: a diagonal colour gradient that scrolls, with a moving sine pattern."""
    y = np.arange(height, dtype=np.float32)[:, None]
    x = np.arange(width, dtype=np.float32)[None, :]
    frames = []
    for index in range(count):
        phase = index / count
        shift = phase * width
        r = 255 * ((x + shift) % width) / width + 0 * y
        g = 255 * (y / height) + 0 * x
        b = 127.5 + 127.5 * np.sin(2 * np.pi * ((x + y) / 160 + phase)) * np.cos(2 * np.pi * (y / 90 - phase))
        rgb = np.clip(np.stack([r, g, b], axis=-1), 0, 255).astype(np.uint8)
        frames.append(av.VideoFrame.from_ndarray(rgb, format="rgb24").reformat(format="yuv420p"))
    return frames


def generate_source(path: Path, *, seconds: float, fps: int, width: int, height: int) -> tuple[int, float]:
    """Write the clean source video; return its frame count and the seconds it took."""
    started = time.perf_counter()
    frames = source_frames(width, height, DISTINCT_FRAMES)
    total = round(seconds * fps)
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.options = {"preset": "ultrafast", "crf": "23"}
        for index in range(total):
            frame = frames[index % len(frames)]
            frame.pts = index
            frame.time_base = Fraction(1, fps)
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))
    return total, time.perf_counter() - started


def read_kib(pid: int, fields: tuple[str, ...]) -> dict[str, int]:
    """Fields such as VmRSS and VmHWM from /proc/<pid>/status, in KiB; empty once the process is gone."""
    values: dict[str, int] = {}
    try:
        with open(f"/proc/{pid}/status") as status:
            for line in status:
                name, _, rest = line.partition(":")
                if name in fields:
                    values[name] = int(rest.split()[0])
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        pass
    return values


def descendants(pid: int) -> list[int]:
    """All live descendants of ``pid`` (torch.compile may start worker processes)."""
    found, queue = [], [pid]
    while queue:
        parent = queue.pop()
        try:
            for task in os.listdir(f"/proc/{parent}/task"):
                with open(f"/proc/{parent}/task/{task}/children") as children:
                    for child in children.read().split():
                        found.append(int(child))
                        queue.append(int(child))
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            pass
    return found


@dataclass
class ChildRun:
    """One ``darksynth apply`` child: wall time, peak RSS from wait4, and a sampled RSS timeline."""

    seconds: float = 0.0
    maxrss_kib: int = 0
    last_hwm_kib: int = 0
    peak_tree_kib: int = 0
    max_descendants: int = 0
    timeline: list[tuple[float, int]] = field(default_factory=list)
    frames: int = 0
    stderr_tail: str = ""


def run_apply(source: Path, output: Path, codec: str | None, profile: Path = PROFILE) -> ChildRun:
    """Run ``darksynth apply`` on one video in a child process and measure it.

    Peak memory: the child is reaped with ``os.wait4``, whose rusage belongs to that child alone (its ru_maxrss is
    the high-water mark of its resident set, or of a reaped descendant's if larger), so neither this process (which
    generated the sources) nor the other runs are mixed in, unlike ``RUSAGE_CHILDREN``, which keeps the maximum over
    all children ever reaped. A thread also polls /proc/<pid>/status while the child runs: VmRSS gives a timeline
    (does memory grow during the run?), VmHWM read last is a cross-check of ru_maxrss, and the summed RSS of the
    child and any live descendants catches memory in helper processes that a per-process peak would not add up.
    """
    command = [sys.executable, "-m", "darksynth", "apply", str(source), str(output)]
    command += ["--profile", str(profile), "--seed", "0"]
    if codec:
        command += ["--codec", codec]
    run = ChildRun()
    with tempfile.TemporaryFile(mode="w+") as stderr:
        started = time.perf_counter()
        child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr)
        done = threading.Event()

        def poll() -> None:
            while not done.is_set():
                own = read_kib(child.pid, ("VmRSS", "VmHWM"))
                if own:
                    run.last_hwm_kib = max(run.last_hwm_kib, own.get("VmHWM", 0))
                    run.timeline.append((time.perf_counter() - started, own.get("VmRSS", 0)))
                    extra = descendants(child.pid)
                    run.max_descendants = max(run.max_descendants, len(extra))
                    tree = own.get("VmRSS", 0) + sum(read_kib(p, ("VmRSS",)).get("VmRSS", 0) for p in extra)
                    run.peak_tree_kib = max(run.peak_tree_kib, tree)
                done.wait(POLL_S)

        poller = threading.Thread(target=poll, daemon=True)
        poller.start()
        _, status, usage = os.wait4(child.pid, 0)
        run.seconds = time.perf_counter() - started
        child.returncode = os.waitstatus_to_exitcode(status)  # already reaped: keep Popen from waiting again
        done.set()
        poller.join()
        stderr.seek(0)
        text = stderr.read()
        # The CLI's summary ("wrote 1 file(s), N frame(s) in T s; ...") may be wrapped over several lines.
        start = text.rfind("wrote ") if "wrote " in text else max(text.rstrip().rfind("\n"), 0)
        run.stderr_tail = " ".join(text[start:].split())
    if child.returncode != 0:
        raise SystemExit(f"darksynth apply failed with status {child.returncode}: {run.stderr_tail}")
    run.maxrss_kib = usage.ru_maxrss  # KiB on Linux
    manifest = json.loads(output.with_name(output.name + ".manifest.json").read_text())
    run.frames = sum(int(record["frames"]) for record in manifest["files"])
    return run


def rss_profile(run: ChildRun) -> str:
    """Resident memory at 10, 25, 50, 75 and 95 % of the run, in MiB."""
    if not run.timeline:
        return "no samples"
    points = []
    for share in (0.10, 0.25, 0.50, 0.75, 0.95):
        moment = share * run.seconds
        rss = min(run.timeline, key=lambda sample: abs(sample[0] - moment))[1]
        points.append(f"{share:.0%} {rss / MIB:.0f}")
    return ", ".join(points)


def report(label: str, run: ChildRun) -> None:
    print(
        f"{label}: {run.frames} frames in {run.seconds:.1f} s ({run.frames / run.seconds:.2f} fps); "
        f"peak RSS {run.maxrss_kib / MIB:.0f} MiB (wait4 ru_maxrss; last VmHWM {run.last_hwm_kib / MIB:.0f} MiB, "
        f"peak RSS of the process tree {run.peak_tree_kib / MIB:.0f} MiB, "
        f"at most {run.max_descendants} descendant process(es))"
    )
    print(f"  RSS (MiB) at share of the run: {rss_profile(run)}")
    print(f"  apply: {run.stderr_tail}")


def profile_stages(source: Path, output: Path, frames: int, codec: str | None, profile: Path = PROFILE) -> None:
    """Time decoding, synthesis (compiled, warmed up) and encoding separately on ``frames`` frames, in process."""
    import torch

    from darksynth.io.video import VideoWriter, iter_video_frames, probe_video
    from darksynth.profile import load_profile
    from darksynth.synthesize import ClipSynthesizer, draw_clip_parameters

    info = probe_video(source)
    started = time.perf_counter()
    decoded = []
    for frame in iter_video_frames(source):
        decoded.append(frame)
        if len(decoded) == frames:
            break
    decode_s = time.perf_counter() - started

    generator = torch.Generator().manual_seed(0)
    parameters = draw_clip_parameters(load_profile(profile), darkening="profile", generator=generator)
    synthesizer = ClipSynthesizer(parameters, generator=generator, compile=True)
    started = time.perf_counter()
    synthesizer(torch.from_numpy(decoded[0]).permute(2, 0, 1))
    first_call_s = time.perf_counter() - started
    for frame in decoded[:3]:
        synthesizer(torch.from_numpy(frame).permute(2, 0, 1))
    started = time.perf_counter()
    results = []
    for frame in decoded:
        result = synthesizer(torch.from_numpy(frame).permute(2, 0, 1))
        results.append(np.ascontiguousarray(result.permute(1, 2, 0).numpy()))
    synthesize_s = time.perf_counter() - started

    writer_options: dict[str, object] = {"width": info.width, "height": info.height, "fps": info.fps}
    if codec:
        writer_options["codec"] = codec
    started = time.perf_counter()
    with VideoWriter(output, **writer_options) as writer:  # type: ignore[arg-type]
        for result in results:
            writer.write(result)
    encode_s = time.perf_counter() - started  # includes flushing the encoder's look-ahead at the end

    total = decode_s + synthesize_s + encode_s
    print(f"stages on {len(decoded)} frames, in process (compiled kernel, first call {first_call_s:.1f} s, excluded):")
    for name, seconds in (("decode", decode_s), ("synthesize", synthesize_s), ("encode", encode_s)):
        print(
            f"  {name:<10} {seconds / len(decoded) * 1e3:7.1f} ms/frame  {seconds / total:4.0%}  "
            f"({len(decoded) / seconds:.1f} fps alone)"
        )
    print(f"  sum        {total / len(decoded) * 1e3:7.1f} ms/frame  -> {len(decoded) / total:.2f} fps")


def main() -> None:
    print(cpu_summary(), flush=True)
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=120.0, help="length of the long video")
    parser.add_argument("--short-seconds", type=float, default=10.0, help="length of the short video")
    parser.add_argument("--fps", type=int, default=30)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--codec", default=None, help="passed to darksynth apply --codec (default: its own)")
    parser.add_argument("--workdir", type=Path, default=None, help="kept if given; else a temporary folder")
    parser.add_argument("--profile-stages", type=int, default=0, metavar="N", help="time the stages on N frames")
    parser.add_argument(
        "--profile",
        type=Path,
        default=PROFILE,
        help="noise profile (default: the shipped paper-model default; an estimate'd profile takes the sRGB path)",
    )
    args = parser.parse_args()

    import torch  # only to report the thread count the children get by default (they run the same torch)

    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="darksynth-bench-video-"))
    workdir.mkdir(parents=True, exist_ok=True)
    suffix = ".mkv" if args.codec == "ffv1" else ".mp4"
    try:
        commit = subprocess.run(
            ["git", "-C", str(REPO), "describe", "--always", "--dirty"], capture_output=True, text=True, check=False
        ).stdout.strip()
        print(f"darksynth at {commit or 'unknown commit'}")
        print(
            f"{args.width}x{args.height} at {args.fps} fps; {os.cpu_count()} cores, torch {torch.__version__} "
            f"with {torch.get_num_threads()} threads, PyAV {av.__version__}; codec {args.codec or 'default'}"
        )
        sources = {}
        for name, seconds in (("warmup", WARMUP_SECONDS), ("short", args.short_seconds), ("long", args.seconds)):
            path = workdir / f"source_{name}.mp4"
            frames, took = generate_source(path, seconds=seconds, fps=args.fps, width=args.width, height=args.height)
            size = path.stat().st_size / MIB / MIB
            print(f"generated {name} source: {frames} frames in {took:.1f} s ({frames / took:.0f} fps), {size:.1f} MiB")
            sources[name] = path

        runs = {}
        for name in ("warmup", "short", "long"):
            output = workdir / f"out_{name}{suffix}"
            runs[name] = run = run_apply(sources[name], output, args.codec, args.profile)
            size = output.stat().st_size / MIB / MIB
            report(f"apply {name}", run)
            print(f"  output {size:.0f} MiB, {size * 8 * 1.048576 / (run.frames / args.fps):.0f} Mbit/s")
            output.unlink()

        long, short = runs["long"], runs["short"]
        if long.frames > short.frames and long.seconds > short.seconds:
            steady = (long.frames - short.frames) / (long.seconds - short.seconds)
            overhead = short.seconds - short.frames / steady
            if overhead >= 0:
                print(f"steady-state throughput (long minus short): {steady:.2f} fps; fixed cost ~{overhead:.1f} s")
            else:  # the short run was faster per frame than the long one: the machine's speed varied
                print("per-frame speed differed between the runs more than the fixed start-up cost; none separable")
        growth = (long.maxrss_kib - short.maxrss_kib) / MIB
        print(f"peak RSS long - short: {growth:+.0f} MiB; under 1 GiB: {long.maxrss_kib < 1024 * 1024}")

        if args.profile_stages:
            profile_stages(
                sources["short"], workdir / f"out_stages{suffix}", args.profile_stages, args.codec, args.profile
            )

        print(
            f"video_seconds={args.seconds:g} frames={long.frames} apply_s={long.seconds:.1f} "
            f"fps={long.frames / long.seconds:.2f} peak_rss_mib={long.maxrss_kib / MIB:.0f} "
            f"peak_rss_short_mib={short.maxrss_kib / MIB:.0f}"
        )
    finally:
        if args.workdir is None:
            shutil.rmtree(workdir, ignore_errors=True)


if __name__ == "__main__":
    main()
