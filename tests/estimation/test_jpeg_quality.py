"""Which simulated JPEG strength a reference was encoded at, read off its luma's DCT lattice
(estimation/noise/jpeg_quality.py): each candidate's quality read on noisy dark frames at any grid phase; no read on
noise never encoded, on another quality's JPEG, on a resized JPEG or on too few coefficients; and the fit then
simulates only the strength read."""

from __future__ import annotations

import pytest
import torch

from darksynth.estimation.noise.jpeg_quality import MIN_STEP, lattice_score, luminance_table, read_compression
from darksynth.estimation.noise.spectrum import estimate_spectrum
from darksynth.noise.compression import jpeg_compress

CANDIDATES = (0.0, 0.2, 0.4)


def _noisy(seed: int, size: int = 256, level: float = 0.1, noise: float = 0.02) -> torch.Tensor:
    """A smooth dark scene with white noise, on 8-bit levels."""
    generator = torch.Generator().manual_seed(seed)
    coarse = torch.rand(1, 3, 8, 8, generator=generator)
    scene = torch.nn.functional.interpolate(coarse, size=(size, size), mode="bicubic", align_corners=False)[0]
    image = level * (0.5 + scene.clamp(0, 1)) + noise * torch.randn(3, size, size, generator=generator)
    return (image.clamp(0, 1) * 255.0).round() / 255.0


def test_pillow_s_table_is_the_standard_one_scaled_by_quality() -> None:
    # libjpeg's luminance table at quality 50 is the standard one (its top-left 16, 11, 10, 16): natural order.
    assert luminance_table(50)[0, :4].tolist() == [16.0, 11.0, 10.0, 16.0]
    assert luminance_table(60)[0, 0] == 13.0 and luminance_table(80)[0, 0] == 6.0


@pytest.mark.parametrize(("quality", "expected"), [(80, 0.2), (60, 0.4)])
@pytest.mark.parametrize("offset", [(0, 0), (3, 5)])
def test_each_candidate_s_quality_is_read_at_any_grid_phase(
    quality: int, expected: float, offset: tuple[int, int]
) -> None:
    for seed in range(3):
        top, left = offset
        frame = jpeg_compress(_noisy(seed), quality)[:, top:, left:]
        chosen, meta = read_compression(frame, CANDIDATES)
        assert chosen == expected, meta


def test_noise_never_encoded_and_other_qualities_read_nothing() -> None:
    for seed in range(3):
        frame = _noisy(seed)
        chosen, meta = read_compression(frame, CANDIDATES)
        scores = [value["score"] for value in meta["lattice_scores"].values()]  # type: ignore[attr-defined]
        assert chosen is None and max(scores) < 0.2, meta
        # 30 and 40 put some of their steps on quality 60's and 80's (scores about 0.6): still no read.
        for quality in (30, 40, 50, 70, 95):
            chosen, meta = read_compression(jpeg_compress(frame, quality), CANDIDATES)
            assert chosen is None, (quality, meta)


def test_a_resized_jpeg_and_a_tiny_or_black_frame_read_nothing() -> None:
    compressed = jpeg_compress(_noisy(0, size=384), 60)
    resized = torch.nn.functional.interpolate(compressed[None], size=(256, 256), mode="bilinear", antialias=True)[0]
    assert read_compression((resized * 255).round() / 255, CANDIDATES)[0] is None
    assert read_compression(jpeg_compress(_noisy(0, size=64), 60)[:, :12, :12], CANDIDATES)[0] is None
    black = jpeg_compress(torch.zeros(3, 128, 128), 60)  # every coefficient zero: on every lattice, read none
    assert read_compression(black, CANDIDATES)[0] is None


def test_the_lattice_score_runs_from_chance_to_all() -> None:
    table = luminance_table(60)
    generator = torch.Generator().manual_seed(0)
    on = torch.round(torch.randn(2000, 8, 8, generator=generator) * 8.0) * table
    uniform = torch.randn(2000, 8, 8, generator=generator) * 40.0
    assert lattice_score(on, table)[0] == pytest.approx(1.0)
    assert abs(lattice_score(uniform, table)[0]) < 0.05
    assert lattice_score(uniform, table)[1] < int((table >= MIN_STEP).sum()) * 2000


def test_the_fit_simulates_only_the_strength_the_lattice_reads() -> None:
    reference = jpeg_compress(_noisy(4, size=192), 60)
    meta = estimate_spectrum(reference[None], seed=0).meta
    assert meta["jpeg_lattice"]["lattice_read"] == 0.4
    assert meta["compression_chosen"] == 0.4 and list(meta["compression_scores"]) == ["0.4"]
    plain = estimate_spectrum(_noisy(4, size=192)[None], seed=0).meta
    assert plain["jpeg_lattice"]["lattice_read"] is None and len(plain["compression_scores"]) == 3
