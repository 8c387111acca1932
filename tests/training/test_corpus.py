"""load_corpus and sample_clean_clips: what is read, what is left out, where crops start."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from darksynth.errors import DarksynthError
from darksynth.training.corpus import CleanCorpus, load_corpus, sample_clean_clips
from tests.clean_images import smooth_rgb, write_png


def test_stills_and_clip_folders_are_read(image_folder: Path, clip_root: Path) -> None:
    corpus = load_corpus([image_folder], [clip_root])
    assert len(corpus.images) == 3
    assert len(corpus.clips) == 1
    assert corpus.clips[0].shape == (4, 96, 96, 3)
    assert corpus.clips[0].dtype == np.uint8
    np.testing.assert_array_equal(corpus.clips[0][2], smooth_rgb(96, 96, phase=6))
    assert len(corpus) == 4


def test_small_images_are_left_out(image_folder: Path) -> None:
    write_png(image_folder / "tiny.png", smooth_rgb(40, 96))
    corpus = load_corpus([image_folder])
    assert len(corpus.images) == 3
    assert all(image.shape == (96, 96, 3) for image in corpus.images)


def test_clip_frames_of_different_sizes_are_refused(clip_root: Path) -> None:
    write_png(clip_root / "walk" / "frame_999.png", smooth_rgb(80, 96))
    with pytest.raises(DarksynthError, match="walk"):
        load_corpus([], [clip_root])


def test_no_usable_material_is_an_error(tmp_path: Path) -> None:
    write_png(tmp_path / "small" / "a.png", smooth_rgb(40, 40))
    with pytest.raises(DarksynthError, match="no training images or clips"):
        load_corpus([tmp_path / "small"])


def test_no_usable_material_error_names_the_minimum_side(tmp_path: Path) -> None:
    write_png(tmp_path / "small" / "a.png", smooth_rgb(40, 40))
    with pytest.raises(DarksynthError) as raised:
        load_corpus([tmp_path / "small"], minimum_side=64)
    assert "64" in str(raised.value)
    assert "{" not in str(raised.value)


def test_crops_start_at_multiples_of_four_columns() -> None:
    """Each pixel holds its column index, so a crop's first value is its left edge."""
    columns = np.broadcast_to(np.arange(150, dtype=np.uint8)[None, :, None], (70, 150, 3))
    corpus = CleanCorpus(images=[np.ascontiguousarray(columns)], sources=["columns"])
    crops = sample_clean_clips(corpus, 64, 2, 32, generator=torch.Generator().manual_seed(0))
    assert crops.shape == (64, 2, 3, 32, 32)
    lefts = (crops[:, :, :, :, 0] * 255).round().long()
    assert (lefts == lefts[:, :1, :1, :1]).all()
    lefts = lefts[:, 0, 0, 0]
    assert (lefts % 4 == 0).all()
    assert lefts.max() <= 150 - 32
    assert len(set(lefts.tolist())) > 5
    steps = (crops[..., 1:] - crops[..., :-1]) * 255
    torch.testing.assert_close(steps, torch.ones_like(steps), atol=1e-4, rtol=0)


def test_windows_of_a_clip_are_consecutive_frames() -> None:
    """Each frame of the clip holds its index; a window of T frames holds T consecutive indices."""
    frames = np.stack([np.full((40, 40, 3), index, dtype=np.uint8) for index in range(10)])
    corpus = CleanCorpus(clips=[frames], sources=["counter"])
    crops = sample_clean_clips(corpus, 16, 3, 32, generator=torch.Generator().manual_seed(1))
    indices = (crops[:, :, 0, 0, 0] * 255).round().long()
    assert ((indices[:, 1:] - indices[:, :-1]) == 1).all()
