"""``darksynth demo``: the main job on the shipped sample, with a side-by-side preview."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image as PILImage
from PIL import ImageDraw

from darksynth.apply import ApplyOptions, apply
from darksynth.darkening import darken
from darksynth.errors import DarksynthError
from darksynth.estimate import estimate, load_reference
from darksynth.io.arrays import hwc_to_chw
from darksynth.io.images import Image, read_image, write_image
from darksynth.profile import Profile, default_profile_path, load_profile, save_profile
from darksynth.training.weights import default_weights_path, load_weights

SAMPLE = Path(__file__).parent / "data" / "sample"
LABEL_HEIGHT = 18


def sample_path(name: str) -> Path:
    """A file of the shipped sample (clean.png, clean_clip.mp4, reference.png)."""
    return SAMPLE / name


def _brighten(pixels: np.ndarray, target_mean: float = 0.45) -> np.ndarray:
    # Dark panels are shown a second time with a gain that brings their mean to mid-grey, so the noise shows.
    as_float = pixels.astype(np.float32) / 255.0
    gain = target_mean / max(float(as_float.mean()), 1e-3)
    brightened: np.ndarray = (np.clip(as_float * gain, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return brightened


def _centre_crop(pixels: np.ndarray, height: int, width: int) -> np.ndarray:
    top = max(0, (pixels.shape[0] - height) // 2)
    left = max(0, (pixels.shape[1] - width) // 2)
    crop = pixels[top : top + height, left : left + width]
    padded = np.zeros((height, width, 3), dtype=np.uint8)
    padded[: crop.shape[0], : crop.shape[1]] = crop
    return padded


def preview(panels: list[tuple[str, np.ndarray]], *, brighten_from: int = 1) -> np.ndarray:
    """Side-by-side panels with labels, and below them the panels from ``brighten_from`` on, brightened."""
    height, width = panels[0][1].shape[:2]
    rows = [[p for _, p in panels], [p if i < brighten_from else _brighten(p) for i, (_, p) in enumerate(panels)]]
    canvas = PILImage.new("RGB", (width * len(panels), LABEL_HEIGHT + 2 * height), "black")
    draw = ImageDraw.Draw(canvas)
    for column, (label, _) in enumerate(panels):
        draw.text((column * width + 4, 3), label, fill="white")
        for row, images in enumerate(rows):
            canvas.paste(PILImage.fromarray(images[column]), (column * width, LABEL_HEIGHT + row * height))
    draw.text((4, LABEL_HEIGHT + height + 3), "below: dark panels brightened to mid-grey", fill="yellow")
    return np.asarray(canvas)


def demo_profile() -> tuple[Profile, str]:
    """The demo's profile: noise estimated from the sample reference by the shipped DEN, darkening from the
    shipped default profile (estimating darkening is later work); the shipped profile alone without weights."""
    fallback = load_profile(default_profile_path())
    weights = default_weights_path()
    if not weights.is_file():
        return fallback, "profile shipped with darksynth (no DEN weights installed)"
    estimated = estimate(load_reference(sample_path("reference.png")), load_weights(weights), source="reference.png")
    profile = Profile(
        noise=estimated.profile.noise,
        darkening=fallback.darkening,
        meta={**estimated.profile.meta, "darkening": "from the shipped default profile"},
    )
    return profile, f"estimated from the sample reference by {weights.name}"


def run_demo(out: Path, *, seed: int = 0) -> list[Path]:
    """Write the low-light sample image and clip, the profile used and a preview into ``out``.

    Returns:
        The files written.

    Raises:
        DarksynthError: ``out`` exists and is not a folder, or a sample file is missing from the installation.
    """
    if out.exists() and not out.is_dir():
        raise DarksynthError(f"{out}: exists and is not a folder")
    for name in ("clean.png", "clean_clip.mp4", "reference.png"):
        if not sample_path(name).is_file():
            raise DarksynthError(f"{sample_path(name)}: demo sample missing from the installation")
    profile, source = demo_profile()
    # The demo's folder is the demo's own: a second run replaces its files.
    options = ApplyOptions(profile=profile, seed=seed, profile_source=source, overwrite=True)
    out.mkdir(parents=True, exist_ok=True)
    profile_out = out / "profile.json"
    save_profile(profile_out, profile)
    image_report = apply(sample_path("clean.png"), out / "clean_lowlight.png", options)
    clip_report = apply(sample_path("clean_clip.mp4"), out / "clip_lowlight.mp4", options)
    for report in (image_report, clip_report):
        if report.failures:
            raise DarksynthError(report.failures[0])

    clean = read_image(sample_path("clean.png")).pixels
    darkening = image_report.records[0]["parameters"]["darkening"]
    clean_tensor = hwc_to_chw(clean).float() / 255.0
    darkened = darken(clean_tensor, darkening["alpha"], darkening["gamma"])
    darkened_pixels = (darkened * 255.0).round().byte().permute(1, 2, 0).numpy()
    noisy = read_image(out / "clean_lowlight.png").pixels
    reference = read_image(sample_path("reference.png")).pixels
    panels = [
        ("clean", clean),
        (f"darkened a={darkening['alpha']:.2f} g={darkening['gamma']:.2f}", darkened_pixels),
        ("darkened + noise", noisy),
        ("real reference (crop)", _centre_crop(reference, *clean.shape[:2])),
    ]
    preview_path = out / "preview.png"
    write_image(preview_path, Image(preview(panels)))
    manifests = [r.manifest for r in (image_report, clip_report) if r.manifest is not None]
    return [profile_out, out / "clean_lowlight.png", out / "clip_lowlight.mp4", *manifests, preview_path]
