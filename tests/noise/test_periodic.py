"""Periodic column noise: three Fourier modes at column frequencies 0, W/4 and 3W/4."""

from __future__ import annotations

import math

import pytest
import torch

from darksynth.noise.periodic import periodic_basis, periodic_noise
from darksynth.noise.simulate import noise_sum
from darksynth.noise.values import NoiseValues

S = 0.02


def _values(periodic: tuple[float, float, float]) -> NoiseValues:
    return NoiseValues.from_values({"periodic": periodic}, dtype=torch.float32)


@pytest.mark.parametrize("width", [16, 64, 1000])
def test_spectrum_only_at_bins_zero_quarter_and_three_quarters(width: int) -> None:
    pattern = periodic_noise(
        (5, 3, 1, width), torch.tensor([0.01, 0.02, 0.03]), generator=torch.Generator().manual_seed(1)
    )
    spectrum = torch.fft.fft(pattern[..., 0, :].double(), dim=-1)
    energy = spectrum.abs().square()
    allowed = torch.zeros(width, dtype=torch.bool)
    allowed[[0, width // 4, 3 * width // 4]] = True
    assert energy[..., ~allowed].sum().item() < 1e-6 * energy.sum().item()
    # Each of the three bins carries energy in every frame and channel (no mode silently dropped).
    assert (energy[..., allowed] > 1e-12 * energy.sum()).all()


@pytest.mark.parametrize("mode", [0, 1, 2])
def test_each_mode_alone_has_mean_square_sigma_squared(mode: int) -> None:
    sigmas = [0.0, 0.0, 0.0]
    sigmas[mode] = S
    draws, width = 20000, 64
    pattern = periodic_noise((draws, 1, 1, width), torch.tensor(sigmas), generator=torch.Generator().manual_seed(2))
    per_draw = pattern.double().square().mean(dim=(-1, -2, -3))  # S^2 g^2 for one standard normal g per draw
    # g^2 has mean 1 and variance 2, so the mean over draws has standard error S^2 sqrt(2 / draws); 5 of them.
    assert abs(per_draw.mean().item() - S**2) < 5.0 * S**2 * math.sqrt(2.0 / draws)

    spectrum = torch.fft.fft(pattern[:, 0, 0].double(), dim=-1).abs().square().sum(dim=0)
    bins = {0: [0], 1: [width // 4, 3 * width // 4], 2: [width // 4, 3 * width // 4]}[mode]
    in_bins = spectrum[bins].sum().item()
    assert in_bins > (1.0 - 1e-9) * spectrum.sum().item()


def test_cosine_and_sine_modes_are_in_quadrature() -> None:
    # The cosine mode's coefficient at W/4 is real and the sine mode's imaginary, so the two are independent
    # phases of one frequency rather than the same wave twice.
    width = 32
    cosine = periodic_noise((200, 1, 1, width), torch.tensor([0.0, S, 0.0]), generator=torch.Generator().manual_seed(3))
    sine = periodic_noise((200, 1, 1, width), torch.tensor([0.0, 0.0, S]), generator=torch.Generator().manual_seed(3))
    cos_bin = torch.fft.fft(cosine[:, 0, 0].double(), dim=-1)[:, width // 4]
    sin_bin = torch.fft.fft(sine[:, 0, 0].double(), dim=-1)[:, width // 4]
    assert cos_bin.imag.abs().max().item() < 1e-9 * cos_bin.abs().max().item()
    assert sin_bin.real.abs().max().item() < 1e-9 * sin_bin.abs().max().item()


def test_basis_rows_have_unit_mean_square_and_are_orthogonal() -> None:
    basis = periodic_basis(64).double()
    gram = basis @ basis.T / 64
    torch.testing.assert_close(gram, torch.eye(3, dtype=torch.float64), rtol=0.0, atol=1e-6)


def test_amplitude_is_independent_of_width() -> None:
    sigmas = torch.tensor([0.01, 0.02, 0.03])
    total = math.sqrt(0.01**2 + 0.02**2 + 0.03**2)
    rms = {}
    for width in (64, 1024):
        pattern = periodic_noise((2000, 1, 1, width), sigmas, generator=torch.Generator().manual_seed(4))
        rms[width] = pattern.double().square().mean().sqrt().item()
    # The same seed draws the same coefficients at both widths, so a size-independent amplitude gives the
    # same RMS up to float rounding; the authors' 1/(H W) normalisation would differ by a factor of 16.
    assert math.isclose(rms[64], rms[1024], rel_tol=1e-5)
    # Per draw the mean square is sum s_i^2 g_i^2, variance 2 sum s_i^4; 5 standard errors over 2000 draws,
    # carried to the RMS by the delta method (divide by 2 * total).
    se_ms = math.sqrt(2.0 * (0.01**4 + 0.02**4 + 0.03**4) / 2000)
    assert abs(rms[64] - total) < 5.0 * se_ms / (2.0 * total)


def test_amplitude_is_independent_of_height_and_constant_down_columns() -> None:
    sigmas = (0.01, 0.02, 0.03)
    total = math.sqrt(sum(s * s for s in sigmas))
    rms = {}
    for height in (16, 512):
        signal = torch.zeros(200, 3, height, 32)
        noise = noise_sum(signal, _values(sigmas), generator=torch.Generator().manual_seed(5))
        assert torch.equal(noise, noise[..., :1, :].expand_as(noise))
        rms[height] = noise.double().square().mean().sqrt().item()
    assert math.isclose(rms[16], rms[512], rel_tol=1e-5)
    se_ms = math.sqrt(2.0 * sum(s**4 for s in sigmas) / 600)  # 200 frames x 3 channels independent draws
    assert abs(rms[16] - total) < 5.0 * se_ms / (2.0 * total)


def test_pattern_is_redrawn_every_frame_and_channel() -> None:
    pattern = periodic_noise((400, 2, 1, 16), torch.tensor([S, S, S]), generator=torch.Generator().manual_seed(6))
    dc = pattern[..., 0, 0].double()  # (400, 2): column 0 holds s1 g1 + sqrt(2) s2 g2
    pairs = torch.stack([dc[:-1, 0], dc[1:, 0]])
    # Consecutive frames and the two channels are uncorrelated; 5 standard errors 1 / sqrt(n).
    assert abs(torch.corrcoef(pairs)[0, 1].item()) < 5.0 / math.sqrt(399)
    assert abs(torch.corrcoef(dc.T)[0, 1].item()) < 5.0 / math.sqrt(400)


def test_per_clip_sigmas() -> None:
    sigmas = torch.tensor([[S, 0.0, 0.0], [0.0, 0.0, 2 * S]])
    pattern = periodic_noise((2, 3000, 1, 1, 8), sigmas, generator=torch.Generator().manual_seed(7))
    spectrum = torch.fft.fft(pattern[..., 0, :].double(), dim=-1).abs().square()
    assert spectrum[0][..., 1:].max().item() < 1e-12  # clip 0: only the DC mode
    assert spectrum[1][..., 0].max().item() < 1e-12  # clip 1: no DC mode
    for clip, expected in ((0, S**2), (1, 4 * S**2)):
        mean_square = pattern[clip].double().square().mean().item()
        assert abs(mean_square - expected) < 5.0 * expected * math.sqrt(2.0 / 3000)


def test_wrongly_shaped_sigmas_are_rejected() -> None:
    with pytest.raises(ValueError, match=r"\(2, 3\)"):
        periodic_noise((2, 1, 1, 1, 8), torch.zeros(3, 3))
