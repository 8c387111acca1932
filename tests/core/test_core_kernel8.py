"""The fused 8-bit path: agreement with the float composer, its statistics, and its torch.compile build."""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import pytest
import scipy.stats
import torch

import darksynth
from darksynth.darkening import Darkening
from darksynth.noise.components import NOISE_PARAMETERS
from darksynth.noise.kernel8 import compiled_pixel_kernel, pixel_kernel_8bit
from darksynth.profile import Profile, default_profile_path, load_profile
from darksynth.synthesize import ClipParameters, ClipSynthesizer, draw_clip_parameters

ProfileFactory = Callable[..., Profile]


def _levels_apart(image8: torch.Tensor, image_float: torch.Tensor) -> torch.Tensor:
    return ((image_float.double() * 255.0).round() - image8.double()).abs()


def _assert_paths_agree(clean8: torch.Tensor, profile: Profile, seed: int) -> None:
    fused = darksynth.synthesize(clean8, profile, generator=torch.Generator().manual_seed(seed))
    composed = darksynth.synthesize(clean8.float() / 255.0, profile, generator=torch.Generator().manual_seed(seed))
    assert fused.image.dtype == torch.uint8 and composed.image.dtype == torch.float32
    assert fused.parameters == composed.parameters
    difference = _levels_apart(fused.image, composed.image)
    # Both paths consume the random stream in the same order, so they differ only where float rounding
    # moves a value across a rounding boundary: one level, rarely.
    assert difference.max().item() <= 1.0
    assert (difference > 0).double().mean().item() < 0.01


def test_uint8_and_float_paths_agree_with_the_default_profile() -> None:
    profile = load_profile(default_profile_path())
    assert all(any(v != 0 for v in values) for values in profile.noise.values())
    clean = torch.randint(0, 256, (3, 64, 96), dtype=torch.uint8, generator=torch.Generator().manual_seed(1))
    _assert_paths_agree(clean, profile, seed=2)


def test_uint8_and_float_paths_agree_with_strong_noise_and_ranges(make_profile: ProfileFactory) -> None:
    # Strong noise clips at both ends; ranges make both paths draw parameters from the stream first.
    profile = make_profile(
        darkening=Darkening(0.6, 0.8),
        ranges={"shot": [(0.1, 0.3)], "alpha": [(0.8, 1.0)], "periodic": [(0.0, 0.05)] * 3},
        shot=0.2,
        read=0.1,
        quantization=0.02,
        banding=0.03,
        temporal_banding=0.03,
        periodic=[0.02, 0.02, 0.02],
    )
    clean = torch.randint(0, 256, (2, 1, 3, 48, 64), dtype=torch.uint8, generator=torch.Generator().manual_seed(3))
    _assert_paths_agree(clean, profile, seed=4)
    # The noise really is strong enough to clip, so the clamp of both paths is exercised.
    image = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(4)).image
    assert (image == 0).any() and (image == 255).any()


def test_a_different_seed_is_far_apart() -> None:
    # Control for the agreement tests: unrelated streams differ by many levels at many pixels.
    profile = load_profile(default_profile_path())
    clean = torch.randint(0, 256, (3, 64, 96), dtype=torch.uint8, generator=torch.Generator().manual_seed(1))
    fused = darksynth.synthesize(clean, profile, generator=torch.Generator().manual_seed(2)).image
    composed = darksynth.synthesize(clean.float() / 255.0, profile, generator=torch.Generator().manual_seed(3)).image
    assert (_levels_apart(fused, composed) > 1).double().mean().item() > 0.3


def _parameters(darkening: Darkening | None = None, **nonzero: float) -> ClipParameters:
    return ClipParameters(
        noise={p.name: (nonzero.get(p.name, 0.0),) * p.size for p in NOISE_PARAMETERS}, darkening=darkening
    )


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
        "key": lambda: torch.randint(0, 1 << 62, (), dtype=torch.int64, generator=generator),
        "alpha": lambda: torch.tensor(0.9),
        "inverse_gamma": lambda: torch.tensor(1.3),
        "shot_squared": lambda: torch.tensor(0.3**2),
        "read_squared": lambda: torch.tensor(0.05**2),
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
