"""The coarse anchor: its statistic (the odds of a flat block's noise that survive averaging into coarse means) and
what it says it read."""

import torch
import torch.nn.functional as F

from darksynth.estimation.noise.coarse_anchor import CoarseAnchor, anchor_pool, coarse_odds
from darksynth.estimation.noise.flat_blocks import FLAT_BLOCK
from darksynth.estimation.noise.spectrum import anchor_outcome


def _flat_noise(side: int, std: float, seed: int, blur: float = 0.0) -> torch.Tensor:
    """Noise (3, side, side) of ``std`` about mid-grey with a gentle ramp (a flat wall's shading), optionally
    low-passed by a Gaussian of ``blur`` px (then scaled back to ``std``)."""
    generator = torch.Generator().manual_seed(seed)
    noise = torch.randn(3, side, side, generator=generator, dtype=torch.float64)
    if blur > 0.0:
        radius = int(3 * blur)
        taps = torch.exp(-0.5 * (torch.arange(-radius, radius + 1, dtype=torch.float64) / blur) ** 2)
        taps = taps / taps.sum()
        noise = F.conv2d(noise[:, None], taps[None, None, None, :], padding=(0, radius))
        noise = F.conv2d(noise, taps[None, None, :, None], padding=(radius, 0))[:, 0]
        noise = noise / noise.std()
    ramp = torch.linspace(0.0, 0.05, side, dtype=torch.float64)
    return 0.5 + ramp[None, None, :] + ramp[None, :, None] + std * noise


def test_the_pool_keeps_the_first_unmeasured_octave_and_none_past_a_block_of_four_means() -> None:
    assert anchor_pool(2) == 4 and anchor_pool(3) == 8
    assert anchor_pool(4) is None and anchor_pool(5) is None
    assert FLAT_BLOCK // 8 == 4  # 8-px means: 4 x 4 of them in a block, the fewest the plane leaves a reading in


def test_the_odds_do_not_depend_on_the_noise_level() -> None:
    # The reason for the statistic: the level curve sets the level, and a level error must not move the coarse scale.
    blocks = torch.ones(8, 8, dtype=torch.bool)
    weak = coarse_odds(_flat_noise(256, 2.0 / 255.0, 3), blocks, 8)
    strong = coarse_odds(_flat_noise(256, 12.0 / 255.0, 3), blocks, 8)
    # (The plane projection is float32: the 0.5 offset leaves a residue of some 1e-8 in the weak draw.)
    assert torch.allclose(weak, strong, rtol=1e-4, atol=0.0)


def test_white_noise_keeps_one_part_in_pool_squared_minus_one() -> None:
    # White noise: a p x p mean holds 1/p^2 of the variance, the odds are 1 / (p^2 - 1) (a little less: the plane
    # removes some of the coarse part). Median over 64 blocks x 3 components of one draw.
    blocks = torch.ones(8, 8, dtype=torch.bool)
    for pool in (4, 8):
        odds = coarse_odds(_flat_noise(256, 4.0 / 255.0, pool), blocks, pool)
        expected = 1.0 / (pool * pool - 1)
        assert 0.7 * expected < float(odds.median()) < 1.1 * expected, (pool, float(odds.median()), expected)


def test_coarse_noise_raises_the_odds() -> None:
    blocks = torch.ones(8, 8, dtype=torch.bool)
    white = coarse_odds(_flat_noise(256, 4.0 / 255.0, 5), blocks, 8).median()
    mottled = coarse_odds(_flat_noise(256, 4.0 / 255.0, 5, blur=4.0), blocks, 8).median()
    assert float(mottled) > 10.0 * float(white), (float(white), float(mottled))


def test_only_the_chosen_blocks_are_read() -> None:
    frame = _flat_noise(128, 4.0 / 255.0, 7)
    blocks = torch.zeros(4, 4, dtype=torch.bool)
    blocks[1, 2] = blocks[3, 0] = True
    assert coarse_odds(frame, blocks, 8).shape == (3, 2)


def _anchor() -> CoarseAnchor:
    frame = _flat_noise(128, 4.0 / 255.0, 11)
    return CoarseAnchor.read(frame, frame, torch.ones(128, 128), first_unmeasured=3)


def test_an_anchor_that_only_saw_empty_statistics_read_nothing_and_says_so() -> None:
    # Weak noise erased by JPEG and 8-bit rounding leaves a simulated colour statistic of 0: the update is skipped.
    anchor = _anchor()
    assert anchor.readable and not anchor.observed
    anchor.last = torch.tensor([0.5, 0.0, 0.3], dtype=torch.float64)
    anchor.update()
    assert not anchor.observed and torch.equal(anchor.scale, torch.ones(3, dtype=torch.float64))
    unmatched, meta = anchor_outcome(anchor, True, 3)
    assert unmatched == [] and meta["coarse_anchor"].startswith("not read")
    assert meta["read_octaves"] == {"brightness": 3, "colour": 3}  # colour not counted one octave further
    # Statistics that follow the scale: the anchor moves and the colour octave it anchors counts as read.
    anchor.last = anchor.target / 2.0
    anchor.update()
    anchor.last = anchor.target * 0.95
    anchor.update()
    assert anchor.observed and bool((anchor.scale[1:] > 1.0).all()) and float(anchor.scale[0]) == 1.0
    _, meta = anchor_outcome(anchor, True, 3)
    assert "coarse_anchor" not in meta and meta["read_octaves"] == {"brightness": 3, "colour": 4}
