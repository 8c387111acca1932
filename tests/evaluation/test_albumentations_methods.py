"""albumentations' noise as methods of `darksynth evaluate`: their default ranges, seeded by the generator."""

import pytest
import torch

from darksynth.evaluation.methods.albumentations import ALBUMENTATIONS_METHODS
from darksynth.evaluation.methods.catalogue import METHOD_NAMES, build_method

pytest.importorskip("albumentations")


def _grey(side: int = 96) -> torch.Tensor:
    return torch.full((3, side, side), 128.0 / 255.0, dtype=torch.float64)


def _ramp(side: int = 96) -> torch.Tensor:
    """A colour ramp on 8-bit levels: ISONoise scales its noise by the image's luminance spread (none on flat grey)."""
    ramp = torch.linspace(40.0, 215.0, side, dtype=torch.float64).round() / 255.0
    across, down = ramp[None, :].expand(side, side), ramp[:, None].expand(side, side)
    return torch.stack([across, down, 1.0 - across])


@pytest.mark.parametrize("name", sorted(ALBUMENTATIONS_METHODS))
def test_each_is_a_method_by_name_and_draws_on_8bit_levels_from_its_seed(name: str) -> None:
    assert name in METHOD_NAMES
    method = build_method(name)
    assert method.fit(_grey(), _grey()) is None and not method.oracle
    first = method.synthesize(_ramp(), None, torch.Generator().manual_seed(3))
    again = method.synthesize(_ramp(), None, torch.Generator().manual_seed(3))
    other = method.synthesize(_ramp(), None, torch.Generator().manual_seed(4))
    assert first.dtype == torch.float64 and first.shape == (3, 96, 96)
    assert torch.equal(first, again) and not torch.equal(first, other)
    assert torch.equal((first * 255).round(), first * 255)


def test_gauss_noise_draws_its_documented_std_range() -> None:
    # GaussNoise's default std_range (0.2, 0.44) of full scale: on mid-grey, clipping trims the widest draws a little.
    method = build_method("albu-gauss")
    stds = [
        float((method.synthesize(_grey(), None, torch.Generator().manual_seed(seed)) - _grey()).std())
        for seed in range(12)
    ]
    assert min(stds) > 0.17 and max(stds) < 0.44, stds
    assert max(stds) - min(stds) > 0.05, stds  # drawn per call, not fixed


def test_iso_noise_follows_the_image_and_is_weaker_than_gauss_noise_at_the_defaults() -> None:
    iso = build_method("albu-iso")
    textured = iso.synthesize(_ramp(), None, torch.Generator().manual_seed(0)) - _ramp()
    assert 0.005 < float(textured.std()) < 0.15, float(textured.std())
    flat = iso.synthesize(_grey(), None, torch.Generator().manual_seed(0)) - _grey()
    assert float(flat.abs().max()) == 0.0  # its noise scales with the image's luminance spread
