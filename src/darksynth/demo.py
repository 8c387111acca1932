"""``darksynth demo``: the main job on the shipped sample, with a side-by-side preview."""

from __future__ import annotations

from pathlib import Path

from darksynth.apply import ApplyOptions, apply
from darksynth.errors import DarksynthError
from darksynth.estimation.assemble import estimate
from darksynth.estimation.reference import load_reference
from darksynth.io.images import Image, read_image, write_image
from darksynth.light.darkening import Darkening
from darksynth.preview import centre_crop, compose_sheet, darkened_pixels
from darksynth.profile import Profile, default_profile_path, load_profile, save_profile
from darksynth.recipe import ClipRecipe
from darksynth.training.weights import default_weights_path, load_weights

SAMPLE = Path(__file__).parent / "data" / "sample"


def sample_path(name: str) -> Path:
    """A file of the shipped sample (clean.png, clean_clip.mp4, reference.png)."""
    return SAMPLE / name


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
    options = ApplyOptions(recipe=ClipRecipe(profile), seed=seed, profile_source=source, overwrite=True)
    out.mkdir(parents=True, exist_ok=True)
    profile_out = out / "profile.json"
    save_profile(profile_out, profile)
    # Each input is one file, whose failure apply raises (a one-file report holds no failures).
    image_report = apply(sample_path("clean.png"), out / "clean_lowlight.png", options)
    clip_report = apply(sample_path("clean_clip.mp4"), out / "clip_lowlight.mp4", options)

    clean = read_image(sample_path("clean.png")).pixels
    darkening = image_report.records[0]["parameters"]["darkening"]
    noisy = read_image(out / "clean_lowlight.png").pixels
    reference = read_image(sample_path("reference.png")).pixels
    panels = [
        ("clean", clean),
        (
            f"darkened a={darkening['alpha']:.2f} g={darkening['gamma']:.2f}",
            darkened_pixels(clean, Darkening(**darkening)),
        ),
        ("darkened + noise", noisy),
        ("real reference (crop)", centre_crop(reference, *clean.shape[:2])),
    ]
    preview_path = out / "preview.png"
    write_image(preview_path, Image(compose_sheet(panels)))
    manifests = [r.manifest for r in (image_report, clip_report) if r.manifest is not None]
    return [profile_out, out / "clean_lowlight.png", out / "clip_lowlight.mp4", *manifests, preview_path]
