"""A camera JPEG's 8-px block grid (estimation/noise/jpeg_grid.py): seen on JPEG, not on noise or a 4-px period; a
single image that shows it takes its texture dependence from the camera prior, a clip and an image without it do not."""

from __future__ import annotations

import pytest
import torch

from darksynth.cameras.prior import held_out_sets, shipped_prior
from darksynth.estimation.assemble import estimate
from darksynth.estimation.noise.jpeg_grid import jpeg_grid
from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions
from darksynth.models.den import DEN
from darksynth.noise.compression import jpeg_compress
from darksynth.training.weights import default_weights_path, load_weights


def _noisy(seed: int, size: int = 256) -> torch.Tensor:
    """A smooth dark scene (no period of its own) with white noise of 3 levels, on 8-bit levels."""
    generator = torch.Generator().manual_seed(seed)
    coarse = torch.rand(1, 3, 16, 16, generator=generator)
    scene = torch.nn.functional.interpolate(coarse, size=(size, size), mode="bicubic", align_corners=False)[0]
    image = (0.05 + 0.2 * scene.clamp(0, 1) + 0.012 * torch.randn(3, size, size, generator=generator)).clamp(0, 1)
    return (image * 255.0).round() / 255.0


def test_jpeg_shows_the_grid_and_noise_alone_does_not() -> None:
    for seed in range(3):
        noisy = _noisy(seed)
        assert not jpeg_grid(noisy).shown
        found = jpeg_grid(jpeg_compress(noisy, 60))
        assert found.shown and found.score > 1.3, found
        # Cropped off the grid by 3 and 5 px, the grid is still one phase in 8.
        assert jpeg_grid(jpeg_compress(noisy, 60)[:, 3:, 5:]).shown


def test_a_four_pixel_period_is_not_a_jpeg_grid() -> None:
    noisy = _noisy(0)
    steps = torch.zeros(256)
    steps[::4] = 4.0 / 255.0  # a step every 4 px, on both axes
    patterned = ((noisy + steps[None, :, None] + steps[None, None, :]) * 255.0).round().clamp(0, 255) / 255.0
    assert not jpeg_grid(patterned).shown


def test_a_tiny_image_shows_no_grid() -> None:
    assert not jpeg_grid(jpeg_compress(_noisy(0, size=64)[:, :12, :12], 60)).shown


@pytest.fixture(scope="module")
def network() -> DEN:
    return load_weights(default_weights_path("v3", "srgb"))


def _texture(found: object) -> float:
    return float(found.profile.noise["texture_gain"].reshape(-1)[0])  # type: ignore[attr-defined]


def test_a_jpeg_photo_takes_the_prior_s_texture_dependence_and_a_clip_or_a_plain_image_none(network: DEN) -> None:
    plain, compressed = _noisy(1), jpeg_compress(_noisy(1), 70)
    found = estimate(compressed[None], network, source="photo.jpg")
    grid = found.profile.meta["jpeg_grid"]
    assert grid["shown"] and "camera prior" in grid["texture_from"]
    assert _texture(found) > 0.0
    assert found.profile.meta["spectrum"]["camera_prior"]["supplied"] == ["texture dependence"]
    unasked = estimate(compressed[None], network, source="photo.jpg", options=NoiseEstimateOptions(jpeg_texture=False))
    assert _texture(unasked) == 0.0 and "jpeg_grid" not in unasked.profile.meta
    without = estimate(plain[None], network, source="photo.png")
    assert not without.profile.meta["jpeg_grid"]["shown"] and _texture(without) == 0.0
    clip = estimate(torch.stack([compressed, jpeg_compress(_noisy(2), 70)]), network, source="clip")
    assert "jpeg_grid" not in clip.profile.meta and _texture(clip) == 0.0


def test_the_texture_comes_from_the_prior_it_is_given(network: DEN) -> None:
    compressed = jpeg_compress(_noisy(3), 70)[None]
    without_polyu = shipped_prior(held_out_sets("polyu"))
    options = NoiseEstimateOptions(jpeg_texture_prior=without_polyu)
    found = estimate(compressed, network, source="photo.jpg", options=options)
    assert "polyu" not in found.profile.meta["jpeg_grid"]["texture_from"]
    assert "polyu" in estimate(compressed, network, source="photo.jpg").profile.meta["jpeg_grid"]["texture_from"]


def test_the_texture_rise_is_one_on_a_flat_scene_and_grows_with_its_detail() -> None:
    from darksynth.estimation.noise.readings import texture_rise

    flat = torch.full((1, 3, 96, 96), 0.2)
    assert texture_rise(flat, 0.5, 0.003) == pytest.approx(1.0)
    generator = torch.Generator().manual_seed(0)
    detail = flat + 0.02 * torch.randn(1, 3, 96, 96, generator=generator)
    assert texture_rise(detail, 0.5, 0.003) > 2.0
    assert texture_rise(detail, 0.0, 0.003) == pytest.approx(1.0)
