"""The cross spectra of moving block pairs, aligned: what :mod:`darksynth.estimation.light.motion` reads a shutter from.

A block of frame t and the block of frame t+1 the flow takes it to give a cross spectrum ``F_t conj(F_t+1)`` (N,
B, B//2+1), blocks of B px: the scene's power, times the blur's transfer, with the phase of whatever shift the flow
missed; plus, where noise persists from frame to frame, that noise at the blocks' offset. These functions find the
missed shift and take the persistent noise out, so that the real part left is the scene's.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


def frequencies(size: int) -> tuple[np.ndarray, np.ndarray]:
    """The (ky, kx) frequencies (cycles/px) of a ``size``-px block's real FFT, shaped to broadcast against it."""
    return np.fft.fftfreq(size)[:, None], np.fft.rfftfreq(size)[None, :]


def ring_membership(ring: np.ndarray, rings: int, dtype: npt.DTypeLike = np.float64) -> np.ndarray:
    """One-hot (n, rings) of each frequency's ring index ``ring`` (n,): ``values @ membership`` sums per ring."""
    membership = np.zeros((ring.size, rings), dtype)
    membership[np.arange(ring.size), ring] = 1.0
    return membership


ALONG_SEARCH = np.linspace(-1.5, 1.5, 13)
"""Shifts (px along the motion) tried first for what the flow missed, a quarter of a pixel apart (then refined to
0.05 px around each block's best): noise that stays in place drew DIS up to a third of the way towards no motion at
2-3 px/frame."""

ALONG_REFINE = np.linspace(-0.25, 0.25, 11)
"""The refinement around each block's best coarse shift: 0.05 px apart."""


def align_along(product: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """The shift (N, 2) (dy, dx) along each block's motion that the flow missed, with the noise that stays in place
    in the model: the cross spectrum over rings 2-16 is fitted as ``X(k) exp(2 pi i k.e)`` (the scene moved by the
    missed ``e``; X real, any value at each frequency, so any blur) plus ``P exp(-2 pi i k.D)`` (the pattern at the
    blocks' offset ``D``, one P >= 0 per ring); the ``e`` of least residual wins. A model of the scene alone would
    take the pattern's pull for the scene's."""
    ky, kx = frequencies(product.shape[-2])
    radius = np.hypot(ky, kx) * product.shape[-2]
    use = ((radius >= 2) & (radius <= 16) & (ky != 0) & (kx != 0)).ravel()
    ring = np.broadcast_to(np.rint(radius).astype(int), product.shape[1:]).ravel()[use]
    membership = ring_membership(ring, int(ring.max()) + 1)
    membership = membership[:, membership.sum(axis=0) > 0]
    ky_used, kx_used = (k.ravel()[use] for k in np.broadcast_arrays(ky, kx))
    values = product.reshape(product.shape[0], -1)[:, use]
    direction = motion / np.maximum(np.hypot(motion[:, 0], motion[:, 1]), 1e-9)[:, None]
    pattern = np.exp(-2j * np.pi * (motion[:, 0, None] * ky_used + motion[:, 1, None] * kx_used))
    turn = 2 * np.pi * (direction[:, 0, None] * ky_used + direction[:, 1, None] * kx_used)

    def residual(along: np.ndarray) -> np.ndarray:
        """What the model leaves with the scene moved by ``along`` (N,) px, per block."""
        moved = np.exp(1j * along[:, None] * turn)
        # Turned by the scene's phase, the scene is real whatever its blur: what is left across is the pattern's
        # share, P sin(angle between the two), fitted with one P per ring; the residual is what neither explains.
        across = np.imag(values * np.conj(moved))
        pattern_across = np.imag(np.conj(moved) * pattern)
        covariance = (across * pattern_across) @ membership
        kept = np.maximum(covariance / np.maximum((pattern_across**2) @ membership, 1e-12), 0.0)
        left: np.ndarray = ((across**2) @ membership - kept * covariance).sum(axis=1)
        return left

    count = values.shape[0]
    coarse = np.stack([residual(np.full(count, along)) for along in ALONG_SEARCH])
    start = ALONG_SEARCH[np.argmin(coarse, axis=0)]
    fine = np.stack([residual(start + step) for step in ALONG_REFINE])
    best = start + ALONG_REFINE[np.argmin(fine, axis=0)]
    shift: np.ndarray = best[:, None] * direction
    return shift


def phase_ramp(shift: np.ndarray, size: int) -> np.ndarray:
    """exp(-2 pi i k.shift) for each block's shift (N, 2) (dy, dx), blocks of ``size`` px: multiplied into a cross
    spectrum, it moves the second block by ``shift`` against the first."""
    ky, kx = frequencies(size)
    ramp: np.ndarray = np.exp(-2j * np.pi * (ky[None] * shift[:, 0, None, None] + kx[None] * shift[:, 1, None, None]))
    return ramp


def without_persistent_noise(product: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Cross spectra (N, B, B//2+1), the second block moved by ``shift`` (N, 2) against the first, less the
    noise that stays in place from frame to frame.

    Noise that persists between frames (a phone's temporal noise reduction, a codec carrying its prediction over,
    fixed pattern) does not cancel in the cross spectrum: it stays where it is while the blocks follow the scene,
    so it adds ``P(k) exp(-2 pi i k.D)`` (D the block's shift) to the scene's real ``X(k)``. Its real part,
    ``P cos(2 pi k.D)``, falls along the motion as a blur's transfer does: at 3 px/frame a pattern carrying half
    the noise power read a shutter of 0.5 as 1.5. Its imaginary part ``-P sin(2 pi k.D)`` shows it
    alone (once the scene is aligned), so ``P`` is fitted per block and frequency ring on the imaginary part and
    the term removed. Where the ring's frequencies barely turn the phase (slow motion, low rings) the fit is shrunk
    towards 0 (by a hundredth of the ring's count): there the pattern is a near-constant offset of the ring, which
    the fit's shape test hardly sees."""
    ky, kx = frequencies(product.shape[-2])
    phase = 2 * np.pi * (ky[None] * shift[:, 0, None, None] + kx[None] * shift[:, 1, None, None])
    sine, cosine = np.sin(phase), np.cos(phase)  # exp(-i phase) = cosine - i sine
    ring = np.rint(np.hypot(ky, kx) * product.shape[-2]).astype(int)
    ring = np.broadcast_to(ring, product.shape[1:]).ravel()
    count = product.shape[0]
    flat_sine = sine.reshape(count, -1)
    membership = ring_membership(ring, int(ring.max()) + 1)
    members = membership.sum(axis=0)
    along_imaginary = (-product.imag.reshape(count, -1) * flat_sine) @ membership
    turning = (flat_sine**2) @ membership
    persistent = along_imaginary / (turning + 0.01 * members[None])
    persistent_at = (persistent @ membership.T).reshape(product.shape)
    scene: np.ndarray = product - persistent_at * (cosine - 1j * sine)
    return scene


def align_phase(product: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undo the shift the flow missed: fit a phase ramp to the low frequencies of each cross spectrum.

    Returns the aligned cross spectra and the shift (N, 2) (dy, dx) px added to the flow's.

    A flow error of e px leaves a phase 2 pi k.e in the cross spectrum, and its real part shrinks by cos(2 pi k.e)
    at high frequencies: along the motion that would read as extra blur. The blur itself leaves no phase (both
    frames carry the same box, |H|^2 is real and non-negative), so the ramp is the error alone.
    """
    size = product.shape[-2]
    ky, kx = frequencies(size)
    radius = np.hypot(ky, kx)
    # Low frequencies: high signal to noise, and no phase wrap for errors up to about a pixel.
    low = (radius >= 1.5 / size) & (radius <= 8.5 / size)
    ky_low, kx_low = (k[low] for k in np.broadcast_arrays(ky, kx))
    total = np.zeros((product.shape[0], 2))
    for _ in range(2):
        values = product[:, low]
        weight = np.abs(values)
        angle = np.angle(values) / (2 * np.pi)
        # Weighted least squares for the shift (ey, ex) in angle = ky ey + kx ex.
        a11 = (weight * ky_low**2).sum(axis=1)
        a12 = (weight * ky_low * kx_low).sum(axis=1)
        a22 = (weight * kx_low**2).sum(axis=1)
        b1 = (weight * ky_low * angle).sum(axis=1)
        b2 = (weight * kx_low * angle).sum(axis=1)
        determinant = np.maximum(a11 * a22 - a12**2, 1e-30)
        error_y = np.clip((a22 * b1 - a12 * b2) / determinant, -1.0, 1.0)
        error_x = np.clip((a11 * b2 - a12 * b1) / determinant, -1.0, 1.0)
        error = np.stack([error_y, error_x], axis=1)
        product = product * phase_ramp(error, size)
        total += error
    return product, total
