"""The fused 8-bit path: agreement with the float composer, its statistics, and its torch.compile build."""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import pytest
import scipy.stats
import torch

import darksynth
from darksynth.light.darkening import Darkening
from darksynth.noise.components import model_parameters
from darksynth.noise.counter_rng import advance, random_key
from darksynth.noise.fused_8bit import compiled_pixel_kernel, pixel_kernel_8bit
from darksynth.noise.values import NoiseValues
from darksynth.profile import default_profile_path, load_profile
from darksynth.recipe import ClipParameters, draw_clip_parameters
from darksynth.synthesize import ClipSynthesizer


def _per_level_moments(clean: torch.Tensor, noisy: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean and variance of the output at each of the 256 clean input levels."""
    index = clean.flatten().long()
    values = noisy.flatten().double()
    count = torch.bincount(index, minlength=256).double()
    mean = torch.bincount(index, values, minlength=256) / count
    second = torch.bincount(index, values.square(), minlength=256) / count
    return mean, second - mean.square()


def test_uint8_and_float_paths_draw_from_the_same_distribution() -> None:
    # The 8-bit kernel draws its per-pixel numbers from a counter-based hash keyed by the generator, the float
    # composer from torch's normal stream: different samples, the same law. Every input level is repeated
    # 3 * 64 * 16 = 3072 times, so per-level means have a standard error of std / 55 and variances of about
    # var * sqrt(2 / 3072) = 2.6% of var; the bands below are 5 standard errors.
    profile = load_profile(default_profile_path())
    assert all(any(v != 0 for v in profile.noise[p.name]) for p in model_parameters("paper"))
    levels = torch.arange(256, dtype=torch.uint8).repeat_interleave(16)
    clean8 = levels.view(1, 1, 4096).expand(3, 64, 4096).contiguous()
    fused = darksynth.synthesize(clean8, profile, generator=torch.Generator().manual_seed(2))
    composed = darksynth.synthesize(clean8.float() / 255.0, profile, generator=torch.Generator().manual_seed(2))
    assert fused.parameters == composed.parameters
    fused_mean, fused_var = _per_level_moments(clean8, fused.image.double())
    composed_mean, composed_var = _per_level_moments(clean8, (composed.image.double() * 255.0).round())
    standard_error = (composed_var.clamp_min(0.1) / 3072).sqrt()
    assert ((fused_mean - composed_mean).abs() <= 5 * math.sqrt(2) * standard_error + 1e-9).all()
    relative = (fused_var - composed_var).abs() / composed_var.clamp_min(0.1)
    assert (relative <= 5 * math.sqrt(2) * math.sqrt(2 / 3072) + 0.02).all()


def test_a_different_seed_gives_a_different_sample() -> None:
    profile = load_profile(default_profile_path())
    clean = torch.randint(0, 256, (3, 64, 96), dtype=torch.uint8, generator=torch.Generator().manual_seed(1))
    first = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(2)).image
    again = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(2)).image
    other = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(3)).image
    assert torch.equal(first, again)
    assert (first != other).double().mean().item() > 0.3


def _parameters(darkening: Darkening | None = None, **nonzero: float) -> ClipParameters:
    return ClipParameters(noise=NoiseValues.from_values(nonzero), darkening=darkening)


def test_fused_heteroscedastic_noise_has_the_model_variance_and_gaussian_shape() -> None:
    # Flat 8-bit frame, darkened to x_d = 0.5 * (200/255) ** 2: the fused output is round(255 (x_d + n)).
    x_d = 0.5 * (200 / 255) ** 2
    shot, read = 0.05, 0.01
    sigma = math.sqrt(shot**2 * x_d + read**2) * 255.0  # ~4.1 levels
    synthesizer = ClipSynthesizer(
        _parameters(Darkening(0.5, 0.5), shot=shot, read=read), generator=torch.Generator().manual_seed(5)
    )
    frame = torch.full((3, 128, 128), 200, dtype=torch.uint8)
    first = synthesizer(frame).double()
    second = synthesizer(frame).double()
    n = first.numel()
    # Rounding to integers adds variance 1/12 (Sheppard's correction, exact to 1e-15 for sigma > 1).
    variance = sigma**2 + 1.0 / 12.0
    assert abs(first.mean().item() - 255.0 * x_d) < 5.0 * math.sqrt(variance / n)
    assert abs(first.var().item() - variance) < 5.0 * variance * math.sqrt(2.0 / (n - 1))
    # Kurtosis of a normal plus an independent U(-1/2, 1/2): (3 s^4 + s^2 / 2 + 1/80) / (s^2 + 1/12)^2;
    # standard error sqrt(24 / n); 5 of them.
    expected_kurtosis = (3 * sigma**4 + sigma**2 / 2 + 1 / 80) / variance**2
    kurtosis = scipy.stats.kurtosis(first.flatten().numpy(), fisher=False)
    assert abs(kurtosis - expected_kurtosis) < 5.0 * math.sqrt(24.0 / n)
    # New noise every frame and at every pixel: frames and neighbouring pixels are uncorrelated.
    frames = torch.corrcoef(torch.stack([first.flatten(), second.flatten()]))[0, 1].item()
    neighbours = torch.corrcoef(torch.stack([first[..., :-1].flatten(), first[..., 1:].flatten()]))[0, 1].item()
    channels = torch.corrcoef(torch.stack([first[0].flatten(), first[1].flatten()]))[0, 1].item()
    assert abs(frames) < 5.0 / math.sqrt(n)
    assert abs(neighbours) < 5.0 / math.sqrt(n)
    assert abs(channels) < 5.0 / math.sqrt(n / 3)


def test_fused_quantization_noise_is_one_sided_uniform() -> None:
    q = 0.04  # 10.2 levels
    synthesizer = ClipSynthesizer(_parameters(quantization=q), generator=torch.Generator().manual_seed(6))
    frame = torch.full((3, 128, 128), 100, dtype=torch.uint8)
    offset = synthesizer(frame).double() - 100.0
    n = offset.numel()
    width = q * 255.0
    # The exact law of the output offset: round((k + 1/2) w / 256) for a uniform byte k.
    support = ((torch.arange(256, dtype=torch.float64) + 0.5) * width / 256).round()
    mean, variance = support.mean().item(), support.var(unbiased=False).item()
    fourth = (support - mean).pow(4).mean().item()
    assert set(offset.unique().tolist()) <= set(support.unique().tolist())
    assert offset.min().item() == 0.0 and offset.max().item() == support.max().item()
    # Mean and variance within 5 standard errors: sqrt(var / n) and sqrt((mu4 - var^2) / n).
    assert abs(offset.mean().item() - mean) < 5.0 * math.sqrt(variance / n)
    assert abs(offset.var().item() - variance) < 5.0 * math.sqrt((fourth - variance**2) / n)
    # The model's one-sided offset: the mean is w / 2, not 0.
    assert abs(mean - width / 2) < 0.1


def _kernel_argument(name: str, generator: torch.Generator) -> torch.Tensor:
    shape = (3, 67, 130)
    # Scalars and tables are drawn so that outputs reach below 0 and above 255, exercising both clamps.
    factories: dict[str, Callable[[], torch.Tensor]] = {
        "frame": lambda: torch.randint(0, 256, shape, dtype=torch.uint8, generator=generator),
        "standard_normal": lambda: torch.randn(shape, generator=generator),
        "uniform_levels": lambda: torch.randint(0, 256, shape, dtype=torch.uint8, generator=generator),
        "mean_table": lambda: torch.rand(256, generator=generator) * 300.0 - 20.0,
        "std_table": lambda: torch.rand(256, generator=generator) * 30.0,
        "level_step": lambda: torch.tensor(5.0 / 256.0),
        "key": lambda: random_key(generator),
        "darkened_table": lambda: torch.rand(256, generator=generator) * 1.1 - 0.05,
        "quantization_step": lambda: torch.tensor(0.02 / 256.0),
        "column_pattern": lambda: torch.randn((3, 1, 130), generator=generator) * 4.0,
    }
    if name not in factories:
        pytest.fail(f"pixel_kernel_8bit has an argument {name!r} that this test does not know how to fill")
    return factories[name]()


@pytest.mark.slow
# Inductor itself calls a deprecated torch.jit API while compiling; that is torch's warning, not ours.
@pytest.mark.filterwarnings("ignore:`torch.jit.script_method` is deprecated:DeprecationWarning")
def test_compiled_kernel_is_bit_identical_to_eager() -> None:
    kernel = compiled_pixel_kernel()
    assert kernel is not pixel_kernel_8bit, "torch.compile was unavailable; the test would compare eager to eager"
    generator = torch.Generator().manual_seed(7)
    inputs = [_kernel_argument(name, generator) for name in inspect.signature(pixel_kernel_8bit).parameters]
    eager = pixel_kernel_8bit(*inputs)
    compiled = kernel(*inputs)
    assert compiled.dtype == torch.uint8
    assert (eager == 0).any() and (eager == 255).any()
    assert torch.equal(compiled, eager)

    # The streaming synthesizer with compile=True gives the same frames as without.
    parameters = draw_clip_parameters(load_profile(default_profile_path()))
    frame = inputs[0]
    fast = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(8), compile=True)
    slow = ClipSynthesizer(parameters, generator=torch.Generator().manual_seed(8))
    for _ in range(3):
        assert torch.equal(fast(frame), slow(frame))


def test_kernel_in_pieces_is_bit_identical_to_one_call() -> None:
    from darksynth.noise.fused_8bit import kernel_tables, pixel_kernel_in_pieces

    generator = torch.Generator().manual_seed(5)
    frame = torch.randint(0, 256, (3, 301, 517), dtype=torch.uint8, generator=generator)
    columns = torch.randn(3, 1, 517, generator=generator) * 3
    key = torch.tensor([123_456_789, -5], dtype=torch.int32)
    values = NoiseValues.from_values({"shot": 0.1, "read": 0.02, "quantization": 0.01}).to("cpu", torch.float32)
    scalars = kernel_tables(Darkening(0.3, 0.6), values, device=torch.device("cpu"))
    whole = pixel_kernel_8bit(frame, key, *scalars, columns)
    # Pieces of 7 rows (3619 values) cut every channel into many blocks, the last one partial.
    pieces = pixel_kernel_in_pieces(pixel_kernel_8bit, frame, key, scalars, columns, piece_values=3619)
    assert torch.equal(whole, pieces)
    assert not torch.equal(whole, pixel_kernel_8bit(frame, advance(key, 1), *scalars, columns))
    # The base word wraps at 2^32: a block near the end of the counter range still gets its own numbers.
    wrapped = torch.tensor([(1 << 31) - 1000, -5], dtype=torch.int32)
    whole = pixel_kernel_8bit(frame, wrapped, *scalars, columns)
    assert torch.equal(
        whole, pixel_kernel_in_pieces(pixel_kernel_8bit, frame, wrapped, scalars, columns, piece_values=3619)
    )


def test_counter_normals_and_bytes_have_their_laws_and_are_independent() -> None:
    """Moments of the counter-based normal against N(0, 1), the bytes' histogram against uniform, and no
    correlation between neighbouring draws, between a draw's normal and byte, or between two keys."""
    from darksynth.noise.counter_rng import normal_and_byte

    generator = torch.Generator().manual_seed(11)
    count = 1 << 20
    normal, byte = normal_and_byte((count,), random_key(generator))
    other, _ = normal_and_byte((count,), random_key(generator))
    n = float(count)
    z = normal.double()
    assert abs(z.mean().item()) < 5 / math.sqrt(n)
    assert abs(z.var().item() - 1.0) < 5 * math.sqrt(2 / n)
    assert abs(scipy.stats.skew(z.numpy())) < 5 * math.sqrt(6 / n)
    assert abs(scipy.stats.kurtosis(z.numpy())) < 5 * math.sqrt(24 / n)
    assert scipy.stats.kstest(z.numpy()[:100_000], "norm").pvalue > 1e-3
    histogram = torch.bincount(byte.long(), minlength=256).double()
    assert scipy.stats.chisquare(histogram.numpy()).pvalue > 1e-3
    for a, b in ((z[1:], z[:-1]), (z, byte.double()), (z, other.double())):
        assert abs(torch.corrcoef(torch.stack([a, b]))[0, 1].item()) < 5 / math.sqrt(n)


def test_counter_normal_is_finite_at_both_ends_of_the_words() -> None:
    """The top 24 bits all ones once gave u = 1 in float32 and an infinite normal (one word in 2^24: a hot pixel
    in the fused kernels, a whole frame of NaN in the spectral one); both extreme words give finite tails."""
    from darksynth.noise.counter_rng import normal_from_word

    # Top 24 bits (the normal's): all ones twice, all zeros twice, then just above and just below the middle.
    words = torch.tensor([-1, -256, 0, 255, -(1 << 31), (1 << 31) - 1], dtype=torch.int32)
    normal, _ = normal_from_word(words)
    assert bool(torch.isfinite(normal).all())
    assert 5.0 < normal[0].item() < 6.0 and 5.0 < normal[1].item() < 6.0
    assert -6.0 < normal[2].item() < -5.0 and -6.0 < normal[3].item() < -5.0
    assert abs(normal[4].item()) < 1e-6 and abs(normal[5].item()) < 1e-6


def test_counter_triangular_draws_have_unit_variance_and_the_triangular_shape() -> None:
    from darksynth.noise.counter_rng import first_word, flat_index, triangular_from_word

    count = 1 << 20
    z = triangular_from_word(first_word(flat_index((count,), torch.device("cpu")), random_key())).double()
    n = float(count)
    assert abs(z.mean().item()) < 5 / math.sqrt(n)
    assert abs(z.var().item() - 1.0) < 5 * math.sqrt(0.8 / n)  # fourth moment 2.4 for the triangular law
    assert abs(scipy.stats.kurtosis(z.numpy()) + 0.6) < 0.02
    assert z.abs().max().item() <= math.sqrt(6.0)
    assert abs(torch.corrcoef(torch.stack([z[1:], z[:-1]]))[0, 1].item()) < 5 / math.sqrt(n)
