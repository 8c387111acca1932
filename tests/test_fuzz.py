"""Fuzzing the readers of user files: every generated input ends in a result or a one-line DarksynthError.

The three targets are the noise profile (the dict parser and ``load_profile``), the image reader and the video
reader. The generators start from valid inputs and break them the ways real files break (wrong types, missing
fields, truncation, flipped bytes, a corrupted header, a huge declared size) as well as feeding plain garbage.
Runs are derandomized and keep no example database, so CI tries the same inputs every time; the number tried
per target and what the runs found are in docs/robustness.md.
"""

from __future__ import annotations

import functools
import io
import json
import math
import struct
import tempfile
import time
import warnings
import zlib
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import PIL.Image
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from darksynth.errors import DarksynthError
from darksynth.io.images import IMAGE_SUFFIXES, Image, read_image
from darksynth.io.video import VideoEncoding, VideoWriter, iter_video_frames, probe_video
from darksynth.noise.components import noise_parameters, profile_version
from darksynth.profile import DARKENING_LIMITS, PROFILE_FORMAT, Profile, load_profile, parse_profile

pytestmark = pytest.mark.slow  # each target tries hundreds to thousands of inputs

PROFILE_EXAMPLES = 1000
PROFILE_TEXT_EXAMPLES = 500
IMAGE_EXAMPLES = 1500
IMAGE_GARBAGE_EXAMPLES = 300
VIDEO_EXAMPLES = 800
VIDEO_GARBAGE_EXAMPLES = 200

# One input that takes this long is treated as a hang: the inputs are at most a few kilobytes.
SECONDS_PER_INPUT = 20.0


def _fuzz_settings(examples: int) -> settings:
    return settings(
        derandomize=True,
        database=None,
        max_examples=examples,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


def _result_or_one_line_error(read: Callable[[], Any], names: str) -> Any:
    """``read()``'s result, or None when it raised a DarksynthError of one line that starts with ``names``.

    Any other exception propagates, so hypothesis reports it with the input that caused it; so does a read that
    takes longer than SECONDS_PER_INPUT.
    """
    start = time.monotonic()
    # The suite turns warnings into errors; a user's run only prints them, and the reader goes on past them.
    with warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        try:
            result = read()
        except DarksynthError as error:
            message = str(error)
            assert message.startswith(f"{names}: "), message
            assert message.isprintable(), f"not one printable line: {message!r}"
            event("one-line error")
            return None
        finally:
            assert time.monotonic() - start < SECONDS_PER_INPUT
            if warned:
                event(f"{warned[0].category.__name__} printed")
    event("read")
    return result


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


# --- byte mutations shared by the image and video targets ------------------------------------------------------


@st.composite
def _mutated(draw: st.DrawFn, data: bytes) -> bytes:
    """``data`` broken in one to four ways: truncated, bytes flipped, the header overwritten, bytes inserted,
    a span zeroed or repeated."""
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        if not out:
            break
        kind = draw(st.sampled_from(["truncate", "flip", "header", "insert", "zero", "repeat"]))
        at = draw(st.integers(0, len(out) - 1))
        if kind == "truncate":
            del out[at:]
        elif kind == "flip":
            out[at] ^= draw(st.integers(1, 255))
        elif kind == "header":
            start = draw(st.integers(0, min(len(out), 64) - 1))
            patch = draw(st.binary(min_size=1, max_size=8))
            out[start : start + len(patch)] = patch
        elif kind == "insert":
            out[at:at] = draw(st.binary(min_size=1, max_size=64))
        elif kind == "zero":
            length = draw(st.integers(1, 256))
            out[at : at + length] = bytes(len(out[at : at + length]))
        else:
            length = draw(st.integers(1, 256))
            out[at:at] = out[at : at + length]
    return bytes(out)


# --- profiles ----------------------------------------------------------------------------------------------------

_HUGE_INT = 10**400  # valid JSON, finite, but beyond any float
_ODD_NUMBERS = st.sampled_from(
    [math.nan, math.inf, -math.inf, -1.0, -0.0, 0.0, 1e-320, 1e308, -1e308, 2**63, -(2**63), _HUGE_INT, -_HUGE_INT]
)
_SCALARS = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=True, allow_infinity=True)
    | _ODD_NUMBERS
    | st.text(max_size=12)
)
_JSON = st.recursive(
    _SCALARS,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


@st.composite
def _valid_profile(draw: st.DrawFn) -> dict[str, Any]:
    version = draw(st.integers(1, profile_version()))
    noise: dict[str, Any] = {}
    for parameter in noise_parameters():
        if parameter.since_version > version or (parameter.since_version > 1 and draw(st.booleans())):
            continue
        value = st.floats(parameter.minimum, parameter.maximum)
        noise[parameter.name] = draw(
            value if parameter.size == 1 else st.lists(value, min_size=parameter.size, max_size=parameter.size)
        )
    document: dict[str, Any] = {"format": PROFILE_FORMAT, "version": version, "noise": noise}
    if draw(st.booleans()):
        document["darkening"] = {
            name: draw(st.floats(low, high, exclude_min=True)) for name, (low, high) in DARKENING_LIMITS.items()
        }
    if draw(st.booleans()):
        ranged = draw(st.lists(st.sampled_from([*noise, *DARKENING_LIMITS]), unique=True, max_size=3))
        limits = {p.name: (p.minimum, p.maximum) for p in noise_parameters()} | DARKENING_LIMITS
        ranges = {}
        for name in ranged:
            low, high = limits[name]
            pair = sorted(
                draw(st.lists(st.floats(low, high, exclude_min=name in DARKENING_LIMITS), min_size=2, max_size=2))
            )
            ranges[name] = pair
        document["ranges"] = ranges
    if draw(st.booleans()):
        document["meta"] = draw(st.dictionaries(st.text(max_size=8), _JSON, max_size=3))
    return document


def _containers(document: Any) -> list[Any]:
    """Every dict and list inside ``document``, itself first."""
    found = [document]
    for item in document.values() if isinstance(document, dict) else document if isinstance(document, list) else ():
        if isinstance(item, dict | list):
            found.extend(_containers(item))
    return found


@st.composite
def _mutated_profile(draw: st.DrawFn) -> Any:
    """A valid profile with one to four changes: a value replaced by garbage or an odd number, a key removed or
    added, a pair reversed, a list lengthened or shortened, the version or format changed."""
    document = draw(_valid_profile())
    for _ in range(draw(st.integers(1, 4))):
        target = draw(st.sampled_from(_containers(document)))
        kind = draw(st.sampled_from(["replace", "odd", "remove", "add", "reverse", "resize", "version", "format"]))
        if kind == "version":
            document["version"] = draw(
                st.sampled_from([0, -1, profile_version() + 1, 1.5, "1", True, None, [1], _HUGE_INT]) | _JSON
            )
        elif kind == "format":
            document["format"] = draw(st.sampled_from(["", "darksynth", PROFILE_FORMAT.upper(), None, 1]) | _JSON)
        elif isinstance(target, dict):
            keys = list(target)
            if kind == "add" or not keys:
                target[draw(st.text(max_size=10) | st.sampled_from([p.name for p in noise_parameters()]))] = draw(_JSON)
            elif kind == "remove":
                del target[draw(st.sampled_from(keys))]
            else:
                key = draw(st.sampled_from(keys))
                target[key] = draw(_ODD_NUMBERS if kind == "odd" else _JSON)
        elif target:
            if kind == "reverse":
                target.reverse()
            elif kind == "resize":
                if draw(st.booleans()):
                    target.pop()
                else:
                    target.append(draw(_SCALARS))
            else:
                target[draw(st.integers(0, len(target) - 1))] = draw(_ODD_NUMBERS if kind == "odd" else _JSON)
    return document


def _check_profile(document: Any) -> None:
    profile = _result_or_one_line_error(lambda: parse_profile(document, source="fuzz.json"), "fuzz.json")
    assert profile is None or isinstance(profile, Profile)


@_fuzz_settings(PROFILE_EXAMPLES)
@given(document=_mutated_profile() | _valid_profile() | _JSON)
def test_profile_parser_gives_a_profile_or_a_one_line_error(document: Any) -> None:
    _check_profile(document)


def _deeply_nested(depth: int) -> str:
    return "[" * depth + "]" * depth


@st.composite
def _profile_text(draw: st.DrawFn) -> bytes:
    valid = json.dumps(draw(_mutated_profile() | _valid_profile())).encode()
    return draw(
        _mutated(valid)
        | st.just(valid)
        | st.binary(max_size=200)
        | st.text(max_size=200).map(str.encode)
        | st.integers(1, 100_000).map(lambda depth: _deeply_nested(depth).encode())
        | st.integers(4300, 6000).map(lambda digits: b'{"version": ' + b"9" * digits + b"}")
        | st.sampled_from([b"", b"\xef\xbb\xbf{}", b'"\\ud800"', b"NaN", b"-Infinity", b"1e999", b"{" * 3])
    )


@_fuzz_settings(PROFILE_TEXT_EXAMPLES)
@given(text=_profile_text())
def test_profile_file_gives_a_profile_or_a_one_line_error(workdir: Path, text: bytes) -> None:
    path = workdir / "fuzz-profile.json"
    path.write_bytes(text)
    profile = _result_or_one_line_error(lambda: load_profile(path), str(path))
    assert profile is None or isinstance(profile, Profile)


# --- images ------------------------------------------------------------------------------------------------------

# Pillow modes each format writes, with the arrays that make them (16-bit colour is written by darksynth's own
# FFmpeg path, as Pillow cannot).
_IMAGE_KINDS: dict[str, tuple[str, ...]] = {
    "PNG": ("L", "LA", "RGB", "RGBA", "P", "1", "I;16", "RGB16", "RGBA16"),
    "JPEG": ("L", "RGB", "CMYK"),
    "TIFF": ("L", "LA", "RGB", "RGBA", "P", "1", "I;16", "I", "F", "CMYK", "RGB16", "RGBA16"),
    "BMP": ("L", "RGB", "RGBA", "P", "1"),
}
_SUFFIX = {"PNG": ".png", "JPEG": ".jpg", "TIFF": ".tif", "BMP": ".bmp"}
_TIFF_COMPRESSIONS = [None, "tiff_lzw", "tiff_adobe_deflate", "packbits"]
# Declared sides: zero, small, a few million pixels in all, and far beyond twice Pillow's decompression-bomb limit
# (refused). None makes a product in the band between the limit and twice it, which is read: libjpeg decodes a
# 600-byte JPEG that declares 13000 x 13000 pixels into a grey 500 MB image in 6 s (test_images.py covers the band).
_DECLARED_SIDES = [0, 1, 2, 255, 256, 4097, 65535, 70000, 2**31 - 1, 2**32 - 1]


def _pil_image(kind: str, width: int, height: int, seed: int) -> PIL.Image.Image:
    rng = np.random.default_rng(seed)
    if kind in ("I;16", "I"):
        return PIL.Image.fromarray(rng.integers(0, 65536, (height, width), dtype=np.uint16)).convert(kind)
    if kind == "F":
        return PIL.Image.fromarray(rng.random((height, width), dtype=np.float32))
    channels = {"L": 1, "LA": 2, "RGB": 3, "RGBA": 4, "P": 3, "1": 1, "CMYK": 4}[kind]
    array = rng.integers(0, 256, (height, width, channels), dtype=np.uint8)
    if kind == "CMYK":
        return PIL.Image.frombytes("CMYK", (width, height), array.tobytes())
    pil = PIL.Image.fromarray(array[:, :, 0] if channels == 1 else array)
    return pil.convert(kind) if kind in ("P", "1") else pil


@st.composite
def _image_bytes(draw: st.DrawFn) -> tuple[str, bytes]:
    fmt = draw(st.sampled_from(sorted(_IMAGE_KINDS)))
    kind = draw(st.sampled_from(_IMAGE_KINDS[fmt]))
    width, height, seed = draw(st.integers(1, 12)), draw(st.integers(1, 12)), draw(st.integers(0, 2**16))
    if kind.endswith("16") and kind != "I;16":
        # OpenCV writes 16-bit colour PNG and TIFF, which Pillow cannot.
        channels = 4 if kind.startswith("RGBA") else 3
        pixels = np.random.default_rng(seed).integers(0, 65536, (height, width, channels), dtype=np.uint16)
        written, encoded = cv2.imencode(_SUFFIX[fmt], pixels)
        assert written
        return _SUFFIX[fmt], encoded.tobytes()
    pil = _pil_image(kind, width, height, seed)
    options: dict[str, Any] = {}
    if fmt == "TIFF":
        options["compression"] = draw(st.sampled_from(_TIFF_COMPRESSIONS))
    if fmt == "JPEG":
        options["progressive"] = draw(st.booleans())
    if fmt in ("PNG", "TIFF", "JPEG") and draw(st.booleans()):
        exif = PIL.Image.Exif()
        # libtiff refuses to write an orientation outside 1..8; the other formats carry any value.
        exif[0x0112] = draw(st.integers(1, 8) if fmt == "TIFF" else st.integers(0, 9))
        options["exif"] = exif.tobytes()
    if fmt == "PNG" and kind in ("L", "RGB", "P") and draw(st.booleans()):
        options["transparency"] = 0 if kind != "RGB" else (0, 0, 0)
    buffer = io.BytesIO()
    pil.save(buffer, format=fmt, **options)
    return _SUFFIX[fmt], buffer.getvalue()


def _declare_size(data: bytes, width: int, height: int) -> bytes:
    """The file with another width and height in its header (PNG with the IHDR checksum fixed, JPEG, BMP)."""
    out = bytearray(data)
    if data.startswith(b"\x89PNG") and len(data) >= 33:
        out[16:24] = struct.pack(">II", width, height)
        out[29:33] = struct.pack(">I", zlib.crc32(bytes(out[12:29])))
    elif data.startswith(b"BM") and len(data) >= 26:
        out[18:26] = struct.pack("<ii", min(width, 2**31 - 1), min(height, 2**31 - 1))
    elif data.startswith(b"\xff\xd8"):
        for marker in (b"\xff\xc0", b"\xff\xc2"):
            at = data.find(marker)
            if at >= 0 and at + 9 <= len(data):
                out[at + 5 : at + 9] = struct.pack(">HH", height & 0xFFFF, width & 0xFFFF)
    return bytes(out)


@st.composite
def _broken_image(draw: st.DrawFn) -> tuple[str, bytes]:
    suffix, data = draw(_image_bytes())
    if draw(st.booleans()):
        data = _declare_size(data, draw(st.sampled_from(_DECLARED_SIDES)), draw(st.sampled_from(_DECLARED_SIDES)))
    if draw(st.integers(0, 3)):
        data = draw(_mutated(data))
    return suffix, data


def _check_image(workdir: Path, suffix: str, data: bytes) -> None:
    path = workdir / f"fuzz{suffix}"
    path.write_bytes(data)
    image = _result_or_one_line_error(lambda: read_image(path), str(path))
    assert image is None or isinstance(image, Image)


@_fuzz_settings(IMAGE_EXAMPLES)
@given(file=_broken_image())
def test_image_reader_gives_an_image_or_a_one_line_error(workdir: Path, file: tuple[str, bytes]) -> None:
    _check_image(workdir, *file)


_MAGIC = [b"", b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff", b"II*\x00", b"MM\x00*", b"BM"]


@_fuzz_settings(IMAGE_GARBAGE_EXAMPLES)
@given(
    suffix=st.sampled_from(sorted(IMAGE_SUFFIXES)),
    magic=st.sampled_from(_MAGIC),
    data=st.binary(max_size=2000),
)
def test_random_bytes_with_an_image_suffix_give_a_one_line_error(
    workdir: Path, suffix: str, magic: bytes, data: bytes
) -> None:
    _check_image(workdir, suffix, magic + data)


# --- videos ------------------------------------------------------------------------------------------------------

_CLIPS = {".mp4": "libx264", ".mkv": "ffv1", ".avi": "mpeg4", ".mov": "libx264rgb"}


@functools.cache
def _valid_clip(suffix: str) -> bytes:
    """A valid four-frame clip in the container of ``suffix``, made once per run."""
    rng = np.random.default_rng(7)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"clip{suffix}"
        with VideoWriter(
            path, width=16, height=12, fps=Fraction(25), encoding=VideoEncoding(codec=_CLIPS[suffix])
        ) as writer:
            for _ in range(4):
                writer.write(rng.integers(0, 256, (12, 16, 3), dtype=np.uint8))
        return path.read_bytes()


@st.composite
def _broken_clip(draw: st.DrawFn) -> tuple[str, bytes]:
    suffix = draw(st.sampled_from(sorted(_CLIPS)))
    broken = draw(_mutated(_valid_clip(suffix)))
    if draw(st.integers(0, 9)) == 0:
        suffix = draw(st.sampled_from(sorted(_CLIPS)))  # a file whose suffix names another container
    return suffix, broken


def _check_video(workdir: Path, suffix: str, data: bytes) -> None:
    path = workdir / f"fuzz{suffix}"
    path.write_bytes(data)
    _result_or_one_line_error(lambda: probe_video(path), str(path))
    frames = _result_or_one_line_error(lambda: list(iter_video_frames(path)), str(path))
    for frame in frames or ():
        assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8


@_fuzz_settings(VIDEO_EXAMPLES)
@given(file=_broken_clip())
def test_video_reader_gives_frames_or_a_one_line_error(workdir: Path, file: tuple[str, bytes]) -> None:
    _check_video(workdir, *file)


@_fuzz_settings(VIDEO_GARBAGE_EXAMPLES)
@given(suffix=st.sampled_from(sorted(_CLIPS)), keep=st.integers(0, 256), garbage=st.binary(max_size=4000))
def test_random_bytes_with_a_video_suffix_give_a_one_line_error(
    workdir: Path, suffix: str, keep: int, garbage: bytes
) -> None:
    # The first bytes of a real clip, then garbage: the container is recognised and its contents are not.
    _check_video(workdir, suffix, _valid_clip(suffix)[:keep] + garbage)
