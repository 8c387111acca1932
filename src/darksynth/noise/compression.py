"""The output stage of camera compression: JPEG through Pillow, applied to the finished noisy frame.

Real sRGB low-light pictures are mostly JPEG (or a video codec): blocks of 8 px, chroma subsampled 4:2:0, fine
detail of the noise removed. The table's ``compression`` c encodes and decodes every frame at quality
``round(100 (1 - c))`` (none for c = 0).
"""

from __future__ import annotations

import io
from collections.abc import Mapping

import numpy as np
import torch
from PIL import Image

from darksynth.noise.component_types import COMPRESSION_PATHS, NoiseComponent, Parameter


def jpeg_compress(image: torch.Tensor, quality: int) -> torch.Tensor:
    """Encode and decode (..., C, H, W) [0, 1] images, C = 3 (colour) or 1 (grey), with Pillow's JPEG encoder
    at ``quality`` (1-100, in memory; Pillow's default 4:2:0 chroma subsampling). The result lies on 8-bit
    levels, with the input's dtype and device. Not differentiable: the image goes through numpy and uint8."""
    if not 1 <= quality <= 100:
        raise ValueError(f"JPEG quality must be in 1..100, got {quality}")
    channels = image.shape[-3]
    if channels not in (1, 3):
        raise ValueError(f"JPEG compression needs 3 or 1 channels, got {channels}")
    mode = "RGB" if channels == 3 else "L"
    pixels = (image.detach().clamp(0.0, 1.0) * 255.0).round().to(torch.uint8).cpu()
    flat = pixels.reshape(-1, *pixels.shape[-3:])
    decoded = []
    for single in flat:
        buffer = io.BytesIO()
        array = single.permute(1, 2, 0).numpy()
        Image.fromarray(array if channels == 3 else array[..., 0], mode=mode).save(
            buffer, format="JPEG", quality=quality
        )
        buffer.seek(0)
        array = np.asarray(Image.open(buffer).convert(mode), dtype=np.uint8).reshape(array.shape)
        decoded.append(torch.from_numpy(array.copy()).permute(2, 0, 1))
    out = torch.stack(decoded).reshape(pixels.shape)
    return out.to(device=image.device, dtype=image.dtype) / 255.0


def jpeg_quality(compression: float) -> int | None:
    """The JPEG quality of a compression strength c in [0, 1): round(100 (1 - c)), None (no JPEG) for c = 0."""
    if compression <= 0.0:
        return None
    return max(1, min(100, round(100.0 * (1.0 - compression))))


def jpeg_compress_clips(clips: torch.Tensor, compression: torch.Tensor) -> torch.Tensor:
    """JPEG-compress every frame of clips (*batch, T, C, H, W) in [0, 1], each clip at its own strength
    (``compression`` shaped like the batch, see :func:`jpeg_quality`); clips of strength 0 pass unchanged."""
    batch = clips.shape[: clips.dim() - 4]
    flat = clips.reshape(-1, *clips.shape[-4:])
    strengths = compression.expand(batch).reshape(-1).tolist() if batch else [float(compression)]
    out = [
        clip if jpeg_quality(c) is None else jpeg_compress(clip, jpeg_quality(c) or 100)
        for clip, c in zip(flat, strengths, strict=True)
    ]
    return torch.stack(out).reshape(clips.shape)


def _draw_compression(
    noisy: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    if noisy.dim() < 4:
        return jpeg_compress_clips(noisy[None], values["compression"][..., 0])[0]
    return jpeg_compress_clips(noisy, values["compression"][..., 0])


COMPRESSION = NoiseComponent(
    name="compression",
    parameters=(
        Parameter(
            "compression",
            1,
            "JPEG compression strength c: quality round(100 (1 - c)), 0 for none",
            0.95,
            (0.0, 0.7),
            noise_model="srgb",
            fast_paths=COMPRESSION_PATHS,
            since_version=2,
            statistics="multiscale",
            training_off_probability=0.4,
        ),
    ),
    structure="output",
    draw=_draw_compression,
    variance=None,
    reference="JPEG (ITU-T T.81) through Pillow, 4:2:0; docs/srgb-noise.md",
)
