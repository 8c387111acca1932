"""Counter-based random numbers: per-pixel draws computed from (key, pixel index), not read from a stream.

The 8-bit kernels need Gaussians and random bytes per pixel. Drawing them from ``torch.Generator`` writes
frame-sized tensors to memory from one serial stream; computing them inside the fused per-pixel loop from a
hash of the pixel's index costs a few vector instructions and no memory traffic, and it runs on every core.

The hash works on 32-bit words only. A 64-bit generator (SplitMix64, which this module used before) needs
64-bit multiplies, which x86 has as a vector instruction only with AVX-512DQ: on AVX2-only processors
(most laptops, AMD before Zen 4) the compiler splits each into several 32-bit ones, and the fused kernel ran
3x slower there (docs/performance.md). 32-bit multiplies have a vector form on every x86 processor with AVX2
(and SSE4.1), on ARM NEON and on GPUs.

The mixing function is Chris Wellons' ``lowbias32`` (xor-shift, multiply, xor-shift, multiply, xor-shift),
a bijection of 32-bit words with near-ideal avalanche. A draw's word is ``h(h(i + base) ^ stream)`` for the
value's index ``i``: ``base`` and ``stream``, the two 32-bit halves of the key, are drawn per frame from the
caller's ``torch.Generator``, so a seed still fixes everything, two frames draw the same numbers only if their
64-bit keys are equal, and a block of a frame gets exactly its own numbers when ``base`` is advanced by the
block's first index (:func:`advance`). A normal needs 48 bits: its second word is ``h(first + golden)``.

Everything is written with int32 tensor operations (two's-complement wrap-around, logical shifts by masking),
so it gives the same bits eagerly, under ``torch.compile`` and on any device.
"""

from __future__ import annotations

import math

import torch


def _signed32(value: int) -> int:
    return value - (1 << 32) if value >= (1 << 31) else value


_MIX1 = _signed32(0x7FEB352D)
_MIX2 = _signed32(0x846CA68B)
_GOLDEN = _signed32(0x9E3779B9)
_UNIT_24 = 1.0 / (1 << 24)
KEY_WORDS = 2
"""A key is (base, stream), two int32 words."""


def _shift_right(bits: torch.Tensor, amount: int) -> torch.Tensor:
    # torch's >> on int32 is arithmetic; masking off the sign copies makes it the logical shift of uint32.
    return (bits >> amount) & ((1 << (32 - amount)) - 1)


def lowbias32(bits: torch.Tensor) -> torch.Tensor:
    """Wellons' lowbias32 mixing function of int32 words (read as uint32): a bijection with good avalanche."""
    bits = (bits ^ _shift_right(bits, 16)) * _MIX1
    bits = (bits ^ _shift_right(bits, 15)) * _MIX2
    return bits ^ _shift_right(bits, 16)


def random_key(generator: torch.Generator | None = None) -> torch.Tensor:
    """A (2,) int32 key (base, stream) drawn from the generator, on its device, for one frame's draws."""
    device = generator.device if generator is not None else None
    return torch.randint(-(1 << 31), 1 << 31, (KEY_WORDS,), generator=generator, dtype=torch.int32, device=device)


def advance(key: torch.Tensor, offset: int | torch.Tensor) -> torch.Tensor:
    """The key whose draw for index ``i`` is the draw of ``key`` for index ``i + offset`` (wrapping at 2^32)."""
    step = torch.zeros_like(key)
    step[0] = offset if isinstance(offset, int) and offset < (1 << 31) else _signed32(int(offset) % (1 << 32))
    return key + step


def first_word(index: torch.Tensor, key: torch.Tensor) -> torch.Tensor:
    """The draw's first 32-bit word (int32) for each int32 ``index`` under ``key``."""
    return lowbias32(lowbias32(index + key[0]) ^ key[1])


def normal_from_word(word: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A standard normal float32 (Box-Muller, cosine branch) and a uniform byte (0..255, int32) from a first
    word: the radius uniform is its top 24 bits, the angle uniform the top 24 bits of the second word, the byte
    the second word's low 8 bits. The radius uniform is offset by half a step so that its logarithm is finite,
    which bounds the normal at |z| <= 5.9: a 1e-9 tail mass, far below anything visible in 8-bit output."""
    second = lowbias32(word + _GOLDEN)
    radius_uniform = (_shift_right(word, 8).to(torch.float32) + 0.5) * _UNIT_24
    angle_uniform = _shift_right(second, 8).to(torch.float32) * _UNIT_24
    normal = torch.sqrt(-2.0 * torch.log(radius_uniform)) * torch.cos((2.0 * math.pi) * angle_uniform)
    return normal, second & 0xFF


def flat_index(shape: torch.Size | tuple[int, ...], device: torch.device) -> torch.Tensor:
    """The int32 flat (C-order) index of every element of ``shape``."""
    return torch.arange(math.prod(shape), dtype=torch.int32, device=device).view(shape)


def normal_and_byte(shape: torch.Size | tuple[int, ...], key: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A standard normal float32 and a uniform byte (0..255, as int32) per element of ``shape``.

    Args:
        shape: shape of the draws; element ``i`` in C order is index ``i``.
        key: (2,) int32 tensor on the device of the result (see :func:`random_key`).

    Returns:
        (normal, byte), both shaped ``shape``.
    """
    return normal_from_word(first_word(flat_index(shape, key.device), key))
