"""How a video is encoded: the codec, its quality (CRF) and the pixel format, chosen once (``--codec``, ``--crf``,
``--pix-fmt``) and carried as one :class:`VideoEncoding` from the command line to the writer and the manifest; the
defaults and rules of each codec.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Final

import av
from av.video.reformatter import ColorRange, Colorspace
from av.video.stream import VideoStream

from darksynth.errors import DarksynthError

__all__ = ["DEFAULT_CODEC", "DEFAULT_CRF", "DEFAULT_ENCODING", "VideoEncoding", "configure_stream"]

logger = logging.getLogger(__name__)

# H.264 in 4:2:0 (yuv420p, the High profile) plays everywhere: browsers, QuickTime, phones, hardware decoders. It is
# also what cameras record, so the colour noise of the output is subsampled as a real dark video's is.
# ``pix_fmt="yuv444p"`` keeps per-pixel chroma noise at the price of High 4:4:4, which browsers and QuickTime do not
# play (docs/video-output.md measures the difference).
DEFAULT_CODEC: Final = "libx264"

# x264's CRF 23 default smooths away exactly the fine, low-amplitude noise this tool synthesises. Measured on a
# dark 175x143 clip with i.i.d. noise of std 4 (in 8-bit units): CRF 14 with tune=grain keeps the noise std
# (4.0 -> 4.2, mean abs error 2.2), CRF 14 without tune=grain flattens it to 3.0, CRF 18 with it to 3.4, and
# CRF 12 buys little (error 1.75) for 30% more bytes. Use libx264rgb with crf=0, or ffv1, for bit-exact output.
# With the faster preset below, CRF 12 is the one that keeps that fidelity: on 60 1080p frames with noise of std 6,
# preset medium CRF 14 gave mean abs error 2.27, noise std 6.09, while preset faster gave 2.72 and 6.02 at CRF 14
# and 2.16 and 6.05 at CRF 12 (5% more bytes than medium CRF 14).
DEFAULT_CRF: Final = 12

# x264's medium preset encoded noisy 1080p 4:4:4 at 1.4 frames/s on the 2-core machine and its default 40-frame
# rate-control lookahead held 570 MiB of frames; "faster" with a 10-frame lookahead ran at 6-7 frames/s and held
# 225 MiB, which keeps a streamed 1080p run under 1 GiB in all (docs/performance.md).
X264_OPTIONS: Final[dict[str, str]] = {"tune": "grain", "preset": "faster", "rc-lookahead": "10"}

# Codecs whose quality is set by a constant rate factor, with its largest value; the x264 family also gets
# tune=grain, which lowers the dead zones and psycho-visual smoothing that would otherwise flatten noise in dark,
# flat regions.
MAX_CRF: Final[dict[str, int]] = {"libx264": 51, "libx264rgb": 51, "libx265": 51, "libvpx-vp9": 63, "libaom-av1": 63}
X264_CODECS: Final[frozenset[str]] = frozenset({"libx264", "libx264rgb"})

# H.264 and H.265 carry the colour matrix in the bitstream, so they are converted with BT.709 (the HD standard) and
# say so. Other codecs (MPEG-4 Part 2 in AVI, for example) often reach the reader untagged, and an untagged stream
# is decoded as BT.601 by FFmpeg and most players, so they are converted with BT.601 to round-trip.
BT709_CODECS: Final[frozenset[str]] = frozenset({"libx264", "libx265"})

# Default pixel format per codec: the playable 4:2:0 for H.264, H.265, VP9 (profile 0; 4:4:4 is profile 1, which
# Safari does not decode) and AV1 (main profile), RGB where the codec stores RGB losslessly.
_PIX_FMT: Final[dict[str, str]] = {
    "libx264": "yuv420p",
    "libx264rgb": "rgb24",
    "ffv1": "bgr0",
    "libx265": "yuv420p",
    "mpeg4": "yuv420p",
    "libvpx-vp9": "yuv420p",
    "libaom-av1": "yuv420p",
    "libsvtav1": "yuv420p",
}

# x264 and x265 code subsampled chroma in whole samples and refuse a 4:2:0 picture of odd width or height (FFmpeg's
# mpeg4 encoder, for one, takes it). Padding or cropping would change the frame size, and so every annotation of a
# converted dataset; an odd-sized video is written in 4:4:4 instead, with a notice.
_WHOLE_CHROMA_CODECS: Final[frozenset[str]] = frozenset({"libx264", "libx265"})
_ODD_SIZE_PIX_FMT: Final = "yuv444p"

# Fixed quantiser for MPEG-4 Part 2, whose default 200 kb/s bit rate would be far too low (2 is near the best).
MPEG4_QSCALE: Final = 2


@dataclass(frozen=True)
class VideoEncoding:
    """How a video is encoded; None (or an empty name) leaves a choice to the writer's default for the codec.

    Attributes:
        codec: FFmpeg encoder name: ``libx264`` (:data:`DEFAULT_CODEC`), ``libx264rgb`` (RGB; crf=0 is lossless),
            ``ffv1`` (lossless, .mkv or .avi), ``libx265``, ``mpeg4`` or any other the container accepts.
        crf: Constant rate factor for the codecs that have one (lower is better; 0 lossless for x264); None gives
            :data:`DEFAULT_CRF` for the x264 family and the encoder's own default otherwise.
        pix_fmt: Pixel format the encoder codes, one it supports (``yuv444p`` keeps full-resolution chroma); None
            gives yuv420p for libx264 and libx265 (yuv444p, with a logged notice, when the width or height is odd,
            which x264 and x265 cannot code in 4:2:0), RGB for libx264rgb and ffv1.
    """

    codec: str | None = None
    crf: int | None = None
    pix_fmt: str | None = None

    def to_json(self) -> dict[str, str | int | None]:
        """The choices as a manifest records them (None where the default was left)."""
        return {"codec": self.codec, "crf": self.crf, "pix_fmt": self.pix_fmt}

    def resolved(self, path: Path, width: int, height: int) -> VideoEncoding:
        """Every choice made for a ``width`` x ``height`` video at ``path``: the encoder's own name for the codec
        ("h264" is libx264), the CRF and pixel format by the defaults above.

        Raises:
            DarksynthError: an unknown codec or one that is not for video, a CRF the codec has not or out of its
                range, a pixel format the codec cannot code at this size; the message names ``path``.
        """
        name = self.codec or DEFAULT_CODEC
        try:
            encoder = av.Codec(name, "w")
        except av.codec.codec.UnknownCodecError:
            raise DarksynthError(f"{path}: unknown video codec {name!r}") from None
        if encoder.type != "video":
            raise DarksynthError(f"{path}: {name} is not a video codec")
        codec = encoder.name
        if self.crf is not None:
            max_crf = MAX_CRF.get(codec)
            if max_crf is None:
                raise DarksynthError(f"{path}: codec {codec} has no CRF setting (CRF works with {_sorted(MAX_CRF)})")
            if not 0 <= self.crf <= max_crf:
                raise DarksynthError(f"{path}: CRF for {codec} must be in 0..{max_crf}, got {self.crf}")
        crf = DEFAULT_CRF if self.crf is None and codec in X264_CODECS else self.crf
        pix_fmt = _choose_pix_fmt(path, encoder, self.pix_fmt or None, width, height)
        return replace(self, codec=codec, crf=crf, pix_fmt=pix_fmt)

    def colorspace(self) -> Colorspace:
        """The colour matrix a resolved encoding converts YUV with (see :data:`BT709_CODECS`)."""
        return Colorspace.ITU709 if self.codec in BT709_CODECS else Colorspace.ITU601


DEFAULT_ENCODING: Final = VideoEncoding()
"""Every choice left to the codec's defaults (:data:`DEFAULT_CODEC` and its own)."""


def configure_stream(stream: VideoStream, encoding: VideoEncoding) -> None:
    """Set a new stream's pixel format, colour tags and encoder options from a resolved encoding."""
    pix_fmt = encoding.pix_fmt
    stream.pix_fmt = pix_fmt
    if pix_fmt is not None and not av.VideoFormat(pix_fmt).is_rgb:
        stream.codec_context.colorspace = encoding.colorspace()
        stream.codec_context.color_range = ColorRange.MPEG
    options: dict[str, object] = {}
    if encoding.crf is not None:
        options["crf"] = str(encoding.crf)
    if encoding.codec in X264_CODECS:
        options.update(X264_OPTIONS)
    if encoding.codec == "mpeg4":
        stream.codec_context.qscale = True
        stream.codec_context.global_quality = MPEG4_QSCALE
    stream.options = options


def _choose_pix_fmt(path: Path, encoder: av.Codec, pix_fmt: str | None, width: int, height: int) -> str:
    supported = {fmt.name for fmt in encoder.video_formats or ()}
    if pix_fmt is not None:
        if supported and pix_fmt not in supported:
            raise DarksynthError(
                f"{path}: {encoder.name} cannot encode pixel format {pix_fmt!r} (choices: {_sorted(supported)})"
            )
        try:
            av.VideoFormat(pix_fmt)
        except ValueError:
            raise DarksynthError(f"{path}: unknown pixel format {pix_fmt!r}") from None
        if pix_fmt.startswith("yuvj"):
            # The writer tags and converts to limited range; FFmpeg's full-range "J" formats would contradict it.
            raise DarksynthError(
                f"{path}: {pix_fmt} is FFmpeg's deprecated full-range format; use {pix_fmt.replace('yuvj', 'yuv', 1)}"
            )
        if encoder.name in _WHOLE_CHROMA_CODECS and not _fits_chroma(pix_fmt, width, height):
            raise DarksynthError(
                f"{path}: {encoder.name} cannot code {width}x{height} in {pix_fmt}, whose chroma needs an even "
                f"width and height; use {_ODD_SIZE_PIX_FMT}"
            )
        return pix_fmt
    default = _PIX_FMT.get(encoder.name)
    if default is None:
        return "yuv444p" if "yuv444p" in supported or not supported else sorted(supported)[0]
    if encoder.name in _WHOLE_CHROMA_CODECS and not _fits_chroma(default, width, height):
        logger.warning(
            "%s: %dx%d has an odd side, which %s cannot code in %s; written as %s",
            path, width, height, encoder.name, default, _ODD_SIZE_PIX_FMT,
        )  # fmt: skip
        return _ODD_SIZE_PIX_FMT
    return default


def _fits_chroma(pix_fmt: str, width: int, height: int) -> bool:
    """Whether a picture of this size has whole chroma samples in this format (any size does without subsampling)."""
    fmt = av.VideoFormat(pix_fmt)
    probe = 1024  # chroma_width(n) is n >> log2 of the horizontal subsampling
    return width % (probe // fmt.chroma_width(probe)) == 0 and height % (probe // fmt.chroma_height(probe)) == 0


def _sorted(names: Iterable[str]) -> str:
    return " ".join(sorted(names))
