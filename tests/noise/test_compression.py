"""The compression stage: JPEG at the table's strength, on 8-bit levels, each clip at its own strength."""

from __future__ import annotations

import torch

from darksynth.noise.compression import jpeg_compress, jpeg_compress_clips, jpeg_quality
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues


def _values(**set_values: float | list[float]) -> NoiseValues:
    return NoiseValues.from_values(set_values, dtype=torch.float32)


def test_jpeg_quality_lowers_fine_scale_energy() -> None:
    clean = torch.full((1, 3, 128, 128), 0.5)
    noisy = add_noise(clean, _values(read=0.03), generator=torch.Generator().manual_seed(6))[0]

    def fine_energy(image: torch.Tensor) -> float:
        return float((image[..., :, 1:] - image[..., :, :-1]).square().mean())

    energies = [fine_energy(jpeg_compress(noisy, q)) for q in (95, 75, 40)]
    assert fine_energy(noisy) > energies[0] > energies[1] > energies[2]
    compressed = jpeg_compress(noisy[None], 75)
    assert compressed.shape == (1, 3, 128, 128) and compressed.dtype == noisy.dtype
    assert torch.equal(compressed * 255, (compressed * 255).round())


def test_jpeg_strength_maps_to_quality_and_zero_means_none() -> None:
    assert jpeg_quality(0.0) is None
    assert jpeg_quality(0.3) == 70
    assert jpeg_quality(0.95) == 5
    assert jpeg_quality(0.001) == 100


def test_compression_stage_compresses_each_clip_at_its_strength() -> None:
    generator = torch.Generator().manual_seed(6)
    clips = (0.3 + 0.05 * torch.randn(3, 2, 3, 48, 64, generator=generator)).clamp(0, 1)
    clips = (clips * 255).round() / 255
    out = jpeg_compress_clips(clips, torch.tensor([0.0, 0.3, 0.6]))
    assert torch.equal(out[0], clips[0])
    assert torch.equal(out[1], jpeg_compress(clips[1], 70))
    assert torch.equal(out[2], jpeg_compress(clips[2], 40))
    # Stronger compression removes more of the fine-scale noise energy.
    fine = [float((c[..., 1:] - c[..., :-1]).square().mean()) for c in out]
    assert fine[0] > fine[1] > fine[2]


def test_add_noise_with_compression_gives_8_bit_levels() -> None:
    signal = torch.full((1, 2, 3, 64, 64), 0.2)
    noisy = add_noise(signal, _values(read=0.03, compression=0.4), generator=torch.Generator().manual_seed(7))
    levels = noisy * 255
    assert torch.equal(levels, levels.round())
    white = add_noise(signal, _values(read=0.03), generator=torch.Generator().manual_seed(7))
    assert not torch.equal(noisy, (white * 255).round() / 255)
