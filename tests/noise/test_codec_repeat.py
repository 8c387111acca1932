"""A codec's skipped blocks (noise/codec_repeat.py): which cells are still, the share repeated in every route of a
clip (the 8-bit stream, the compiled-free spectral pass, the float whole-clip composer), none where the scene moves,
none in a single image, and the profile keeps the value."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from darksynth.noise.codec_repeat import CELL, still_cells
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, load_profile, save_profile
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer, synthesize

SIDE = 128
FRAMES = 8


def _values(codec_repeat: float, compression: float = 0.0) -> NoiseValues:
    # A spectral profile of about 4 levels of noise: no 8-px cell of 192 values repeats by chance.
    return NoiseValues.from_values(
        {
            "level_curve": [4.0 / 255] * 24,
            "octave_power": [1.0] * 18,
            "temporal_correlation": [0.3] * 6,
            "compression": compression,
            "codec_repeat": codec_repeat,
        }
    )


def _scene(moving_left: bool, seed: int = 0) -> torch.Tensor:
    """(FRAMES, 3, SIDE, SIDE) uint8: a still textured scene; with ``moving_left`` its left half shifts by one pixel
    every frame."""
    generator = torch.Generator().manual_seed(seed)
    wide = torch.randint(20, 200, (3, SIDE, SIDE + FRAMES), generator=generator, dtype=torch.uint8)
    frames = []
    for t in range(FRAMES):
        frame = wide[..., :SIDE].clone()
        if moving_left:
            frame[..., : SIDE // 2] = wide[..., t : t + SIDE // 2]
        frames.append(frame)
    return torch.stack(frames)


def _repeated_cells(clip: torch.Tensor) -> torch.Tensor:
    """(T - 1, SIDE / CELL, SIDE / CELL) whether each cell repeats bit for bit from the frame before."""
    same = (clip[1:] == clip[:-1]).all(dim=1)
    return same.reshape(FRAMES - 1, SIDE // CELL, CELL, SIDE // CELL, CELL).all(dim=4).all(dim=2)


def _stream(clean: torch.Tensor, codec_repeat: float, seed: int = 0) -> torch.Tensor:
    synthesizer = ClipSynthesizer(
        ClipParameters(_values(codec_repeat), None), generator=torch.Generator().manual_seed(seed)
    )
    return torch.stack([synthesizer(frame) for frame in clean])


def test_a_cell_is_still_unless_a_value_in_it_changes_by_more_than_one_level() -> None:
    before = torch.full((3, 32, 32), 0.5)
    after = before.clone()
    after[1, 3, 20] += 1.0 / 255  # one level: still
    after[0, 17, 9] += 2.0 / 255  # two levels: the cell (2, 1) moves
    still = still_cells(before, after)
    assert still.shape == (4, 4)
    assert not bool(still[2, 1]) and int(still.sum()) == 15
    # A partial cell at the edge counts.
    assert still_cells(before[..., :30, :30], after[..., :30, :30]).shape == (4, 4)


@pytest.mark.parametrize("share", [0.3, 0.8])
def test_the_stream_repeats_the_share_of_still_cells_and_none_that_move(share: float) -> None:
    repeated = _repeated_cells(_stream(_scene(moving_left=True), share))
    left, right = repeated[..., : SIDE // CELL // 2], repeated[..., SIDE // CELL // 2 :]
    assert int(left.sum()) == 0
    # 7 pairs x 128 still cells, drawn independently: the share's std is 0.015.
    assert abs(float(right.float().mean()) - share) < 0.06, float(right.float().mean())


def test_without_the_codec_no_cell_repeats_and_the_bits_are_those_of_the_table_without_it() -> None:
    clean = _scene(moving_left=False)
    assert int(_repeated_cells(_stream(clean, 0.0)).sum()) == 0
    # A single image has no frame before it: the same bits at any share.
    one = [
        ClipSynthesizer(ClipParameters(_values(share), None), generator=torch.Generator().manual_seed(2)).image(
            clean[0]
        )
        for share in (0.0, 0.9)
    ]
    assert torch.equal(one[0], one[1])


def test_the_float_clip_route_repeats_like_the_stream() -> None:
    clean = _scene(moving_left=True).float() / 255
    result = synthesize(clean, Profile(noise=_values(0.6)), darkening=None, generator=torch.Generator().manual_seed(1))
    assert isinstance(result.image, torch.Tensor)
    repeated = _repeated_cells((result.image * 255).round().to(torch.uint8))
    assert int(repeated[..., : SIDE // CELL // 2].sum()) == 0
    assert abs(float(repeated[..., SIDE // CELL // 2 :].float().mean()) - 0.6) < 0.06
    assert result.parameters["noise"]["codec_repeat"] == pytest.approx(0.6)


def test_repeats_follow_compression_and_the_profile_keeps_the_share(tmp_path: Path) -> None:
    # The repeat copies the finished (compressed) frame: the cells repeated are bit-identical after JPEG too.
    synthesizer = ClipSynthesizer(
        ClipParameters(_values(0.5, compression=0.2), None), generator=torch.Generator().manual_seed(3)
    )
    clip = torch.stack([synthesizer(frame) for frame in _scene(moving_left=False)])
    assert abs(float(_repeated_cells(clip).float().mean()) - 0.5) < 0.08
    path = tmp_path / "codec.json"
    save_profile(path, Profile(noise=_values(0.5)))
    assert load_profile(path).noise.scalar("codec_repeat") == pytest.approx(0.5)
