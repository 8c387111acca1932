"""The options that ``apply``, ``convert`` and ``preview`` share, declared once: each is a type that carries its
flag and help, and a command gives it its default (read from its job's options, see
:func:`~darksynth.cli.common.default_of`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from darksynth.cameras.presets import CAMERA_KINDS

ProfileOption = Annotated[
    Path | None,
    typer.Option(
        "--profile",
        "-p",
        help="Noise profile JSON. May be left out with --camera: the default profile then gives the darkening and "
        "the column noise, the camera the rest.",
    ),
]
AlphaOption = Annotated[float | None, typer.Option(help="Darkening scale, with --gamma.")]
GammaOption = Annotated[float | None, typer.Option(help="Darkening exponent: x_d = alpha * x ** (1/gamma).")]
NoDarkenOption = Annotated[bool, typer.Option("--no-darken", help="Add noise only, keep the brightness.")]
JitterOption = Annotated[
    bool,
    typer.Option(
        "--jitter",
        help="Draw each file's or clip's parameters within the profile's ranges (default: the profile's values).",
    ),
]
CodecOption = Annotated[str | None, typer.Option(help="Video codec, e.g. libx264 (default), ffv1.")]
CrfOption = Annotated[int | None, typer.Option(min=0, max=63, help="Video quality (lower is better).")]
PixFmtOption = Annotated[
    str | None, typer.Option("--pix-fmt", help="Video pixel format, e.g. yuv444p (default yuv420p for H.264).")
]
DeviceOption = Annotated[str, typer.Option(help="torch device: cpu, cuda, cuda:1 ...")]
BlurOption = Annotated[
    bool,
    typer.Option(
        "--blur/--no-blur",
        help="Motion blur along each clip's flow with the profile's exposure fraction, camera shake for images.",
    ),
]
FlickerOption = Annotated[
    bool, typer.Option("--flicker/--no-flicker", help="The profile's per-frame brightness flicker on clips and videos.")
]
MatchColourOption = Annotated[
    bool,
    typer.Option(
        "--match-colour",
        help="Also give each input the reference's colour cast (per-channel gains), e.g. sodium-orange streets.",
    ),
]
CameraOption = Annotated[
    str | None,
    typer.Option(
        "--camera",
        metavar="NAME",
        help="Draw each file's or clip's camera from real ones (seeded, recorded in the manifest): "
        + "; ".join(f"{name}: {kind}" for name, kind in CAMERA_KINDS.items())
        + ". With a profile from estimate, its level, JPEG and finer octaves stay and the rest is drawn.",
    ),
]
