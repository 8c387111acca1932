"""Reading and writing still images as numpy arrays, 8 or 16 bits per sample, with alpha carried through.

Pillow reads and writes everything except 16-bit PNG and TIFF files with colour or alpha: Pillow 13 opens those
as 8-bit modes and silently drops the low byte. Those files are decoded and encoded with FFmpeg's PNG and TIFF
codecs through PyAV, which darksynth already depends on for video.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal, cast

import av
import numpy as np
import PIL.Image
import PIL.TiffImagePlugin
from av.video.codeccontext import VideoCodecContext

from darksynth.errors import DarksynthError, InputFileError, error_reason
from darksynth.io.atomic import atomic_output

logger = logging.getLogger(__name__)

__all__ = ["IMAGE_SUFFIXES", "Image", "read_image", "write_image"]

IMAGE_SUFFIXES: Final[frozenset[str]] = frozenset({".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"})

_FORMAT_BY_SUFFIX: Final[dict[str, str]] = {
    ".png": "PNG",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".tif": "TIFF",
    ".tiff": "TIFF",
    ".bmp": "BMP",
}
_SIXTEEN_BIT_FORMATS: Final[frozenset[str]] = frozenset({"PNG", "TIFF"})
_ALPHA_FORMATS: Final[frozenset[str]] = frozenset({"PNG", "TIFF"})

# FFmpeg's packed 16-bit pixel formats by channel count (grey, grey+alpha, RGB, RGBA). PNG stores samples
# big-endian and FFmpeg's TIFF codec works little-endian; the array is converted to match, never reinterpreted.
_PACKED16_BY_CHANNELS: Final[dict[str, dict[int, str]]] = {
    "PNG": {1: "gray16be", 2: "ya16be", 3: "rgb48be", 4: "rgba64be"},
    "TIFF": {1: "gray16le", 2: "ya16le", 3: "rgb48le", 4: "rgba64le"},
}
_FFMPEG_CODEC: Final[dict[str, str]] = {"PNG": "png", "TIFF": "tiff"}

_EXIF_ORIENTATION_TAG: Final = 0x0112
_PNG_SIGNATURE: Final = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class Image:
    """A decoded image.

    Attributes:
        pixels: Array of shape (H, W, C), C = 1 (grey) or 3 (RGB), dtype uint8 or uint16, upright (EXIF
            orientation already applied).
        alpha: Opacity of shape (H, W) with the same dtype as ``pixels``, or None. It is carried through
            unchanged: noise and darkening apply to ``pixels`` only.
        bit_depth: 8 for uint8 samples, 16 for uint16.
        source_mode: Pillow's mode of the file it was read from (for example ``"RGB"``, ``"P"``, ``"I;16"``),
            recorded in manifests; ``""`` for an image that was not read from a file. A 16-bit colour PNG or
            TIFF still reports Pillow's 8-bit mode name (``"RGB"``, ``"RGBA"``): ``bit_depth`` says 16.

    Raises:
        ValueError: If the arrays do not have the shapes and dtypes above.
    """

    pixels: np.ndarray
    alpha: np.ndarray | None = None
    bit_depth: int = 8
    source_mode: str = ""

    def __post_init__(self) -> None:
        expected = {8: np.uint8, 16: np.uint16}.get(self.bit_depth)
        if expected is None:
            raise ValueError(f"bit_depth must be 8 or 16, got {self.bit_depth}")
        if self.pixels.ndim != 3 or self.pixels.shape[2] not in (1, 3):
            raise ValueError(f"pixels must have shape (H, W, 1) or (H, W, 3), got {self.pixels.shape}")
        if self.pixels.dtype != expected:
            raise ValueError(
                f"pixels of a {self.bit_depth}-bit image must be {expected.__name__}, got {self.pixels.dtype}"
            )
        if self.alpha is not None:
            if self.alpha.shape != self.pixels.shape[:2]:
                raise ValueError(f"alpha must have shape {self.pixels.shape[:2]}, got {self.alpha.shape}")
            if self.alpha.dtype != expected:
                raise ValueError(f"alpha must have the dtype of pixels ({expected.__name__}), got {self.alpha.dtype}")


def read_image(path: str | Path) -> Image:
    """Read an image file as an upright array of 8- or 16-bit samples.

    Grey stays one channel and RGB three; an alpha channel (RGBA, LA, transparent palette or colour-key
    transparency) is split off into ``alpha``. Palette images become RGB, 1-bit images grey uint8, CMYK and YCbCr
    RGB. 16-bit grey, grey+alpha, RGB and RGBA PNG and TIFF files are read exactly as uint16. 32-bit integer
    images are read as uint16 when all values fit in 0..65535; 32-bit float images are rejected. Only the first
    frame of a multi-page file is read.

    The EXIF orientation tag, if present, is applied (as :func:`PIL.ImageOps.exif_transpose` would) so that the
    pixels are upright; outputs are written without EXIF, so they display the same way in every viewer.

    Pillow's decompression-bomb warning (images over ``PIL.Image.MAX_IMAGE_PIXELS``) is silenced, since the user
    chose the file; images more than twice that size are rejected.

    Args:
        path: The image file.

    Returns:
        The decoded image.

    Raises:
        InputFileError: If the file is missing, not an image, corrupt, truncated or of an unsupported kind.
    """
    # A str path would reach Pillow's opener as it is and fail there as "corrupt or truncated image".
    path = Path(path)
    try:
        # Pillow warns about damage it reads past (a truncated tag, corrupt EXIF): recorded here, so that the user
        # sees one line naming the file instead of Python's two-line warning naming Pillow's source.
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            warnings.simplefilter("ignore", PIL.Image.DecompressionBombWarning)
            with PIL.Image.open(path) as pil:
                # load() decodes everything now, so a truncated file fails here and not in the middle of a run.
                pil.load()
                source_mode = pil.mode
                orientation = _exif_orientation(pil)
                if _needs_ffmpeg(path, pil):
                    pixels, alpha = _read_16bit_with_ffmpeg(path, pil.format or "")
                else:
                    pixels, alpha = _pil_to_arrays(path, pil)
    except InputFileError:
        raise
    except Exception as err:  # Pillow's decoders raise OSError, SyntaxError, ValueError, EOFError, zlib.error...
        raise _reading_error(path, err) from None

    for message in dict.fromkeys(" ".join(str(w.message).split()) for w in caught):
        logger.warning("%s: %s", path, message)
    pixels = _apply_orientation(pixels, orientation)
    if alpha is not None:
        alpha = _apply_orientation(alpha, orientation)
    bit_depth = 16 if pixels.dtype == np.uint16 else 8
    return Image(pixels=pixels, alpha=alpha, bit_depth=bit_depth, source_mode=source_mode)


def _reading_error(path: Path, error: Exception) -> InputFileError:
    """The one-line error of an image file that could not be read, by what went wrong."""
    if isinstance(error, FileNotFoundError):
        return InputFileError(path, "no such file")
    if isinstance(error, IsADirectoryError):
        return InputFileError(path, "is a folder, not an image file")
    if isinstance(error, PermissionError):
        return InputFileError(path, "permission denied")
    if isinstance(error, PIL.UnidentifiedImageError):
        return InputFileError(path, "not an image file, or an image format that cannot be read")
    if isinstance(error, PIL.Image.DecompressionBombError):
        return InputFileError(path, f"image too large to read safely ({error})")
    if isinstance(error, MemoryError):
        return InputFileError(path, "not enough memory to decode this image")
    if isinstance(error, av.FFmpegError):  # 16-bit PNG and TIFF are decoded by FFmpeg
        return InputFileError(path, f"corrupt or truncated image ({error_reason(error)})")
    return InputFileError(path, f"corrupt or truncated image ({type(error).__name__}: {error})")


def write_image(path: Path, image: Image, *, jpeg_quality: int = 95) -> None:
    """Write an image atomically, in the format named by the path's suffix.

    16-bit images are written as 16-bit PNG or TIFF (16-bit grey with alpha as PNG only). Alpha is written to
    PNG and TIFF; JPEG and BMP cannot carry it (Pillow's BMP reader ignores a fourth channel), so there it is
    dropped. JPEG is written without chroma subsampling (4:4:4), because subsampling would blur the colour noise
    this tool adds. No EXIF is written.

    Args:
        path: Output path; parent folders are created; the suffix (case-insensitive) chooses the format.
        image: The image to write.
        jpeg_quality: JPEG quality, 1 to 100 (ignored for other formats).

    Raises:
        DarksynthError: If the suffix is not an image format, the format cannot store 16-bit samples, or the
            file cannot be written.
        ValueError: If ``jpeg_quality`` is outside 1..100.
    """
    if not 1 <= jpeg_quality <= 100:
        raise ValueError(f"jpeg_quality must be in 1..100, got {jpeg_quality}")
    fmt = _FORMAT_BY_SUFFIX.get(path.suffix.lower())
    if fmt is None:
        known = " ".join(sorted(IMAGE_SUFFIXES))
        raise DarksynthError(f"{path}: cannot write an image with suffix {path.suffix!r} (use one of {known})")
    if image.bit_depth == 16 and fmt not in _SIXTEEN_BIT_FORMATS:
        raise DarksynthError(f"{path}: {fmt} cannot store 16-bit images; write PNG or TIFF instead")

    alpha = image.alpha if fmt in _ALPHA_FORMATS else None
    if image.bit_depth == 16 and fmt == "TIFF" and alpha is not None and image.pixels.shape[2] == 1:
        # FFmpeg writes it, but neither Pillow nor libtiff-based readers such as OpenCV read it back correctly.
        raise DarksynthError(f"{path}: 16-bit grey with alpha cannot be written as TIFF; write PNG instead")
    channels = image.pixels if alpha is None else np.concatenate([image.pixels, alpha[:, :, None]], axis=2)
    try:
        with atomic_output(path) as tmp:
            if image.bit_depth == 16:
                tmp.write_bytes(_encode_16bit_with_ffmpeg(channels, fmt))
            else:
                _save_8bit_with_pil(tmp, channels, fmt, jpeg_quality)
    except (OSError, ValueError, av.FFmpegError) as err:
        raise DarksynthError(f"{path}: cannot write {fmt} image ({error_reason(err)})") from err


def _pil_to_arrays(path: Path, pil: PIL.Image.Image) -> tuple[np.ndarray, np.ndarray | None]:
    mode = pil.mode
    if mode == "P":
        pil = pil.convert("RGBA" if _has_transparency(pil) else "RGB")
    elif mode in ("L", "RGB") and "transparency" in pil.info:
        pil = pil.convert(mode + "A" if mode == "L" else "RGBA")
    elif mode in ("1", "RGBX", "CMYK", "YCbCr", "LAB", "HSV"):
        pil = pil.convert("L" if mode == "1" else "RGB")
    elif mode in ("PA", "RGBa"):
        pil = pil.convert("RGBA")
    elif mode == "La":
        pil = pil.convert("LA")

    mode = pil.mode
    if mode in ("L", "RGB", "LA", "RGBA"):
        array = np.asarray(pil, dtype=np.uint8)
        array = array[:, :, None] if array.ndim == 2 else array
        return _split_alpha(array, has_alpha=mode.endswith("A"))
    if mode.startswith("I"):
        return _integer_to_uint16(path, np.asarray(pil))[:, :, None], None
    if mode == "F":
        raise InputFileError(path, "32-bit floating-point images are not supported (convert to 8 or 16 bits)")
    raise InputFileError(path, f"unsupported image mode {mode}")


def _has_transparency(pil: PIL.Image.Image) -> bool:
    return "transparency" in pil.info or (pil.palette is not None and pil.palette.mode == "RGBA")


def _integer_to_uint16(path: Path, array: np.ndarray) -> np.ndarray:
    if array.dtype.kind == "u" and array.dtype.itemsize == 2:
        return array.astype(np.uint16)  # byte-swaps big-endian ("I;16B") data to native order
    if array.size and (array.min() < 0 or array.max() > np.iinfo(np.uint16).max):
        raise InputFileError(path, "integer image with values outside 0..65535 is not supported")
    return array.astype(np.uint16)


def _split_alpha(array: np.ndarray, *, has_alpha: bool) -> tuple[np.ndarray, np.ndarray | None]:
    if not has_alpha:
        return np.ascontiguousarray(array), None
    return np.ascontiguousarray(array[:, :, :-1]), np.ascontiguousarray(array[:, :, -1])


def _exif_orientation(pil: PIL.Image.Image) -> int:
    try:
        value = pil.getexif().get(_EXIF_ORIENTATION_TAG, 1)
    except Exception:  # a damaged EXIF block should not make the pixels unreadable
        return 1
    return value if isinstance(value, int) and 1 <= value <= 8 else 1


def _apply_orientation(array: np.ndarray, orientation: int) -> np.ndarray:
    """Turn stored pixels upright for an EXIF orientation value (1..8); works on (H, W) and (H, W, C) arrays."""
    match orientation:
        case 2:
            out = array[:, ::-1]
        case 3:
            out = array[::-1, ::-1]
        case 4:
            out = array[::-1]
        case 5:
            out = array.swapaxes(0, 1)
        case 6:
            out = np.rot90(array, k=-1)
        case 7:
            out = array[::-1, ::-1].swapaxes(0, 1)
        case 8:
            out = np.rot90(array, k=1)
        case _:
            return array
    return np.ascontiguousarray(out)


def _needs_ffmpeg(path: Path, pil: PIL.Image.Image) -> bool:
    """Whether this is a 16-bit PNG or TIFF that Pillow has read as an 8-bit mode (colour or alpha)."""
    if pil.mode.startswith("I") or pil.mode == "F":
        return False
    if pil.format == "PNG":
        with path.open("rb") as file:
            header = file.read(25)
        # The IHDR chunk always comes first; its bit-depth byte sits at a fixed offset after the signature.
        return header.startswith(_PNG_SIGNATURE) and len(header) == 25 and header[24] == 16
    if isinstance(pil, PIL.TiffImagePlugin.TiffImageFile):
        bits = pil.tag_v2.get(PIL.TiffImagePlugin.BITSPERSAMPLE, 8)
        return 16 in (bits if isinstance(bits, tuple) else (bits,))
    return False


def _read_16bit_with_ffmpeg(path: Path, fmt: str) -> tuple[np.ndarray, np.ndarray | None]:
    codec = _video_codec(_FFMPEG_CODEC[fmt], "r")
    # PNG and TIFF files are a single packet each: the codec decodes the whole file without a demuxer.
    frames = codec.decode(av.Packet(path.read_bytes())) + codec.decode(None)
    if not frames:
        raise InputFileError(path, f"corrupt 16-bit {fmt} image (no picture decoded)")
    frame = frames[0]
    channels = len(frame.format.components)
    packed_formats = _PACKED16_BY_CHANNELS[fmt]
    if channels not in packed_formats:
        raise InputFileError(path, f"unsupported 16-bit {fmt} pixel format {frame.format.name}")
    if frame.format.name not in packed_formats.values():
        frame = frame.reformat(format=packed_formats[channels])  # for example planar TIFF; a lossless repack
    array = _frame_to_array(frame, channels)
    return _split_alpha(array, has_alpha=channels in (2, 4))


def _video_codec(name: str, mode: Literal["r", "w"]) -> VideoCodecContext:
    return cast(VideoCodecContext, av.CodecContext.create(name, mode))


def _frame_to_array(frame: av.VideoFrame, channels: int) -> np.ndarray:
    plane = frame.planes[0]
    dtype = np.dtype(">u2" if frame.format.name.endswith("be") else "<u2")
    rows = np.frombuffer(memoryview(plane), dtype=np.uint8).reshape(frame.height, plane.line_size)
    # Each row may be padded past width * channels samples for alignment.
    samples = rows[:, : frame.width * channels * 2].copy().view(dtype)
    return samples.reshape(frame.height, frame.width, channels).astype(np.uint16)


def _encode_16bit_with_ffmpeg(channels: np.ndarray, fmt: str) -> bytes:
    height, width, count = channels.shape
    pix_fmt = _PACKED16_BY_CHANNELS[fmt][count]
    frame = av.VideoFrame(width, height, pix_fmt)
    plane = frame.planes[0]
    dtype = np.dtype(">u2" if pix_fmt.endswith("be") else "<u2")
    rows = np.zeros((height, plane.line_size), dtype=np.uint8)
    # Any layout is accepted: viewing the samples as bytes needs a C-contiguous array.
    samples = np.ascontiguousarray(channels, dtype=dtype)
    rows[:, : width * count * 2] = samples.view(np.uint8).reshape(height, width * count * 2)
    plane.update(rows.tobytes())
    codec = _video_codec(_FFMPEG_CODEC[fmt], "w")
    codec.width = width
    codec.height = height
    codec.pix_fmt = pix_fmt
    packets = codec.encode(frame) + codec.encode(None)
    return b"".join(bytes(packet) for packet in packets)


def _save_8bit_with_pil(tmp: Path, channels: np.ndarray, fmt: str, jpeg_quality: int) -> None:
    # fromarray picks L, LA, RGB or RGBA from the channel count.
    array = channels[:, :, 0] if channels.shape[2] == 1 else channels
    pil = PIL.Image.fromarray(np.ascontiguousarray(array))
    if fmt == "JPEG":
        pil.save(tmp, format=fmt, quality=jpeg_quality, subsampling="4:4:4")
    else:
        pil.save(tmp, format=fmt)
