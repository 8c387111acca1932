"""Side-by-side preview sheets: clean, darkened, darkened + noise and a real reference, dark panels brightened.

``darksynth preview`` makes one from a user's image and profile before a whole dataset is converted; ``darksynth
demo`` makes one from the shipped sample. The noisy panel is what ``apply`` writes for the same image, seed and
darkening (:func:`darksynth.apply.synthesize_image`), cropped.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from PIL import Image as PILImage
from PIL import ImageDraw

from darksynth.apply import ApplyOptions, synthesize_image
from darksynth.apply_outputs import claim_outputs
from darksynth.errors import DarksynthError
from darksynth.io.discover import check_output_location, classify_input, scan_folder
from darksynth.io.images import IMAGE_SUFFIXES, Image, read_image, write_image
from darksynth.io.video import VIDEO_SUFFIXES, iter_video_frames
from darksynth.light.darkening import Darkening, darken
from darksynth.profile import Profile

LABEL_HEIGHT = 18
MID_GREY = 0.45
"""Mean level, in [0, 1], that the brightened row brings a dark panel to."""

PANEL_SIZE = (512, 512)
"""Largest panel (width, height) by default: four panels side by side stay viewable on one screen."""


def mid_grey_gain(pixels: np.ndarray, target_mean: float = MID_GREY) -> float:
    """The gain that brings the mean of 8-bit ``pixels`` to ``target_mean``."""
    return target_mean / max(float(pixels.astype(np.float32).mean()) / 255.0, 1e-3)


def brighten(pixels: np.ndarray, gain: float | None = None) -> np.ndarray:
    """8-bit ``pixels`` multiplied by ``gain`` and clipped; by default the gain that takes their mean to mid-grey."""
    as_float = pixels.astype(np.float32) / 255.0
    if gain is None:
        gain = mid_grey_gain(pixels)
    brightened: np.ndarray = (np.clip(as_float * gain, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return brightened


def centre_window(pixels: np.ndarray, height: int, width: int) -> np.ndarray:
    """The centre ``height`` x ``width`` of an image (H, W, C), or less where it is smaller (a view, not a copy)."""
    top = max(0, (pixels.shape[0] - height) // 2)
    left = max(0, (pixels.shape[1] - width) // 2)
    return pixels[top : top + height, left : left + width]


def centre_crop(pixels: np.ndarray, height: int, width: int) -> np.ndarray:
    """The centre ``height`` x ``width`` of an 8-bit RGB image, padded with black where it is smaller."""
    crop = centre_window(pixels, height, width)
    padded = np.zeros((height, width, 3), dtype=np.uint8)
    padded[: crop.shape[0], : crop.shape[1]] = crop
    return padded


def display_pixels(pixels: np.ndarray) -> np.ndarray:
    """An image (H, W, 1 or 3), uint8 or uint16, as the 8-bit RGB a sheet shows."""
    if pixels.dtype == np.uint16:
        pixels = ((pixels.astype(np.uint32) + 128) // 257).astype(np.uint8)
    return np.repeat(pixels, 3, axis=2) if pixels.shape[2] == 1 else pixels


def darkened_pixels(clean: np.ndarray, darkening: Darkening) -> np.ndarray:
    """The darkening alone, x_d = alpha * x ** (1/gamma), of an image (H, W, C), rounded back to its dtype."""
    scale = 65535.0 if clean.dtype == np.uint16 else 255.0
    tensor = torch.from_numpy(clean.astype(np.float32)).permute(2, 0, 1) / scale
    darkened = (darken(tensor, darkening.alpha, darkening.gamma) * scale).round()
    result: np.ndarray = darkened.permute(1, 2, 0).numpy().astype(clean.dtype)
    return result


def compose_sheet(
    panels: list[tuple[str, np.ndarray]], *, brighten_from: int = 1, gain: float | None = None
) -> np.ndarray:
    """Labelled 8-bit RGB panels of one size side by side, and below them the panels from ``brighten_from`` on,
    brightened.

    Args:
        panels: (label, pixels (H, W, 3) uint8) in the order shown.
        brighten_from: the first panel of the second row that is brightened; those before it are shown as they are.
        gain: one gain for every brightened panel, said in a caption bar between the rows; None (the demo's sheet):
            each panel to mid-grey by its own gain, said in a caption over the second row.
    """
    height, width = panels[0][1].shape[:2]
    rows = [
        [p for _, p in panels],
        [p if i < brighten_from else brighten(p, gain) for i, (_, p) in enumerate(panels)],
    ]
    row_tops = (LABEL_HEIGHT, LABEL_HEIGHT + height + (0 if gain is None else LABEL_HEIGHT))
    canvas = PILImage.new("RGB", (width * len(panels), row_tops[1] + height), "black")
    draw = ImageDraw.Draw(canvas)
    for column, (label, _) in enumerate(panels):
        draw.text((column * width + 4, 3), label, fill="white")
        for top, images in zip(row_tops, rows, strict=True):
            canvas.paste(PILImage.fromarray(images[column]), (column * width, top))
    caption = (
        "below: dark panels brightened to mid-grey"
        if gain is None
        else f"below: dark panels x{gain:.1f}, one gain for all (the synthetic panel's mean to mid-grey)"
    )
    draw.text((4, LABEL_HEIGHT + height + 3), caption, fill="yellow")
    return np.asarray(canvas)


def parse_panel_size(text: str) -> tuple[int, int]:
    """``WxH`` (or ``N`` for a square) as (width, height) in pixels, each at least 16."""
    width_text, sep, height_text = text.lower().partition("x")
    try:
        width = int(width_text)
        height = int(height_text) if sep else width
    except ValueError:
        raise DarksynthError(
            f"--crop must be WIDTHxHEIGHT or SIDE in pixels, for example 512x384, got {text!r}"
        ) from None
    if width < 16 or height < 16:
        raise DarksynthError(f"--crop must be at least 16x16 pixels, got {text!r}")
    return width, height


def named_reference(profile: Profile, profile_path: Path | None = None) -> tuple[Path | None, str | None]:
    """The real reference a profile was estimated from: (path, None) when it is found, (None, warning) when the
    profile names one that is missing, (None, None) when it names none.

    ``estimate`` records the reference as given on its command line in ``meta.source`` (with ``meta.estimator``);
    a relative path is looked for from the current folder, then from the profile's folder. A ``source`` without an
    estimator and without an image or video suffix is free-form provenance, not a file.
    """
    source = profile.meta.get("source")
    if not isinstance(source, str) or not source:
        return None, None
    named = Path(source)
    if "estimator" not in profile.meta and named.suffix.lower() not in IMAGE_SUFFIXES | VIDEO_SUFFIXES:
        return None, None
    candidates = [named]
    if not named.is_absolute() and profile_path is not None:
        candidates.append(profile_path.parent / named)
    for candidate in candidates:
        if candidate.exists():
            return candidate, None
    return None, f"{source}: the profile's reference is not found; the preview has no reference panel"


def first_frame(path: Path) -> np.ndarray:
    """The first frame (H, W, C) of a reference: the image itself, a video's first frame, a folder's first image.

    Raises:
        DarksynthError: the reference cannot be read.
    """
    kind = classify_input(path)
    if kind == "image":
        return read_image(path).pixels
    if kind == "video":
        for frame in iter_video_frames(path):
            return frame
        raise DarksynthError(f"{path}: the video has no decodable frames")
    images = scan_folder(path).images
    if not images:
        raise DarksynthError(f"{path}: no images in the folder")
    return read_image(path / images[0]).pixels


@dataclass(frozen=True)
class PreviewOptions:
    """What a preview adds to ``apply``'s options.

    Attributes:
        synthesis: the options ``apply`` would run with (profile, seed, darkening, device).
        panel_size: largest panel (width, height); an image larger than that is shown by its centre.
        overwrite: replace an existing output file (inputs are never replaced).
        profile_path: the profile's file, where a relative reference path is also looked for.
    """

    synthesis: ApplyOptions
    panel_size: tuple[int, int] = PANEL_SIZE
    overwrite: bool = False
    profile_path: Path | None = None


@dataclass
class PreviewReport:
    """What a preview showed: its panels' size and labels, the darkening, the gain and the reference."""

    output: Path
    panel_size: tuple[int, int]
    labels: list[str]
    darkening: Darkening | None
    gain: float
    reference: Path | None
    warnings: list[str] = field(default_factory=list)


def check_preview_output(out: Path, inputs: list[Path], *, overwrite: bool) -> None:
    """Refuse an output that is not an image file, is one of the inputs, exists (unless ``overwrite``) or cannot be
    written.

    Raises:
        DarksynthError: naming the output and the problem.
    """
    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise DarksynthError(f"{out}: a preview needs one of the suffixes {' '.join(sorted(IMAGE_SUFFIXES))}")
    for source in inputs:
        check_output_location(source, out)
    # apply's own rule: refused if it exists (without overwrite) or cannot be written, a killed run's temporary removed.
    claim_outputs([out], out, folder=False, overwrite=overwrite)


def run_preview(image_path: Path, out: Path, options: PreviewOptions) -> PreviewReport:
    """Write a preview sheet of one clean image with a profile: clean | darkened | darkened + noise | reference.

    The second row shows the dark panels with one common gain, so the synthetic panel and the real reference can
    be compared at the same brightness.

    Raises:
        DarksynthError: the image is missing, unreadable or not an image, or the output is refused.
    """
    kind = classify_input(image_path)
    if kind != "image":
        raise DarksynthError(f"{image_path}: is a {kind}; preview takes one image (a frame of it saved as PNG will do)")
    synthesis = options.synthesis
    reference, missing = named_reference(synthesis.recipe.profile, options.profile_path)
    warnings = [missing] if missing else []
    inputs = [image_path, *(p for p in (options.profile_path, reference) if p is not None)]
    check_preview_output(out, inputs, overwrite=options.overwrite)

    clean = read_image(image_path).pixels
    noisy, parameters = synthesize_image(clean, image_path.name, synthesis)
    width = min(options.panel_size[0], clean.shape[1])
    height = min(options.panel_size[1], clean.shape[0])

    def shown(pixels: np.ndarray) -> np.ndarray:
        return centre_crop(display_pixels(pixels), height, width)

    darkening = parameters.darkening
    panels = [("clean", shown(clean))]
    if darkening is not None:
        label = f"darkened a={darkening.alpha:.2f} g={darkening.gamma:.2f}"
        # The darkening is per pixel: the window alone is darkened, at the image's own bit depth.
        panels.append((label, shown(darkened_pixels(centre_window(clean, height, width), darkening))))
    noisy_panel = shown(noisy)
    panels.append(("darkened + noise" if darkening is not None else "noise, not darkened", noisy_panel))
    if reference is not None:
        try:
            panels.append(("real reference (crop)", shown(first_frame(reference))))
        except DarksynthError as error:
            reference = None
            warnings.append(f"{error}; the preview has no reference panel")
    # One gain for the synthetic and the real panel: each brought to mid-grey on its own would hide a difference
    # of level between them, which is part of what a user checks. The synthetic panel sets it, so its noise is
    # shown the same way whatever the reference.
    gain = mid_grey_gain(noisy_panel)
    write_image(out, Image(compose_sheet(panels, gain=gain)))
    return PreviewReport(
        output=out,
        panel_size=(width, height),
        labels=[label for label, _ in panels],
        darkening=darkening,
        gain=gain,
        reference=reference,
        warnings=warnings,
    )
