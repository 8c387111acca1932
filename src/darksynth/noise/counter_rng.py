"""Counter-based random numbers: per-pixel draws computed from (key, pixel index), not read from a stream.

The 8-bit kernels need Gaussians and random bytes per pixel. Drawing them from ``torch.Generator`` writes
frame-sized tensors to memory from one serial stream; computing them inside the fused per-pixel loop from a
hash of the pixel's index costs a few vector instructions and no memory traffic, and it runs on every core.

The hash works on 32-bit words only. A 64-bit generator (SplitMix64, for example) needs 64-bit multiplies,
which x86 has as a vector instruction only with AVX-512DQ: on AVX2-only processors (most laptops, AMD before
Zen 4) the compiler splits each into several 32-bit ones, and a fused kernel on SplitMix64 ran 3x slower there
(docs/performance.md). 32-bit multiplies have a vector form on every x86 processor with AVX2
(and SSE4.1), on ARM NEON and on GPUs.

The mixing function is Chris Wellons' ``lowbias32`` (xor-shift, multiply, xor-shift, multiply, xor-shift),
a bijection of 32-bit words with near-ideal avalanche. A draw's word is ``h(h(i + base) ^ stream)`` for the
value's index ``i``: ``base`` and ``stream``, the two 32-bit halves of the key, are drawn per frame from the
caller's ``torch.Generator``, so a seed still fixes everything, two frames draw the same numbers only if their
64-bit keys are equal, and a block of a frame gets exactly its own numbers when ``base`` is advanced by the
block's first index (:func:`advance`). One word gives a value's normal (24 bits) and byte (8 bits).

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
_UNIT_24 = 1.0 / (1 << 24)
_BELOW_ONE = 1.0 - _UNIT_24
_TRIANGULAR_SCALE = math.sqrt(6.0 / (65536.0**2 - 1.0))
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


def advance(key: torch.Tensor, offset: int) -> torch.Tensor:
    """The key whose draw for index ``i`` is the draw of ``key`` for index ``i + offset`` (wrapping at 2^32)."""
    step = torch.zeros_like(key)
    step[0] = _signed32(offset % (1 << 32))
    return key + step


def first_word(index: torch.Tensor, key: torch.Tensor) -> torch.Tensor:
    """The draw's first 32-bit word (int32) for each int32 ``index`` under ``key``."""
    return lowbias32(lowbias32(index + key[0]) ^ key[1])


# Giles' single-precision approximation of erfinv ("Approximating the erfinv function", GPU Computing Gems,
# 2011): a polynomial in w - 2.5 for w = -log(1 - x^2) < 5 and in sqrt(w) - 3 beyond, highest power first.
_ERFINV_CENTRAL = (
    2.81022636e-08, 3.43273939e-07, -3.5233877e-06, -4.39150654e-06, 0.00021858087,
    -0.00125372503, -0.00417768164, 0.246640727, 1.50140941,
)  # fmt: skip
_ERFINV_TAIL = (
    -0.000200214257, 0.000100950558, 0.00134934322, -0.00367342844, 0.00573950773,
    -0.0076224613, 0.00943887047, 1.00167406, 2.83297682,
)  # fmt: skip


def _polynomial(coefficients: tuple[float, ...], variable: torch.Tensor) -> torch.Tensor:
    result = torch.full_like(variable, coefficients[0])
    for coefficient in coefficients[1:]:
        result = result * variable + coefficient
    return result


def normal_from_word(word: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A standard normal float32 and a uniform byte (0..255, int32) from one word: the normal is the inverse
    normal CDF of the uniform u in its top 24 bits (offset by half a step, so 0 < u < 1), the byte its low 8.

    Why the inverse CDF and not Box-Muller: it needs 24 bits, not 48, so one word per value (two hashes instead
    of three), and a logarithm and a square root instead of a logarithm, a square root and a cosine, whose
    vector forms are several times slower on AVX2 than on AVX-512 (docs/performance.md). z = sqrt(2)
    erfinv(2u - 1), with 1 - (2u - 1)^2 written as 4 u (1 - u) so that the tails keep their precision; |z| is
    at most 5.5 (a 1e-7 tail mass, invisible in 8-bit output) and the approximation's relative error is below
    1e-6.
    """
    # The top value's u, (2^24 - 1/2) / 2^24, is not a float32: it rounds to 1, whose normal is infinite (one word
    # in 2^24, i.e. a 1080p frame's draws hit it about every third frame). It is held at the largest float32
    # below 1; every other word keeps its value.
    uniform = ((_shift_right(word, 8).to(torch.float32) + 0.5) * _UNIT_24).clamp_max(_BELOW_ONE)
    centred = 2.0 * uniform - 1.0
    w = -torch.log(4.0 * uniform * (1.0 - uniform))
    central = _polynomial(_ERFINV_CENTRAL, w - 2.5)
    tail = _polynomial(_ERFINV_TAIL, torch.sqrt(w) - 3.0)
    normal = math.sqrt(2.0) * torch.where(w < 5.0, central, tail) * centred
    return normal, byte_from_word(word)


def triangular_from_word(word: torch.Tensor) -> torch.Tensor:
    """A zero-mean, unit-variance float32 from one word: the sum of its two 16-bit halves, centred and scaled (a
    triangular law on [-sqrt 6, sqrt 6], excess kurtosis -0.6).

    For draws that are summed by thousands before anyone sees them, as the frequency coefficients of a noise
    field are by its inverse FFT: the field's covariance depends only on the draws' variance, and its values are
    normal by the central limit theorem (their excess kurtosis is -0.6 / the effective number of coefficients).
    Two integer-to-float conversions instead of :func:`normal_from_word`'s logarithm, square root and two
    polynomials: 4 against 21 ms for the 7 million draws of a 1080p frame's grid on AVX2 (3 against 16 on
    AVX-512)."""
    low = (word & 0xFFFF).to(torch.float32)
    high = _shift_right(word, 16).to(torch.float32)
    # Each half is uniform on 0..65535 (variance (65536^2 - 1) / 12); their sum's mean is 65535.
    return (low + high - 65535.0) * _TRIANGULAR_SCALE


def byte_from_word(word: torch.Tensor) -> torch.Tensor:
    """The uniform byte (0..255, int32) of a word: its low 8 bits, which the normal of the same word leaves
    unused, so a value's normal and byte are independent."""
    return word & 0xFF


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
