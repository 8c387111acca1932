"""Peak memory and throughput of ``darksynth apply`` streaming a long 1080p video, against a short one.

Run: ``.venv/bin/python benchmarks/bench_video_memory.py [--seconds 120] [--short-seconds 10] [--fps 30]
[--width 1920 --height 1080] [--codec C] [--workdir DIR] [--profile-stages N] [--blur]``.

A synthetic clean source video (a few distinct frames of a moving gradient and pattern, cycled) is encoded
cheaply (libx264 ultrafast, yuv420p, CRF 23) in this process and timed on its own. ``darksynth apply`` then runs
as a child process (``sys.executable -m darksynth``, default profile, seed 0): first on a 2-second clip as a
warm-up (long enough for ``apply`` to compile its kernel, it fills torch.compile's on-disk cache so that neither
measured run pays a cold compile), then on the short video, then on the long one. If the peak resident memory of
the long run is no larger than that of the short one, memory does not grow with the length of the video. With
``--profile-stages N`` the time per frame of decoding, synthesis and encoding is measured in this process on N
frames, after the children have finished.

With ``--blur`` the profile gets a light section (:data:`LIGHT`: exposure fraction 1.0, flicker), written to the
working folder, so ``apply`` blurs every frame along the scene's optical flow before its noise (the warm-up runs
with ``--no-blur --no-flicker``: it only fills the compile cache). The stages then also time
``MotionBlurStream(1.0).push`` frame by frame on the same frames (the whole picture moves: the worst case for the
blur) and on two sources where only the middle third of the rows, or of the columns, moves, each with a breakdown
(flow, remaps, the rest), and print the ratio of blur to encode per frame.

The last line is ``video_seconds=<n> frames=<n> apply_s=<t> fps=<f> peak_rss_mib=<m> peak_rss_short_mib=<m2>``,
followed by `` blur=1`` with ``--blur``.
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
from typing import Any

import av
import numpy as np

from machine import cpu_summary, opencv_summary

REPO = Path(__file__).resolve().parents[1]
PROFILE = REPO / "src" / "darksynth" / "data" / "default_profile.json"
DISTINCT_FRAMES = 15
"""Distinct source frames, cycled: enough motion for the decoder and encoder, cheap to generate."""
POLL_S = 0.25
WARMUP_SECONDS = 3.0
"""At 1080p and 30 fps, 90 frames are 5.6e8 values: above the stream size (5e8) from which ``apply`` compiles."""
MIB = 1024.0


LIGHT = {"exposure_fraction": 1.0, "flicker": 0.03, "flicker_correlation": 0.6}
"""The light section of ``--blur``: a shutter open for the whole frame interval (the longest blur) and flicker."""


def blur_profile(path: Path) -> dict[str, Any]:
    """The profile document at ``path`` with :data:`LIGHT` as its light section (profile version 5 at least)."""
    document: dict[str, Any] = json.loads(path.read_text())
    document["version"] = max(5, int(document.get("version", 1)))
    document["light"] = document.get("light", {}) | LIGHT
    return document


def source_frames(width: int, height: int, count: int, moving: str = "all") -> list[av.VideoFrame]:
    """``count`` distinct yuv420p frames: a diagonal colour gradient that scrolls, with a moving sine pattern.

    ``moving``: "all" (the whole frame moves, the worst case for motion blur), "rows" (only the middle third of
    the rows moves, the rest is the first frame, still) or "columns" (only the middle third of the columns)."""
    y = np.arange(height, dtype=np.float32)[:, None]
    x = np.arange(width, dtype=np.float32)[None, :]

    def picture(phase: float) -> np.ndarray:
        shift = phase * width
        r = 255 * ((x + shift) % width) / width + 0 * y
        g = 255 * (y / height) + 0 * x
        b = 127.5 + 127.5 * np.sin(2 * np.pi * ((x + y) / 160 + phase)) * np.cos(2 * np.pi * (y / 90 - phase))
        return np.clip(np.stack([r, g, b], axis=-1), 0, 255).astype(np.uint8)

    still = picture(0.0) if moving != "all" else None
    frames = []
    for index in range(count):
        rgb = picture(index / count)
        if still is not None:
            region = rgb.copy()
            rgb = still.copy()
            if moving == "rows":
                rgb[height // 3 : 2 * height // 3] = region[height // 3 : 2 * height // 3]
            elif moving == "columns":
                rgb[:, width // 3 : 2 * width // 3] = region[:, width // 3 : 2 * width // 3]
            else:
                raise ValueError(f"unknown moving region {moving!r}")
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


def run_apply(
    source: Path, output: Path, codec: str | None, profile: Path = PROFILE, extra: tuple[str, ...] = ()
) -> ChildRun:
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
    command += list(extra)
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


class _TimedCv2:
    """Stands in for the ``cv2`` module inside ``darksynth.light.motion_blur`` while the blur is profiled: the
    calls named in ``timed`` add their wall time to ``seconds``; everything else is OpenCV's own."""

    def __init__(self, real: Any, timed: tuple[str, ...]) -> None:
        self._real, self._timed = real, timed
        self.seconds: dict[str, float] = dict.fromkeys(timed, 0.0)

    def __getattr__(self, name: str) -> Any:
        attribute = getattr(self._real, name)
        if name not in self._timed:
            return attribute

        def timed(*args: Any, **kwargs: Any) -> Any:
            started = time.perf_counter()
            try:
                return attribute(*args, **kwargs)
            finally:
                self.seconds[name] += time.perf_counter() - started

        return timed


@dataclass
class BlurTiming:
    """Per finished frame of ``MotionBlurStream(1.0).push``, in seconds, and where the time went (summed)."""

    per_frame: list[float] = field(default_factory=list)
    parts: dict[str, float] = field(default_factory=dict)
    cuts: int = 0


def time_blur(frames: list[np.ndarray], exposure_fraction: float = 1.0) -> BlurTiming:
    """``MotionBlurStream(exposure_fraction).push`` timed frame by frame (the first push only holds its frame and
    is left out), with a breakdown of the same calls: the flow (grey images, scene-cut test, two DIS flows, their
    checks and the resize to full resolution) timed as ``push`` runs it, and inside ``blur_along`` the OpenCV
    remaps (the ternary steps' resamplings), the other OpenCV calls, and the rest (numpy: velocity, the sRGB encode,
    blending, copies)."""
    from darksynth.light import motion_blur

    timing = BlurTiming()
    stream = motion_blur.MotionBlurStream(exposure_fraction)
    real_cv2 = motion_blur.cv2
    proxy = _TimedCv2(real_cv2, ("remap", "multiply", "addWeighted", "LUT", "split", "magnitude", "resize", "cvtColor"))
    wrapped = {
        name: getattr(motion_blur, name)
        for name in ("flow_image", "is_scene_cut", "dense_flow", "flow_holds", "full_resolution", "blur_along")
    }
    spent = dict.fromkeys(wrapped, 0.0)
    in_blur = dict.fromkeys(proxy.seconds, 0.0)  # OpenCV time inside blur_along only (flow_holds remaps too)

    def timer(name: str, function: Any) -> Any:
        def timed(*args: Any, **kwargs: Any) -> Any:
            before = dict(proxy.seconds)
            started = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent[name] += time.perf_counter() - started
                if name == "blur_along":
                    for call, seconds in proxy.seconds.items():
                        in_blur[call] += seconds - before[call]

        return timed

    try:
        motion_blur.cv2 = proxy  # type: ignore[attr-defined]
        for name, function in wrapped.items():
            setattr(motion_blur, name, timer(name, function))
        for index, frame in enumerate(frames):
            started = time.perf_counter()
            stream.push(frame)
            if index:
                timing.per_frame.append(time.perf_counter() - started)
        started = time.perf_counter()
        stream.finish()  # the last frame, blurred with its flow to the previous one alone
        timing.per_frame.append(time.perf_counter() - started)
    finally:
        motion_blur.cv2 = real_cv2  # type: ignore[attr-defined]
        for name, function in wrapped.items():
            setattr(motion_blur, name, function)
    flow = sum(spent[name] for name in ("flow_image", "is_scene_cut", "dense_flow", "flow_holds", "full_resolution"))
    timing.parts = {
        "flow (grey, cut test, 2x DIS, checks, upscale)": flow,
        "  of which DIS": spent["dense_flow"],
        "blur_along (the integral)": spent["blur_along"],
        "  of which remap": in_blur["remap"],
        "  of which multiply + addWeighted (offsets, means)": in_blur["multiply"] + in_blur["addWeighted"],
        "  of which LUT (sRGB decode) + split + magnitude": in_blur["LUT"] + in_blur["split"] + in_blur["magnitude"],
    }
    timing.parts["  of which the rest (sRGB encode, blend, copies)"] = spent["blur_along"] - sum(
        in_blur[name] for name in ("remap", "multiply", "addWeighted", "LUT", "split", "magnitude")
    )
    timing.cuts = stream.cuts
    return timing


def _median_ms(values: list[float]) -> float:
    return float(np.median(values)) * 1e3 if values else float("nan")


def profile_stages(
    source: Path,
    output: Path,
    frames: int,
    codec: str | None,
    profile: Path = PROFILE,
    *,
    blur: bool = False,
    width: int = 1920,
    height: int = 1080,
) -> dict[str, float]:
    """Time decoding, motion blur (with ``blur``), synthesis (compiled, warmed up) and encoding separately on
    ``frames`` frames, in process, frame by frame. Returns the per-frame medians in ms."""
    import torch

    from darksynth.io.video import VideoWriter, iter_video_frames, probe_video
    from darksynth.profile import load_profile
    from darksynth.recipe import draw_clip_parameters
    from darksynth.synthesize import ClipSynthesizer

    info = probe_video(source)
    decoded: list[np.ndarray] = []
    decode_times: list[float] = []
    iterator = iter_video_frames(source)
    started = time.perf_counter()
    total_started = started
    for frame in iterator:
        decode_times.append(time.perf_counter() - started)
        decoded.append(frame)
        if len(decoded) == frames:
            break
        started = time.perf_counter()
    decode_s = time.perf_counter() - total_started

    blurs: dict[str, BlurTiming] = {}
    if blur:
        blurs["blur, whole frame moves"] = time_blur(decoded)
        for moving, label in (
            ("rows", "blur, middle third of rows moves"),
            ("columns", "blur, middle third of columns moves"),
        ):
            partial = [
                f.to_ndarray(format="rgb24") for f in source_frames(width, height, DISTINCT_FRAMES, moving=moving)
            ]
            blurs[label] = time_blur([partial[index % len(partial)] for index in range(len(decoded))])

    generator = torch.Generator().manual_seed(0)
    parameters = draw_clip_parameters(load_profile(profile), darkening="profile", generator=generator)
    synthesizer = ClipSynthesizer(parameters, generator=generator, compile=True)
    started = time.perf_counter()
    synthesizer(torch.from_numpy(decoded[0]).permute(2, 0, 1))
    first_call_s = time.perf_counter() - started
    for frame in decoded[:3]:
        synthesizer(torch.from_numpy(frame).permute(2, 0, 1))
    results = []
    noise_times: list[float] = []
    for frame in decoded:
        started = time.perf_counter()
        result = synthesizer(torch.from_numpy(frame).permute(2, 0, 1))
        results.append(np.ascontiguousarray(result.permute(1, 2, 0).numpy()))
        noise_times.append(time.perf_counter() - started)
    synthesize_s = sum(noise_times)

    writer_options: dict[str, object] = {"width": info.width, "height": info.height, "fps": info.fps}
    if codec:
        writer_options["codec"] = codec
    encode_times: list[float] = []
    total_started = time.perf_counter()
    with VideoWriter(output, **writer_options) as writer:  # type: ignore[arg-type]
        for result in results:
            started = time.perf_counter()
            writer.write(result)
            encode_times.append(time.perf_counter() - started)
    encode_s = time.perf_counter() - total_started  # includes flushing the encoder's look-ahead at the end

    count = len(decoded)
    rows = [("decode", decode_times, decode_s)]
    rows += [(label, timing.per_frame, sum(timing.per_frame)) for label, timing in blurs.items()]
    rows += [("noise (compiled)", noise_times, synthesize_s), ("encode", encode_times, encode_s)]
    print(
        f"stages on {count} frames, in process, one after another (compiled kernel, first call {first_call_s:.1f} s, "
        "excluded); per frame: median of the calls, and mean = total / frames (encode: with the final flush)"
    )
    total = decode_s + synthesize_s + encode_s + (sum(blurs[next(iter(blurs))].per_frame) if blurs else 0.0)
    for name, times, seconds in rows:
        mean = seconds / max(1, len(times))
        print(
            f"  {name:<36} median {_median_ms(times):7.1f} ms  mean {mean * 1e3:7.1f} ms  "
            f"({1 / mean if mean else float('inf'):.1f} fps alone)"
        )
    print(f"  sum of means (whole-frame blur)      {total / count * 1e3:7.1f} ms/frame  -> {count / total:.2f} fps")
    medians = {"decode": _median_ms(decode_times), "noise": _median_ms(noise_times), "encode": _median_ms(encode_times)}
    encode_mean = encode_s / count
    for label, timing in blurs.items():
        frames_timed = max(1, len(timing.per_frame))
        blur_mean = sum(timing.per_frame) / frames_timed
        print(
            f"  {label}: blur / encode = {blur_mean / encode_mean:.2f} per frame (means; on medians "
            f"{_median_ms(timing.per_frame) / medians['encode']:.2f}, but the encoder's per-call median leaves out "
            "the work its threads and look-ahead do between calls); "
            f"pairs without blur (cuts or failed flow): {timing.cuts}"
        )
        for part, seconds in timing.parts.items():
            print(f"      {part:<44} {seconds / frames_timed * 1e3:7.1f} ms/frame")
    key = {"blur, whole frame moves": "blur_full", "blur, middle third of rows moves": "blur_rows"}
    key["blur, middle third of columns moves"] = "blur_columns"
    for label, timing in blurs.items():
        medians[key[label]] = _median_ms(timing.per_frame)
    medians["encode_mean"] = encode_mean * 1e3
    return medians


def steady_ms_per_frame(short: ChildRun, long: ChildRun) -> float | None:
    """Milliseconds a frame in the steady state: the difference of two runs' times over that of their frames (None
    when the long run is not longer)."""
    if long.frames <= short.frames or long.seconds <= short.seconds:
        return None
    return (long.seconds - short.seconds) / (long.frames - short.frames) * 1e3


def main() -> None:
    print(cpu_summary(), flush=True)
    print(opencv_summary(), flush=True)  # the motion blur's remaps and flow run in OpenCV
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
    parser.add_argument(
        "--blur",
        action="store_true",
        help="apply with motion blur (exposure_fraction 1.0) and flicker: the profile plus a light section, "
        "written to the workdir; the stages then include MotionBlurStream(1.0).push",
    )
    args = parser.parse_args()

    import torch  # only to report the thread count the children get by default (they run the same torch)

    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="darksynth-bench-video-"))
    workdir.mkdir(parents=True, exist_ok=True)
    suffix = ".mkv" if args.codec == "ffv1" else ".mp4"
    profile = args.profile
    try:
        if args.blur:
            profile = workdir / "profile_blur.json"
            profile.write_text(json.dumps(blur_profile(args.profile), indent=2))
            print(f"profile with motion blur and flicker: {profile} (light: {json.dumps(LIGHT)})")
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
            # The warm-up only fills torch.compile's cache: without the blur it takes seconds, not minutes.
            extra = ("--no-blur", "--no-flicker") if args.blur and name == "warmup" else ()
            runs[name] = run = run_apply(sources[name], output, args.codec, profile, extra)
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
        if args.blur:
            # The same two videos without blur and flicker: what the blur adds to a frame in the running pipeline,
            # where the encoder's threads share the two cores with everything else, in the steady state (long
            # minus short, which leaves out start-up, compile-cache load and the encoder's fill and flush).
            plain = {}
            for name in ("short", "long"):
                output = workdir / f"out_{name}_plain{suffix}"
                plain[name] = run_apply(sources[name], output, args.codec, profile, ("--no-blur", "--no-flicker"))
                report(f"apply {name}, --no-blur --no-flicker", plain[name])
                output.unlink()
            with_blur = steady_ms_per_frame(short, long)
            without = steady_ms_per_frame(plain["short"], plain["long"])
            if with_blur is not None and without is not None:
                print(
                    f"steady state per frame: {with_blur:.1f} ms with blur and flicker, {without:.1f} ms without; "
                    f"the blur adds {with_blur - without:.1f} ms a frame in the pipeline"
                )

        if args.profile_stages:
            print(cpu_summary(), flush=True)
            print(opencv_summary(), flush=True)
            profile_stages(
                sources["short"],
                workdir / f"out_stages{suffix}",
                args.profile_stages,
                args.codec,
                profile,
                blur=args.blur,
                width=args.width,
                height=args.height,
            )

        print(
            f"video_seconds={args.seconds:g} frames={long.frames} apply_s={long.seconds:.1f} "
            f"fps={long.frames / long.seconds:.2f} peak_rss_mib={long.maxrss_kib / MIB:.0f} "
            f"peak_rss_short_mib={short.maxrss_kib / MIB:.0f}" + (" blur=1" if args.blur else "")
        )
    finally:
        if args.workdir is None:
            shutil.rmtree(workdir, ignore_errors=True)


if __name__ == "__main__":
    main()
