from __future__ import annotations

import io
import logging
from pathlib import Path

import cv2
import numpy as np
import PIL.Image
import PIL.ImageOps
import PIL.JpegImagePlugin
import pytest

from darksynth.errors import DarksynthError, InputFileError
from darksynth.io.images import IMAGE_SUFFIXES, Image, read_image, write_image

RNG = np.random.default_rng(1234)


def _random(shape: tuple[int, ...], dtype: type[np.integer] = np.uint8) -> np.ndarray:
    return RNG.integers(0, np.iinfo(dtype).max, size=shape, dtype=dtype, endpoint=True)


def _save_pil(path: Path, array: np.ndarray, **kwargs: object) -> Path:
    PIL.Image.fromarray(array).save(path, **kwargs)
    return path


def _write_cv2(path: Path, rgb: np.ndarray) -> Path:
    """Write with OpenCV, an independent 16-bit colour encoder, so the reader is not only checked against itself."""
    order = [2, 1, 0, 3][: rgb.shape[2]]
    assert cv2.imwrite(str(path), rgb[:, :, order])
    return path


def _read_cv2(path: Path) -> np.ndarray:
    array = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert array is not None
    return array[:, :, [2, 1, 0, 3][: array.shape[2]]] if array.ndim == 3 else array


def test_image_suffixes() -> None:
    assert frozenset({".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"}) == IMAGE_SUFFIXES


# --- 8-bit reading and round trips -------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".png", ".tif", ".bmp", ".PNG"])
def test_rgb_round_trip_is_exact(tmp_path: Path, suffix: str) -> None:
    pixels = _random((7, 5, 3))
    path = tmp_path / f"rgb{suffix}"
    write_image(path, Image(pixels=pixels, bit_depth=8))
    image = read_image(path)
    assert image.bit_depth == 8
    assert image.source_mode == "RGB"
    assert image.alpha is None
    np.testing.assert_array_equal(image.pixels, pixels)


@pytest.mark.parametrize("suffix", [".png", ".tif", ".bmp"])
def test_grey_stays_one_channel(tmp_path: Path, suffix: str) -> None:
    grey = _random((6, 9))
    image = read_image(_save_pil(tmp_path / f"grey{suffix}", grey))
    assert image.pixels.shape == (6, 9, 1)
    assert image.pixels.dtype == np.uint8
    assert image.source_mode == "L"
    np.testing.assert_array_equal(image.pixels[:, :, 0], grey)
    write_image(tmp_path / f"out{suffix}", image)
    np.testing.assert_array_equal(read_image(tmp_path / f"out{suffix}").pixels, image.pixels)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_rgba_round_trip_keeps_alpha(tmp_path: Path, suffix: str) -> None:
    rgba = _random((5, 4, 4))
    image = read_image(_save_pil(tmp_path / f"in{suffix}", rgba))
    assert image.source_mode == "RGBA"
    np.testing.assert_array_equal(image.pixels, rgba[:, :, :3])
    assert image.alpha is not None
    np.testing.assert_array_equal(image.alpha, rgba[:, :, 3])
    write_image(tmp_path / f"out{suffix}", image)
    back = read_image(tmp_path / f"out{suffix}")
    np.testing.assert_array_equal(back.pixels, rgba[:, :, :3])
    assert back.alpha is not None
    np.testing.assert_array_equal(back.alpha, rgba[:, :, 3])


def test_la_is_grey_plus_alpha(tmp_path: Path) -> None:
    la = _random((4, 6, 2))
    image = read_image(_save_pil(tmp_path / "la.png", la))
    assert image.source_mode == "LA"
    assert image.pixels.shape == (4, 6, 1)
    np.testing.assert_array_equal(image.pixels[:, :, 0], la[:, :, 0])
    assert image.alpha is not None
    np.testing.assert_array_equal(image.alpha, la[:, :, 1])
    write_image(tmp_path / "out.png", image)
    with PIL.Image.open(tmp_path / "out.png") as pil:
        assert pil.mode == "LA"
    back = read_image(tmp_path / "out.png")
    np.testing.assert_array_equal(back.pixels, image.pixels)
    np.testing.assert_array_equal(back.alpha, image.alpha)  # type: ignore[arg-type]


def test_palette_png_becomes_rgb(tmp_path: Path) -> None:
    rgb = _random((8, 8, 3))
    pil = PIL.Image.fromarray(rgb).quantize(colors=16)
    pil.save(tmp_path / "p.png")
    image = read_image(tmp_path / "p.png")
    assert image.source_mode == "P"
    assert image.alpha is None
    assert image.pixels.shape == (8, 8, 3)
    np.testing.assert_array_equal(image.pixels, np.asarray(pil.convert("RGB")))


def test_palette_png_with_transparency_becomes_rgba(tmp_path: Path) -> None:
    indices = np.arange(12, dtype=np.uint8).reshape(3, 4)
    pil = PIL.Image.fromarray(indices, mode="L").convert("P")
    pil.putpalette([v for i in range(256) for v in (i, 255 - i, i // 2)])
    pil.save(tmp_path / "pt.png", transparency=5)
    image = read_image(tmp_path / "pt.png")
    assert image.pixels.shape == (3, 4, 3)
    assert image.alpha is not None
    np.testing.assert_array_equal(image.alpha, np.where(indices == 5, 0, 255))
    np.testing.assert_array_equal(image.pixels[0, 1], [1, 254, 0])


def test_grey_colour_key_transparency_becomes_alpha(tmp_path: Path) -> None:
    grey = np.array([[0, 7], [7, 200]], dtype=np.uint8)
    _save_pil(tmp_path / "key.png", grey, transparency=7)
    image = read_image(tmp_path / "key.png")
    assert image.alpha is not None
    np.testing.assert_array_equal(image.alpha, [[255, 0], [0, 255]])
    np.testing.assert_array_equal(image.pixels[:, :, 0], grey)


def test_one_bit_becomes_grey_uint8(tmp_path: Path) -> None:
    bits = RNG.integers(0, 2, size=(5, 9)).astype(bool)
    PIL.Image.fromarray(bits).save(tmp_path / "bits.png")
    image = read_image(tmp_path / "bits.png")
    assert image.source_mode == "1"
    assert image.pixels.dtype == np.uint8
    np.testing.assert_array_equal(image.pixels[:, :, 0], np.where(bits, 255, 0))


def test_cmyk_jpeg_becomes_rgb(tmp_path: Path) -> None:
    PIL.Image.new("CMYK", (4, 3), (0, 255, 255, 0)).save(tmp_path / "cmyk.jpg")
    image = read_image(tmp_path / "cmyk.jpg")
    assert image.source_mode == "CMYK"
    assert image.pixels.shape == (3, 4, 3)
    assert image.pixels[..., 0].min() > 240 and image.pixels[..., 1:].max() < 15


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".tif", ".bmp"])
def test_one_by_one_image(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"dot{suffix}"
    write_image(path, Image(pixels=np.array([[[10, 20, 30]]], dtype=np.uint8)))
    image = read_image(path)
    assert image.pixels.shape == (1, 1, 3)
    if suffix != ".jpg":
        np.testing.assert_array_equal(image.pixels, [[[10, 20, 30]]])


@pytest.mark.parametrize("orientation", range(1, 9))
def test_exif_orientation_is_applied_like_pillow(tmp_path: Path, orientation: int) -> None:
    rgba = _random((3, 5, 4))
    exif = PIL.Image.Exif()
    exif[0x0112] = orientation
    path = _save_pil(tmp_path / "rotated.png", rgba, exif=exif)
    with PIL.Image.open(path) as pil:
        expected = np.asarray(PIL.ImageOps.exif_transpose(pil))
    image = read_image(path)
    np.testing.assert_array_equal(image.pixels, expected[:, :, :3])
    np.testing.assert_array_equal(image.alpha, expected[:, :, 3])  # type: ignore[arg-type]
    if orientation >= 5:
        assert image.pixels.shape[:2] == (5, 3)


def test_written_files_carry_no_exif(tmp_path: Path) -> None:
    exif = PIL.Image.Exif()
    exif[0x0112] = 6
    image = read_image(_save_pil(tmp_path / "in.jpg", _random((4, 6, 3)), exif=exif))
    write_image(tmp_path / "out.jpg", image)
    with PIL.Image.open(tmp_path / "out.jpg") as pil:
        assert pil.getexif().get(0x0112) is None
    assert read_image(tmp_path / "out.jpg").pixels.shape == (6, 4, 3)


# --- 16-bit ------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_16bit_grey_round_trip_is_exact(tmp_path: Path, suffix: str) -> None:
    grey = _random((5, 7), np.uint16)
    image = read_image(_save_pil(tmp_path / f"g16{suffix}", grey))
    assert image.bit_depth == 16
    assert image.pixels.dtype == np.uint16
    assert image.source_mode.startswith("I;16")
    np.testing.assert_array_equal(image.pixels[:, :, 0], grey)
    write_image(tmp_path / f"out{suffix}", image)
    np.testing.assert_array_equal(_read_cv2(tmp_path / f"out{suffix}"), grey)
    np.testing.assert_array_equal(read_image(tmp_path / f"out{suffix}").pixels, image.pixels)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
@pytest.mark.parametrize("channels", [3, 4])
def test_16bit_colour_is_read_exactly(tmp_path: Path, suffix: str, channels: int) -> None:
    # Pillow alone would return these as 8-bit RGB(A), dropping the low byte of every sample.
    array = _random((6, 5, channels), np.uint16)
    image = read_image(_write_cv2(tmp_path / f"c16{suffix}", array))
    assert image.bit_depth == 16
    np.testing.assert_array_equal(image.pixels, array[:, :, :3])
    if channels == 4:
        assert image.alpha is not None
        np.testing.assert_array_equal(image.alpha, array[:, :, 3])
    else:
        assert image.alpha is None


@pytest.mark.parametrize(
    ("suffix", "channels", "with_alpha"),
    # 16-bit grey with alpha as TIFF is refused, see test_16bit_grey_alpha_tiff_is_refused.
    [(".png", c, a) for c in (1, 3) for a in (False, True)]
    + [(".tif", 1, False), (".tif", 3, False), (".tif", 3, True)],
)
def test_16bit_write_read_round_trip_is_exact(tmp_path: Path, suffix: str, channels: int, with_alpha: bool) -> None:
    pixels = _random((9, 4, channels), np.uint16)
    alpha = _random((9, 4), np.uint16) if with_alpha else None
    path = tmp_path / f"out{suffix}"
    write_image(path, Image(pixels=pixels, alpha=alpha, bit_depth=16))
    back = read_image(path)
    assert back.bit_depth == 16
    np.testing.assert_array_equal(back.pixels, pixels)
    if alpha is None:
        assert back.alpha is None
    else:
        assert back.alpha is not None
        np.testing.assert_array_equal(back.alpha, alpha)
    if channels == 3:  # checked against an independent decoder too
        reference = _read_cv2(path)
        np.testing.assert_array_equal(reference[:, :, :3], pixels)
        if alpha is not None:
            np.testing.assert_array_equal(reference[:, :, 3], alpha)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_16bit_write_accepts_a_non_contiguous_array(tmp_path: Path, suffix: str) -> None:
    """A (H, W, C) view of a channels-first array (what a permuted tensor gives) is written like its copy."""
    channels_first = _random((3, 9, 4), np.uint16)
    pixels = channels_first.transpose(1, 2, 0)
    assert not pixels.flags.c_contiguous
    write_image(tmp_path / f"out{suffix}", Image(pixels=pixels, alpha=None, bit_depth=16))
    np.testing.assert_array_equal(read_image(tmp_path / f"out{suffix}").pixels, pixels)


def test_16bit_grey_alpha_tiff_is_refused(tmp_path: Path) -> None:
    image = Image(pixels=_random((2, 2, 1), np.uint16), alpha=_random((2, 2), np.uint16), bit_depth=16)
    with pytest.raises(DarksynthError, match=r"out\.tif: 16-bit grey with alpha cannot be written as TIFF"):
        write_image(tmp_path / "out.tif", image)
    assert list(tmp_path.iterdir()) == []


def test_16bit_colour_with_exif_orientation(tmp_path: Path) -> None:
    array = _random((2, 3, 3), np.uint16)
    path = tmp_path / "c16.png"
    _write_cv2(path, array)
    with PIL.Image.open(path) as pil:
        exif = PIL.Image.Exif()
        exif[0x0112] = 8
        pil.save(tmp_path / "carrier.png", exif=exif)
    # Graft the eXIf chunk onto the 16-bit file: Pillow itself cannot write 16-bit colour.
    carrier = (tmp_path / "carrier.png").read_bytes()
    start = carrier.index(b"eXIf") - 4
    length = int.from_bytes(carrier[start : start + 4], "big")
    chunk = carrier[start : start + 12 + length]
    data = path.read_bytes()
    iend = data.index(b"IEND") - 4
    (tmp_path / "rot.png").write_bytes(data[:iend] + chunk + data[iend:])
    image = read_image(tmp_path / "rot.png")
    np.testing.assert_array_equal(image.pixels, np.rot90(array))


def test_32bit_integer_image_within_range_becomes_uint16(tmp_path: Path) -> None:
    values = np.array([[0, 1, 65535], [300, 4000, 70]], dtype=np.int32)
    PIL.Image.fromarray(values).save(tmp_path / "i32.tif")
    image = read_image(tmp_path / "i32.tif")
    assert image.source_mode == "I"
    assert image.bit_depth == 16
    np.testing.assert_array_equal(image.pixels[:, :, 0], values)


def test_32bit_integer_image_out_of_range_is_rejected(tmp_path: Path) -> None:
    PIL.Image.fromarray(np.array([[0, 70000]], dtype=np.int32)).save(tmp_path / "i32.tif")
    with pytest.raises(InputFileError, match=r"outside 0\.\.65535"):
        read_image(tmp_path / "i32.tif")


def test_float_image_is_rejected(tmp_path: Path) -> None:
    PIL.Image.fromarray(np.ones((2, 2), dtype=np.float32)).save(tmp_path / "f.tif")
    with pytest.raises(InputFileError, match="floating-point images are not supported") as info:
        read_image(tmp_path / "f.tif")
    assert info.value.path == tmp_path / "f.tif"


# --- bad inputs --------------------------------------------------------------------------------------------------


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="no such file"):
        read_image(tmp_path / "missing.png")


def test_folder_is_not_an_image(tmp_path: Path) -> None:
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(InputFileError, match="is a folder"):
        read_image(tmp_path / "dir.png")


def test_random_bytes_with_png_suffix(tmp_path: Path) -> None:
    path = tmp_path / "noise.png"
    path.write_bytes(RNG.integers(0, 256, size=4096, dtype=np.uint8).tobytes())
    with pytest.raises(InputFileError, match="not an image file") as info:
        read_image(path)
    assert info.value.path == path


def test_text_file_named_jpg(tmp_path: Path) -> None:
    path = tmp_path / "notes.jpg"
    path.write_text("this is not a JPEG\n" * 20)
    with pytest.raises(InputFileError, match="not an image file"):
        read_image(path)


def test_corrupt_png_body(tmp_path: Path) -> None:
    path = _save_pil(tmp_path / "c.png", _random((32, 32, 3)))
    data = bytearray(path.read_bytes())
    data[60:200] = bytes(140)
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match="corrupt or truncated"):
        read_image(path)


@pytest.mark.parametrize(
    ("suffix", "shape", "dtype", "writer"),
    [
        (".png", (64, 64, 3), np.uint8, "pil"),
        (".jpg", (64, 64, 3), np.uint8, "pil"),
        (".tif", (64, 64, 3), np.uint8, "pil"),
        (".png", (64, 64, 3), np.uint16, "cv2"),
    ],
)
def test_truncated_file(tmp_path: Path, suffix: str, shape: tuple[int, ...], dtype: type, writer: str) -> None:
    path = tmp_path / f"cut{suffix}"
    array = _random(shape, dtype)
    _save_pil(path, array) if writer == "pil" else _write_cv2(path, array)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputFileError) as info:
        read_image(path)
    assert info.value.path == path
    assert info.value.__cause__ is None and info.value.__suppress_context__


def test_decompression_bomb_warning_is_not_a_crash(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _save_pil(tmp_path / "big.png", _random((10, 10, 3)))
    monkeypatch.setattr(PIL.Image, "MAX_IMAGE_PIXELS", 60)  # 100 pixels: over the limit, under twice it
    assert read_image(path).pixels.shape == (10, 10, 3)
    monkeypatch.setattr(PIL.Image, "MAX_IMAGE_PIXELS", 40)
    with pytest.raises(InputFileError, match="too large"):
        read_image(path)


# --- writing -----------------------------------------------------------------------------------------------------


def test_jpeg_is_written_444_with_quality(tmp_path: Path) -> None:
    pixels = _random((16, 16, 3))
    write_image(tmp_path / "hi.jpg", Image(pixels=pixels), jpeg_quality=95)
    write_image(tmp_path / "lo.jpeg", Image(pixels=pixels), jpeg_quality=20)
    with PIL.Image.open(tmp_path / "hi.jpg") as pil:
        assert isinstance(pil, PIL.JpegImagePlugin.JpegImageFile)
        assert PIL.JpegImagePlugin.get_sampling(pil) == 0  # 0 means 4:4:4
    assert (tmp_path / "lo.jpeg").stat().st_size < (tmp_path / "hi.jpg").stat().st_size
    error = np.abs(read_image(tmp_path / "hi.jpg").pixels.astype(int) - pixels).mean()
    assert error < 12


@pytest.mark.parametrize("suffix", [".jpg", ".bmp"])
def test_alpha_is_dropped_where_the_format_has_none(tmp_path: Path, suffix: str) -> None:
    image = Image(pixels=_random((4, 4, 3)), alpha=_random((4, 4)))
    write_image(tmp_path / f"out{suffix}", image)
    back = read_image(tmp_path / f"out{suffix}")
    assert back.alpha is None
    assert back.pixels.shape == (4, 4, 3)


@pytest.mark.parametrize("suffix", [".jpg", ".bmp"])
def test_16bit_to_8bit_only_format_raises(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"out{suffix}"
    with pytest.raises(DarksynthError, match=r"out\.(jpg|bmp).*(JPEG|BMP) cannot store 16-bit"):
        write_image(path, Image(pixels=_random((2, 2, 3), np.uint16), bit_depth=16))
    assert list(tmp_path.iterdir()) == []


def test_unknown_output_suffix_raises(tmp_path: Path) -> None:
    with pytest.raises(DarksynthError, match=r"out\.gif.*suffix '\.gif'"):
        write_image(tmp_path / "out.gif", Image(pixels=_random((2, 2, 3))))


def test_write_creates_folders_and_leaves_no_temp(tmp_path: Path) -> None:
    path = tmp_path / "a" / "b" / "out.png"
    write_image(path, Image(pixels=_random((3, 3, 1))))
    assert [p.name for p in path.parent.iterdir()] == ["out.png"]


def test_failed_write_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "out.png"
    path.write_bytes(b"old")

    def fail(*args: object, **kwargs: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(PIL.Image.Image, "save", fail)
    with pytest.raises(DarksynthError, match="disk full"):
        write_image(path, Image(pixels=_random((3, 3, 3))))
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_bad_jpeg_quality() -> None:
    with pytest.raises(ValueError, match="jpeg_quality"):
        write_image(Path("x.jpg"), Image(pixels=_random((2, 2, 3))), jpeg_quality=0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"pixels": np.zeros((2, 2), np.uint8)}, "shape"),
        ({"pixels": np.zeros((2, 2, 4), np.uint8)}, "shape"),
        ({"pixels": np.zeros((2, 2, 3), np.uint16)}, "must be uint8"),
        ({"pixels": np.zeros((2, 2, 3), np.uint8), "bit_depth": 12}, "bit_depth"),
        ({"pixels": np.zeros((2, 2, 3), np.uint8), "alpha": np.zeros((2, 3), np.uint8)}, "alpha must have shape"),
        ({"pixels": np.zeros((2, 2, 3), np.uint8), "alpha": np.zeros((2, 2), np.uint16)}, "alpha must have the"),
    ],
)
def test_image_validates_its_arrays(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Image(**kwargs)  # type: ignore[arg-type]


def test_a_str_path_reads_like_a_path(tmp_path: Path) -> None:
    """A str path was passed on to Pillow as it was and reported as a corrupt image."""
    pixels = _random((6, 4, 3))
    path = tmp_path / "str.png"
    write_image(path, Image(pixels=pixels, bit_depth=8))
    np.testing.assert_array_equal(read_image(str(path)).pixels, pixels)


def test_a_warning_of_pillow_becomes_one_logged_line_naming_the_file(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A damaged tag Pillow skips: the image is read and the user gets one line naming the file, not Python's
    two-line warning from Pillow's source (the suite turns warnings into errors, so this fails without it)."""
    buffer = io.BytesIO()
    PIL.Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(buffer, "TIFF")
    damaged = bytearray(buffer.getvalue())
    damaged[122] = 194  # the PlanarConfiguration tag (284) now claims data beyond the end of the file
    path = tmp_path / "damaged.tif"
    path.write_bytes(bytes(damaged))
    with caplog.at_level(logging.WARNING, logger="darksynth"):
        image = read_image(path)
    assert image.pixels.shape == (8, 8, 3)
    messages = [r.getMessage() for r in caplog.records if r.name == "darksynth.io.images"]
    assert messages == [f"{path}: Tag data larger than file. Skipping tag 284"]
