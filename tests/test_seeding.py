"""derive_seed: pinned values (the seeds recorded in manifests and checkpoints), spread, range; its callers."""

from __future__ import annotations

import hashlib

import pytest
import torch

from darksynth.apply import task_seed
from darksynth.seeding import derive_seed, seeded_generator
from darksynth.training.distributed import Ranks, process_seed
from darksynth.transforms import mix_seed

# Values that the seed derivations gave before they shared derive_seed: manifests written then record them.
PINNED = [
    (("darksynth", 1, "train2017/000000000000.jpg"), 5806132450391506095),
    (("darksynth", 0, "a:b/c.png"), 372144511321099421),
    (("darksynth", "train", 7, "rank", 1), 4838629208405211145),
    (("darksynth-transform", "sample", 0, 5), 7255285004282864930),
]


@pytest.mark.parametrize(("parts", "seed"), PINNED)
def test_pinned_seeds(parts: tuple[int | str, ...], seed: int) -> None:
    assert derive_seed(*parts) == seed


def test_a_seed_is_the_masked_sha256_of_the_joined_parts() -> None:
    digest = hashlib.sha256(b"darksynth:12:x/y.png").digest()
    assert derive_seed("darksynth", 12, "x/y.png") == int.from_bytes(digest[:8], "little") % 2**63


def test_callers_keep_their_layouts() -> None:
    assert task_seed(1, "train2017/000000000000.jpg") == PINNED[0][1]
    assert process_seed(7, Ranks(rank=1, world_size=2)) == PINNED[2][1]
    assert mix_seed("sample", 0, 5) == PINNED[3][1]


def test_different_parts_give_different_seeds_all_below_2_to_the_63() -> None:
    seeds = {derive_seed("darksynth", run, f"image{index}.png") for run in range(20) for index in range(50)}
    seeds |= {derive_seed("darksynth-transform", "sample", 0, index) for index in range(1000)}
    assert len(seeds) == 2000
    assert all(0 <= seed < 2**63 for seed in seeds)
    # The top bit is cleared, not the value squeezed: the seeds still fill the upper half of the range.
    assert any(seed >= 2**62 for seed in seeds)


def test_order_and_grouping_of_parts_matter() -> None:
    assert derive_seed("darksynth", 1, 2) != derive_seed("darksynth", 2, 1)
    assert derive_seed("darksynth", 1) != derive_seed("darksynth", 1, "")


def test_no_parts_is_an_error() -> None:
    with pytest.raises(ValueError, match="at least one part"):
        derive_seed()


def test_seeded_generators_with_one_seed_give_one_stream() -> None:
    first = torch.rand(5, generator=seeded_generator(derive_seed("test", 1)))
    second = torch.rand(5, generator=seeded_generator(derive_seed("test", 1)))
    other = torch.rand(5, generator=seeded_generator(derive_seed("test", 2)))
    assert torch.equal(first, second)
    assert not torch.equal(first, other)
