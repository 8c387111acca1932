"""The one derivation of seeds from other seeds and names, and generators seeded with them.

A derived seed is a hash, so that nearby inputs (run seed 7 and 8, worker 0 and 1, a file and the next) give
unrelated generator streams, and so that a seed depends only on what names it, never on the order in which
things are processed. Every seed darksynth derives (apply's per-file seeds, the training processes' data
streams, the transforms' per-sample generators, the evaluation's draws) comes from :func:`derive_seed`; the
callers keep their own first part (``"darksynth"``, ``"darksynth-transform"``), which fixes their seeds for good:
manifests record them and resumed runs rely on them.

Imports nothing from darksynth, so that any module can use it.
"""

from __future__ import annotations

import hashlib

import torch

SEED_BITS = 63
"""Derived seeds lie in [0, 2**63): non-negative in a signed 64-bit integer (numpy, JSON readers, torch)."""


def derive_seed(*parts: int | str) -> int:
    """A 63-bit seed from its parts: the first 8 bytes (little-endian) of the SHA-256 of the parts written as
    text and joined by ``:``, with the top bit cleared.

    ``derive_seed("darksynth", 3, "a/b.png")`` hashes ``"darksynth:3:a/b.png"``. The text is not escaped, so
    parts that may contain ``:`` (file keys) belong last, where they cannot be mistaken for a separator.

    Args:
        parts: what names the seed, most general first (a namespace, a run seed, then a key or an index).

    Returns:
        An integer in [0, 2**63).

    Raises:
        ValueError: no parts.
    """
    if not parts:
        raise ValueError("derive_seed needs at least one part")
    text = ":".join(str(part) for part in parts)
    digest = hashlib.sha256(text.encode()).digest()
    return int.from_bytes(digest[:8], "little") & ((1 << SEED_BITS) - 1)


def seeded_generator(seed: int, device: str | torch.device = "cpu") -> torch.Generator:
    """A new torch generator on ``device`` seeded with ``seed`` (a run seed or a :func:`derive_seed`)."""
    return torch.Generator(device).manual_seed(seed)
