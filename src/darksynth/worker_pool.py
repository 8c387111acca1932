"""Worker processes of a folder run that never outlive the run (``apply`` and ``convert`` on a folder)."""

from __future__ import annotations

import os
import threading
import time

import torch

PARENT_POLL_SECONDS = 0.5
"""How often a pool worker checks that the process that started it is alive."""


def init_worker(threads: int) -> None:
    """What a pool worker runs first: its share of the cores, and a watch on its parent."""
    torch.set_num_threads(threads)
    # A pool worker outlives a parent killed with SIGKILL: the executor's shutdown never runs, and a worker in the
    # middle of a frame does not read the closed queue until its task ends (minutes for a long video). A thread that
    # sees the parent gone (the worker re-parented) ends the worker; its half-written file is a hidden temporary,
    # removed by the next run. PR_SET_PDEATHSIG would be immediate but fires when the *thread* that started the
    # worker ends, which for an executor need not be the main one.
    threading.Thread(target=exit_with_parent, args=(os.getppid(),), name="exit-with-parent", daemon=True).start()


def exit_with_parent(parent: int) -> None:
    """End this process once ``parent`` is gone (this process is re-parented)."""
    while True:
        time.sleep(PARENT_POLL_SECONDS)
        if os.getppid() != parent:
            os._exit(1)
