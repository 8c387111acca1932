"""Thread pools made before a fork: the forked child (a DataLoader worker running the transforms) must make its own,
not wait for ever on the parent's, whose threads it does not have."""

from __future__ import annotations

import multiprocessing
import sys

import numpy as np
import pytest
import torch

from darksynth.estimation.noise import nonlocal_means
from darksynth.light.linear_light import LEVEL_OF_LINEAR16, levels_of_linear16


def _in_the_child(results: multiprocessing.Queue) -> None:  # type: ignore[type-arg]
    # Only numpy and the pools here: torch's and OpenCV's own thread pools have their own rules after a fork
    # (a DataLoader worker runs torch on one thread).
    linear = np.arange(200 * 30 * 3, dtype=np.uint16).reshape(200, 30, 3) * 7
    same = bool(np.array_equal(levels_of_linear16(linear), LEVEL_OF_LINEAR16[linear]))
    results.put((same, nonlocal_means._nlm_pool is None))


@pytest.mark.skipif(sys.platform != "linux", reason="fork is the default start method on Linux only")
def test_a_forked_child_makes_its_own_thread_pools() -> None:
    torch_threads = torch.get_num_threads()
    torch.set_num_threads(2)  # so that non-local means makes its pool
    try:
        # The parent makes and uses both pools first.
        levels_of_linear16(np.zeros((128, 8, 3), np.uint16))
        nonlocal_means.nlm_denoise(torch.rand(1, 3, 96, 64), 9.0)
        assert nonlocal_means._nlm_pool is not None
    finally:
        torch.set_num_threads(torch_threads)
    context = multiprocessing.get_context("fork")
    results = context.Queue()
    child = context.Process(target=_in_the_child, args=(results,))
    child.start()
    child.join(timeout=30)
    hung = child.is_alive()
    if hung:
        child.kill()
    assert not hung, "the forked child waited on its parent's thread pool"
    assert child.exitcode == 0
    assert results.get(timeout=5) == (True, True)
