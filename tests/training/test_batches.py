"""synthesize_batch: 8-bit noisy input, the true v inside the training ranges, absent components."""

from __future__ import annotations

import pytest
import torch

from darksynth.noise.components import (
    NOISE_COMPONENTS,
    model_parameters,
    vector_size,
)
from darksynth.noise.values import values_from_vector
from darksynth.training.batches import synthesize_batch

LOW = torch.tensor([p.training_range[0] for p in model_parameters("srgb") for _ in range(p.size)])
HIGH = torch.tensor([p.training_range[1] for p in model_parameters("srgb") for _ in range(p.size)])
NEUTRAL = torch.tensor([p.neutral for p in model_parameters("srgb") for _ in range(p.size)])


def _clean(batch: int = 6, seed: int = 0) -> torch.Tensor:
    """Smooth clean clips (B, 2, 3, 32, 32): horizontal and vertical ramps."""
    ramp = torch.linspace(0.05, 0.95, 32)
    pattern = torch.stack([ramp.expand(32, 32), ramp[:, None].expand(32, 32), torch.full((32, 32), 0.5)])
    shift = torch.rand(batch, 1, 1, 1, 1, generator=torch.Generator().manual_seed(seed)) * 0.05
    return (pattern.expand(batch, 2, 3, 32, 32) * (1 - shift)).contiguous()


def test_noisy_clips_are_on_the_8_bit_grid() -> None:
    batch = synthesize_batch(_clean(), generator=torch.Generator().manual_seed(1))
    levels = batch.noisy * 255.0
    torch.testing.assert_close(levels, levels.round(), atol=1e-4, rtol=0)
    assert batch.noisy.min() >= 0 and batch.noisy.max() <= 1
    assert batch.noisy.shape == batch.dark.shape == (6, 2, 3, 32, 32)


def test_vectors_lie_inside_the_training_ranges_over_many_draws() -> None:
    generator = torch.Generator().manual_seed(2)
    vectors = torch.cat([synthesize_batch(_clean(), generator=generator).vector for _ in range(20)])
    assert vectors.shape == (120, vector_size())
    assert ((vectors >= LOW) & (vectors <= HIGH)).all()
    # The draws spread over each range instead of sitting at one end (absent components aside).
    present = vectors.clone()
    present[present == NEUTRAL.expand_as(present)] = float("nan")
    assert (present.nanquantile(0.9, 0) - present.nanquantile(0.1, 0) > 0.5 * (HIGH - LOW)).all()


def test_every_component_is_present_when_absence_is_impossible() -> None:
    batch = synthesize_batch(
        _clean(), generator=torch.Generator().manual_seed(3), absent_probability=0.0, noise_model="paper"
    )
    assert (batch.vector > 0).all()
    assert not torch.equal(batch.noisy, (batch.dark * 255).round() / 255)
    # In the sRGB model, the shape parameters are also switched off alone (white, uncompressed noise is
    # kept in the training data): neutral in about their off-probability of clips, never for the paper's.
    generator = torch.Generator().manual_seed(3)
    vectors = torch.cat(
        [synthesize_batch(_clean(), generator=generator, absent_probability=0.0).vector for _ in range(40)]
    )
    values = values_from_vector(vectors)
    for parameter in model_parameters("srgb"):
        off = (values[parameter.name] == parameter.neutral).all(-1).float().mean().item()
        expected = parameter.training_off_probability or 0.0
        # 240 clips: a binomial share's standard error is at most 0.032; 4 of them.
        assert abs(off - expected) < 0.13, parameter.name


def test_absent_components_give_the_quantised_dark_clip_and_a_neutral_vector() -> None:
    batch = synthesize_batch(_clean(), generator=torch.Generator().manual_seed(4), absent_probability=1.0)
    assert torch.equal(batch.vector, NEUTRAL.expand(6, vector_size()))
    assert torch.equal(batch.noisy, (batch.dark * 255.0).round() / 255.0)
    paper = synthesize_batch(
        _clean(), generator=torch.Generator().manual_seed(4), absent_probability=1.0, noise_model="paper"
    )
    assert torch.equal(paper.vector, torch.zeros(6, 8))


def test_absence_switches_whole_components() -> None:
    """A component is on or off as a whole: periodic's three sigmas are all zero or all non-zero."""
    generator = torch.Generator().manual_seed(5)
    vectors = torch.cat(
        [synthesize_batch(_clean(), generator=generator, absent_probability=0.5).vector for _ in range(10)]
    )
    values = values_from_vector(vectors)
    for component in NOISE_COMPONENTS:
        # Parameters that training also switches off alone may be neutral while the rest is on.
        together = [p for p in component.parameters if p.training_off_probability is None]
        if len(together) < 2:
            continue
        zero = torch.cat([values[p.name] == p.neutral for p in together], dim=-1)
        assert (zero.all(-1) | (~zero).all(-1)).all(), component.name
    assert 0.3 < (values["shot"] == 0).float().mean() < 0.7
    # An absent heteroscedastic component takes its shape parameters with it.
    absent = (values["shot"] == 0)[:, 0]
    assert (values["channel_gain"][absent] == 1.0).all()
    assert (values["correlation_length"][absent] == 0.0).all()


def test_dark_clip_is_a_darkening_of_the_clean_one() -> None:
    clean = _clean()
    batch = synthesize_batch(clean, generator=torch.Generator().manual_seed(6))
    assert batch.dark.max() < clean.max()
    # Darkening alpha * x ** (1 / gamma) keeps the order of pixel values within a clip.
    order_clean = clean[0, 0, 0, 0].argsort()
    assert torch.equal(batch.dark[0, 0, 0, 0].argsort(), order_clean)


def test_same_generator_seed_gives_the_same_batch() -> None:
    first = synthesize_batch(_clean(), generator=torch.Generator().manual_seed(7))
    second = synthesize_batch(_clean(), generator=torch.Generator().manual_seed(7))
    assert torch.equal(first.noisy, second.noisy)
    assert torch.equal(first.vector, second.vector)
    third = synthesize_batch(_clean(), generator=torch.Generator().manual_seed(8))
    assert not torch.equal(first.vector, third.vector)


@pytest.mark.parametrize("probability", [0.0, 1.0])
def test_noise_is_redrawn_for_every_frame_of_a_clip(probability: float) -> None:
    """The clean frames are identical: only the signal (p = 1) keeps them so; pixel noise differs per frame."""
    batch = synthesize_batch(_clean(), generator=torch.Generator().manual_seed(9), absent_probability=probability)
    identical = torch.equal(batch.noisy[:, 0], batch.noisy[:, 1])
    assert identical == (probability == 1.0)
