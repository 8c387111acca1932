"""Non-local means on 8-bit frames, the denoiser the blind spectral measurement reads its residual from.

OpenCV's implementation, run on the RGB values, split into bands of rows denoised side by side.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import torch

NLM_TEMPLATE, NLM_SEARCH = 5, 13
"""Non-local means patch and search window sides: OpenCV's defaults (7, 21) cost 2.5x the time for the same
statistics after the correction by re-synthesis."""

NLM_OVERLAP = 16
"""Rows of overlap between the bands a frame's denoising is split into: a pixel's result reads the pixels within
the search radius plus the patch radius (6 + 2 rows), so with 8 or more the bands give the whole frame's bits."""


_nlm_pool: ThreadPoolExecutor | None = None


def _forget_nlm_pool() -> None:
    # A forked child inherits the pool without its threads (work sent to it would wait for ever): it makes its own.
    global _nlm_pool
    _nlm_pool = None


os.register_at_fork(after_in_child=_forget_nlm_pool)


def _nlm_workers() -> int:
    return max(1, torch.get_num_threads())


def _nlm(image: np.ndarray, strength: float) -> np.ndarray:
    # On the RGB values themselves: the colour variant compares patches in 8-bit Lab, whose steep dark end spreads
    # the noise of dark pixels, so that a strength that denoises mid-grey returns the noise of a pixel at 5 levels
    # (a residual of 0.5 levels where the noise was 4: the fit by re-synthesis then read dark references far too
    # weak). Here a strength equal to the noise's std removes about 95 % of it at every intensity.
    result: np.ndarray = cv2.fastNlMeansDenoising(image, None, strength, NLM_TEMPLATE, NLM_SEARCH)
    return result


def _to_uint8(frame: torch.Tensor) -> np.ndarray:
    array: np.ndarray = (frame.clamp(0.0, 1.0) * 255.0).round().to(torch.uint8).permute(1, 2, 0).cpu().numpy()
    return np.ascontiguousarray(array)


def nlm_denoise(frames: torch.Tensor, strength: float) -> torch.Tensor:
    """Non-local means (OpenCV) of each frame of (T, 3, H, W) in [0, 1] on 8-bit levels, patches compared on the
    three RGB channels together, strength ``h`` in 8-bit levels; float32 on the input's device.

    OpenCV's non-local means runs on one core: each frame is cut into bands of rows (one per torch thread,
    overlapping by :data:`NLM_OVERLAP`) denoised side by side in threads (OpenCV releases the GIL), which gives the
    whole frame's result exactly (tested) in about half the time on two cores."""
    global _nlm_pool
    workers = _nlm_workers()
    if workers > 1 and _nlm_pool is None:
        _nlm_pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="darksynth-nlm")
    images = [_to_uint8(frame) for frame in frames]
    height = images[0].shape[0]
    band = -(-height // workers)
    if workers == 1 or band <= 2 * NLM_OVERLAP or _nlm_pool is None:
        results = [_nlm(image, float(strength)) for image in images]
    else:
        # Every band of every frame is queued at once, so neither thread waits for the other's last band of a frame.
        starts = range(0, height, band)
        jobs = [
            [
                _nlm_pool.submit(
                    _nlm,
                    np.ascontiguousarray(image[max(0, top - NLM_OVERLAP) : min(height, top + band + NLM_OVERLAP)]),
                    float(strength),
                )
                for top in starts
            ]
            for image in images
        ]
        results = [
            np.concatenate(
                [
                    job.result()[top - max(0, top - NLM_OVERLAP) :][: min(band, height - top)]
                    for top, job in zip(starts, frame_jobs, strict=True)
                ]
            )
            for frame_jobs in jobs
        ]
    out = [torch.from_numpy(result).permute(2, 0, 1).to(torch.float32) / 255.0 for result in results]
    return torch.stack(out).to(frames.device)
