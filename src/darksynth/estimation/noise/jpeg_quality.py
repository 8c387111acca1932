"""Which of the JPEG strengths the fit can simulate a reference was itself encoded at, read off its luma's DCT.

A JPEG stores each 8x8 block's DCT coefficients as whole multiples of its quantization table's steps; decoding keeps
them there up to the rounding of the pixels (a fraction of a level). A frame decoded from a JPEG of table T, cut on
the encoder's block grid, therefore has its luma's coefficients on T's lattice, whatever the noise before encoding;
noise that was never encoded with T puts them anywhere. The fit's own choice between the strengths, from how well
each re-synthesis matches the residual's statistics, picked the wrong one of the three candidates on 21 of 40
held-out JPEG round-trip cases (seeds 3000-3099); with the true one the cases' median error went 0.159 -> 0.139.

Per candidate (Pillow's luminance table at :func:`~darksynth.noise.compression.jpeg_quality`, the table the
simulation encodes with), on each of the 64 grid phases: of the coefficients whose step is at least
:data:`MIN_STEP` and that are at least half a step from zero (zero lies on every lattice), but for the block
means (DC: a flat dark region's blocks all have about one mean, which a lattice holds or misses by chance: a real
clip read quality 60 off its DC alone, 1154 values near 27, none of its AC), the share within
:data:`LATTICE_TOLERANCE` of the lattice, as an excess over chance (1: all on it, 0: as uniform values fall). The
best phase's excess is the candidate's score; a candidate is read when it scores at least :data:`READ_SCORE` on at
least :data:`MIN_COEFFICIENTS` coefficients. A camera's own tables, a resized or re-encoded JPEG, or a raw
reference show no candidate: the fit chooses as before.
"""

from __future__ import annotations

import functools
import io
import math

import torch
from PIL import Image
from PIL.JpegImagePlugin import JpegImageFile

from darksynth.noise.compression import jpeg_quality

MIN_STEP = 4
"""Coefficients whose step is under this many levels are not read: within the tolerance of a lattice that fine,
chance alone puts half of any values."""

LATTICE_TOLERANCE = 1.0
"""How far (DCT units, 8-bit levels) a coefficient may lie from the lattice and count as on it: decoding rounds each
pixel and converts colour, which moves an orthonormal coefficient by about 0.3-0.5."""

READ_SCORE = 0.75
"""A candidate is read when its share on the lattice rises at least this far from chance toward all. Round trips
0-99, 3000-3099 and 5000-5099, on 200 coefficients or more: no JPEG at most 0.10, quality 80 0.91-0.99, quality 60
0.81-0.99. Other qualities' steps fall on a candidate's at some frequencies: qualities 30-95 scored at most 0.64
(30 on quality 60's table, 40 on quality 80's), and read nothing..."""

READ_MARGIN = 0.1
"""...and at least this much above every other candidate (quality 60's lattice holds about half of quality 80's
points: a quality-60 frame scores 0.43-0.58 on quality 80's)."""

MIN_COEFFICIENTS = 200
"""Fewer readable coefficients than this (a dark frame whose blocks quantized to zero) read nothing."""

LUMA_WEIGHTS = (0.299, 0.587, 0.114)
"""JPEG's (JFIF) luma of R, G and B."""

READ_SIDE = 512
"""The phases are read on at most this many pixels a side from the frame's top left: enough blocks for every
phase, a small cost on a large frame."""


@functools.cache
def luminance_table(quality: int) -> torch.Tensor:
    """The 8x8 luminance quantization table (natural order, float64) Pillow's encoder writes at ``quality``."""
    buffer = io.BytesIO()
    Image.new("RGB", (8, 8)).save(buffer, format="JPEG", quality=quality)
    buffer.seek(0)
    with Image.open(buffer) as image:
        assert isinstance(image, JpegImageFile)
        table = image.quantization[0]
    return torch.tensor(list(table), dtype=torch.float64).reshape(8, 8)


def _dct_matrix() -> torch.Tensor:
    index = torch.arange(8, dtype=torch.float64)
    matrix = torch.cos(math.pi * (2 * index[None, :] + 1) * index[:, None] / 16) * math.sqrt(2 / 8)
    matrix[0] /= math.sqrt(2)
    return matrix


DCT_8 = _dct_matrix()
"""The orthonormal 8-point DCT-II (JPEG's transform, up to its integer rounding), rows the frequencies."""

AC_COEFFICIENTS = torch.ones(8, 8, dtype=torch.bool)
AC_COEFFICIENTS[0, 0] = False
"""The coefficients a lattice is read on: all but the block mean (a flat dark region's block means all sit near one
value, which a lattice holds or misses by chance)."""


def _block_coefficients(luma: torch.Tensor, clipped: torch.Tensor, top: int, left: int) -> torch.Tensor:
    """Orthonormal DCT (n, 8, 8) of the 8x8 blocks of ``luma`` (H, W) cut from (top, left), but for the blocks with
    a ``clipped`` pixel (decoding clips a channel at 0 or 255 after the coefficients, which moves them off the
    lattice: most of a dark reference's blocks touch 0)."""
    rows, cols = (luma.shape[0] - top) // 8, (luma.shape[1] - left) // 8

    def blocks(plane: torch.Tensor) -> torch.Tensor:
        cut = plane[top : top + 8 * rows, left : left + 8 * cols]
        return cut.reshape(rows, 8, cols, 8).permute(0, 2, 1, 3).reshape(-1, 8, 8)

    kept = blocks(luma)[~blocks(clipped).flatten(1).any(1)]
    return DCT_8 @ kept @ DCT_8.T


def lattice_score(coefficients: torch.Tensor, table: torch.Tensor) -> tuple[float, int]:
    """How far the share of ``coefficients`` (n, 8, 8) on ``table``'s lattice rises from chance toward all of them
    (see the module), and how many coefficients it read."""
    steps = table.expand_as(coefficients)
    readable = AC_COEFFICIENTS & (steps >= MIN_STEP) & (coefficients.abs() >= steps / 2)
    count = int(readable.sum())
    if count == 0:
        return 0.0, 0
    values, step = coefficients[readable], steps[readable]
    distance = (values - step * torch.round(values / step)).abs()
    on = float((distance <= LATTICE_TOLERANCE).double().mean())
    chance = float((2 * LATTICE_TOLERANCE / step).clamp(max=1.0).mean())
    return (on - chance) / max(1.0 - chance, 1e-9), count


def compression_scores(frame: torch.Tensor, candidates: tuple[float, ...]) -> dict[float, tuple[float, int]]:
    """Each JPEG candidate's (score, readable coefficients) on ``frame`` (3, H, W) in [0, 1], at its best phase;
    strength 0 (no JPEG) is not read."""
    weights = torch.tensor(LUMA_WEIGHTS, dtype=torch.float64).to(frame.device)
    levels = (frame[:, :READ_SIDE, :READ_SIDE].to(torch.float64) * 255.0).round()
    luma = torch.einsum("c,chw->hw", weights, levels).cpu()
    clipped = ((levels <= 0) | (levels >= 255)).any(0).cpu()
    if min(luma.shape) < 16:
        return {}
    phases = [_block_coefficients(luma, clipped, top, left) for top in range(8) for left in range(8)]
    scores: dict[float, tuple[float, int]] = {}
    for compression in candidates:
        quality = jpeg_quality(compression)
        if quality is not None:
            table = luminance_table(quality)
            scores[compression] = max((lattice_score(c, table) for c in phases), key=lambda read: read[0])
    return scores


def read_compression(frame: torch.Tensor, candidates: tuple[float, ...]) -> tuple[float | None, dict[str, object]]:
    """The candidate JPEG strength ``frame`` (3, H, W) was encoded at, or None where none is read; with the scores
    for ``meta``."""
    scores = compression_scores(frame, candidates)
    ranked = sorted(scores, key=lambda c: scores[c][0], reverse=True)
    chosen = ranked[0] if ranked else None
    if chosen is not None:
        score, count = scores[chosen]
        runner_up = scores[ranked[1]][0] if len(ranked) > 1 else -math.inf
        if score < READ_SCORE or count < MIN_COEFFICIENTS or score - runner_up < READ_MARGIN:
            chosen = None
    note = {str(c): {"score": round(score, 3), "coefficients": count} for c, (score, count) in scores.items()}
    return chosen, {"lattice_scores": note, "lattice_read": chosen}
