"""A video codec's skipped blocks: cells of a still scene copied bit for bit from the previous finished frame.

A codec codes a frame as changes from the one before it and copies the blocks it finds unchanged (H.264's skipped
macroblocks, HEVC's skip mode). On a still night scene the change is the noise, which the codec drops at a low bit
rate: the frame's noise is the previous frame's, exactly, in most still blocks. An AR(1) coefficient cannot make
this (its frames are rounded afresh), so the shared codec clip clip132, which repeats 82% of its still flat cells,
read lag-1 1.00 in the real and 0.68 from its profile (issue 39).

The table's ``codec_repeat`` p is the share of still cells repeated: after a clip's frame is finished (noise,
clipping, rounding, compression), each :data:`CELL`-px cell whose clean input did not change since the previous
frame (:data:`STILL_CHANGE`) takes the previous finished frame's values with probability p, drawn per cell and
frame. A cell where the scene moves is always coded afresh. A single image has no previous frame: nothing repeats.
``estimate`` reads p on a codec clip (``estimation.noise.persistence_fit``: the share of still flat cells repeated
bit-identically), and sets it only where a codec, not chance, repeats them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
import torch.nn.functional as F

from darksynth.noise.component_types import ALL_PATHS, NoiseComponent, Parameter

CELL = 8
"""Side of the cells a codec copies: the smallest block H.264 and HEVC skip or copy (the estimate's ``SKIP_CELL``)."""

STILL_CHANGE = 1.0 / 255.0
"""A cell is still where no clean value in it changed by more than this (one 8-bit level of the [0, 1] scale, at
any input depth): a decoded clean video's still regions change by a level or less from frame to frame, and after
darkening that is under half a level, which a codec does not see under the noise."""

HELD_KEY = "codec_repeat"
"""Where a stream keeps the previous clean and finished frame in its ``held`` state."""


def still_cells(previous_clean: torch.Tensor, clean: torch.Tensor) -> torch.Tensor:
    """(..., ceil(H / CELL), ceil(W / CELL)) bool: the cells of frames (..., C, H, W) on the [0, 1] scale whose every
    value changed by at most :data:`STILL_CHANGE` (channels together; a partial cell at the edge counts)."""
    change = (clean.to(torch.float32) - previous_clean.to(torch.float32)).abs().amax(dim=-3)
    flat = change.reshape(-1, 1, *change.shape[-2:])
    moved = F.max_pool2d(flat, CELL, ceil_mode=True) > STILL_CHANGE
    return (~moved).reshape(*change.shape[:-2], *moved.shape[-2:])


def repeat_cells(
    previous: torch.Tensor, frame: torch.Tensor, still: torch.Tensor, share: float, generator: torch.Generator | None
) -> torch.Tensor:
    """``frame`` (C, H, W) with each ``still`` cell (from :func:`still_cells`) replaced, with probability ``share``,
    by the same cell of ``previous`` (the previous finished frame, same shape and dtype)."""
    if share <= 0.0:
        return frame
    # Drawn on the generator's device (a CUDA generator cannot fill a CPU tensor), used where the cells are.
    device = generator.device if generator is not None else still.device
    draws = torch.rand(still.shape, generator=generator, device=device).to(still.device)
    copied = still & (draws < share)
    mask = copied.repeat_interleave(CELL, dim=-2).repeat_interleave(CELL, dim=-1)
    mask = mask[..., : frame.shape[-2], : frame.shape[-1]]
    return torch.where(mask, previous, frame)


def repeat_in_stream(
    clean: torch.Tensor, frame: torch.Tensor, share: float, generator: torch.Generator | None, held: dict[str, Any]
) -> torch.Tensor:
    """The finished ``frame`` (C, H, W) of a stream with the codec's repeats from the previous frame, which ``held``
    keeps (with its ``clean`` input, on the [0, 1] scale) for the next call; the first frame passes unchanged."""
    previous = held.get(HELD_KEY)
    if previous is not None and previous[0].shape == clean.shape:
        frame = repeat_cells(previous[1], frame, still_cells(previous[0], clean), share, generator)
    held[HELD_KEY] = (clean, frame)
    return frame


def _after_frame(
    clean: torch.Tensor, finished: torch.Tensor, values: Any, generator: torch.Generator | None, held: dict[str, Any]
) -> torch.Tensor:
    return repeat_in_stream(clean, finished, values.scalar("codec_repeat"), generator, held)


def _draw_nothing(
    noisy: torch.Tensor, values: Mapping[str, torch.Tensor], generator: torch.Generator | None
) -> torch.Tensor:
    # The repeat needs the clean frames, which the output stages do not see: it runs after them, frame after frame
    # (its after_frame, darksynth.noise.simulate.finish_frame); the composer passes the image unchanged.
    return noisy


CODEC_REPEAT = NoiseComponent(
    name="codec_repeat",
    parameters=(
        Parameter(
            "codec_repeat",
            1,
            "share of the still 8-px cells a video codec copies from the previous frame (0: every frame coded afresh)",
            1.0,
            (0.0, 0.9),
            noise_model="spectral",
            since_version=6,
            # Every route of a clip runs it after its frame is finished (its after_frame).
            fast_paths=ALL_PATHS,
            training_off_probability=0.5,
        ),
    ),
    structure="output",
    draw=_draw_nothing,
    after_frame=_after_frame,
    variance=None,
    reference="darksynth, issue 39: a codec's skipped blocks (ITU-T H.264 P_Skip); docs/spectral-noise.md",
)
