"""The DEN: any frame size, bounded predictions, order- and batch-independence, input checks."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import torch

from darksynth.models.den import DEN, denormalise, normalise
from darksynth.noise.components import model_parameters, vector_size
from darksynth.noise.values import model_vector

LOW = torch.tensor([p.training_range[0] for p in model_parameters("srgb") for _ in range(p.size)])
HIGH = torch.tensor([p.training_range[1] for p in model_parameters("srgb") for _ in range(p.size)])


def _clip(shape: tuple[int, ...], seed: int = 0) -> torch.Tensor:
    return torch.rand(shape, generator=torch.Generator().manual_seed(seed))


@pytest.mark.parametrize("frames", [1, 3])
@pytest.mark.parametrize("depth", [1, 2])
def test_odd_frame_sizes_give_estimates_and_a_same_size_reconstruction(
    tiny_model: Callable[..., DEN], frames: int, depth: int
) -> None:
    model = tiny_model(depth=depth)
    clip = _clip((2, frames, 3, 37, 53))
    with torch.no_grad():
        output = model(clip)
    assert output.normalised.shape == (2, vector_size())
    assert torch.isfinite(output.normalised).all()
    assert output.dark is not None
    assert output.dark.shape == clip.shape
    assert torch.isfinite(output.dark).all()


def test_v2_has_no_reconstruction_and_no_decoder(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model(variant="v2")
    with torch.no_grad():
        output = model(_clip((1, 2, 3, 37, 53)))
    assert output.dark is None
    assert output.normalised.shape == (1, vector_size())
    assert len(model.decoders) == 0
    # The decoder's parameters are not built at all, so v2 is strictly smaller than v3.
    v3 = tiny_model(variant="v3")
    assert sum(p.numel() for p in model.parameters()) < sum(p.numel() for p in v3.parameters())


@pytest.mark.parametrize("content", ["random", "zeros", "ones"])
@pytest.mark.parametrize("head_gain", [1.0, 1e4])
def test_predictions_lie_inside_the_training_ranges(
    tiny_model: Callable[..., DEN], content: str, head_gain: float
) -> None:
    """Whatever the head outputs (a gain of 1e4 drives it far outside), v stays inside the training ranges."""
    model = tiny_model()
    with torch.no_grad():
        model.head[-1].weight.mul_(head_gain)
        model.head[-1].bias.mul_(head_gain)
    shape = (3, 2, 3, 33, 41)
    clip = {"random": _clip(shape), "zeros": torch.zeros(shape), "ones": torch.ones(shape)}[content]
    with torch.no_grad():
        output = model(clip)
    values = model_vector(output.values)
    assert values.shape == (3, vector_size())
    assert torch.isfinite(values).all()
    assert (values >= LOW - 1e-7).all()
    assert (values <= HIGH + 1e-7).all()
    assert ((output.normalised >= 0) & (output.normalised <= 1)).all()


FLOOR = torch.tensor([p.log_floor or 0.0 for p in model_parameters("srgb") for _ in range(p.size)])
LOGARITHMIC = FLOOR > 0


def test_values_are_the_normalised_output_on_the_parameter_scale(tiny_model: Callable[..., DEN]) -> None:
    with torch.no_grad():
        linear = tiny_model(log_levels=False)(_clip((2, 1, 3, 32, 32)))
        logarithmic = tiny_model(log_levels=True)(_clip((2, 1, 3, 32, 32)))
    torch.testing.assert_close(model_vector(linear.values), LOW + linear.normalised * (HIGH - LOW))
    # Levels with a log floor: floor * (high / floor) ** n; the other entries stay linear.
    n = logarithmic.normalised
    expected = torch.where(
        LOGARITHMIC, FLOOR.clamp_min(1e-12) * (HIGH / FLOOR.clamp_min(1e-12)) ** n, LOW + n * (HIGH - LOW)
    )
    torch.testing.assert_close(model_vector(logarithmic.values), expected)


def test_log_levels_normalise_relative_precision_evenly() -> None:
    assert LOGARITHMIC.sum() == 8  # shot, read, quantization, banding, temporal banding, periodic (3)
    floor, high = FLOOR[LOGARITHMIC], HIGH[LOGARITHMIC]
    vector = LOW.clone()
    vector[LOGARITHMIC] = floor
    torch.testing.assert_close(normalise(vector, log_levels=True)[LOGARITHMIC], torch.zeros(8))
    vector[LOGARITHMIC] = (floor * high).sqrt()  # the geometric middle is half-way
    torch.testing.assert_close(normalise(vector, log_levels=True)[LOGARITHMIC], torch.full((8,), 0.5))
    vector[LOGARITHMIC] = 0.0  # absent: below the floor reads as the floor
    torch.testing.assert_close(normalise(vector, log_levels=True)[LOGARITHMIC], torch.zeros(8))
    unit = torch.rand(6, vector_size(), generator=torch.Generator().manual_seed(4))
    torch.testing.assert_close(normalise(denormalise(unit, log_levels=True), log_levels=True), unit)


def test_normalise_maps_each_training_range_onto_the_unit_interval() -> None:
    torch.testing.assert_close(normalise(LOW), torch.zeros(vector_size()))
    torch.testing.assert_close(normalise(HIGH), torch.ones(vector_size()))
    torch.testing.assert_close(normalise((LOW + HIGH) / 2), torch.full((vector_size(),), 0.5))
    # shot's training range is (0, 0.2): 0.05 is a quarter of the way; read's is (0, 0.1): 0.05 is half.
    vector = torch.zeros(vector_size())
    vector[0], vector[1] = 0.05, 0.05
    assert normalise(vector)[:2].tolist() == pytest.approx([0.25, 0.5])
    # The paper's model normalises its own 8 values over the same ranges.
    paper = model_parameters("paper")
    low = torch.tensor([p.training_range[0] for p in paper for _ in range(p.size)])
    high = torch.tensor([p.training_range[1] for p in paper for _ in range(p.size)])
    torch.testing.assert_close(normalise(high, "paper"), torch.ones(vector_size("paper")))
    torch.testing.assert_close(denormalise(normalise(low, "paper"), "paper"), low)


def test_paper_model_predicts_the_papers_eight_values(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model(noise_model="paper")
    with torch.no_grad():
        output = model(_clip((2, 2, 3, 32, 40)))
    assert output.normalised.shape == (2, 8)
    assert model_vector(output.values, "paper").shape == (2, 8)
    # It reads only the paper's statistics: fewer head inputs than the sRGB model.
    srgb = tiny_model()
    assert model.head[0].in_features < srgb.head[0].in_features


def test_normalise_denormalise_round_trip() -> None:
    generator = torch.Generator().manual_seed(3)
    vector = LOW + torch.rand(5, 4, vector_size(), generator=generator) * (HIGH - LOW)
    torch.testing.assert_close(denormalise(normalise(vector)), vector)
    unit = torch.rand(7, vector_size(), generator=generator)
    torch.testing.assert_close(normalise(denormalise(unit)), unit)


def test_frame_order_does_not_change_the_estimate(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model()
    clip = _clip((1, 4, 3, 32, 40))
    order = torch.tensor([2, 0, 3, 1])
    with torch.no_grad():
        straight, shuffled = model(clip), model(clip[:, order])
    torch.testing.assert_close(shuffled.normalised, straight.normalised, atol=1e-5, rtol=1e-4)
    assert straight.dark is not None and shuffled.dark is not None
    torch.testing.assert_close(shuffled.dark, straight.dark[:, order], atol=1e-5, rtol=1e-4)


def test_clips_of_a_batch_do_not_influence_each_other(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model()
    clips = _clip((3, 2, 3, 32, 36))
    with torch.no_grad():
        together = model(clips)
        alone = [model(clips[i : i + 1]) for i in range(3)]
    torch.testing.assert_close(together.normalised, torch.cat([a.normalised for a in alone]), atol=1e-5, rtol=1e-4)


def test_different_noise_gives_different_estimates(tiny_model: Callable[..., DEN]) -> None:
    """The fixed noise statistics reach the head: a flat clip and a noisy one are told apart."""
    model = tiny_model()
    flat = torch.full((1, 2, 3, 32, 32), 0.2)
    noisy = (flat + 0.05 * torch.randn(flat.shape, generator=torch.Generator().manual_seed(0))).clamp(0, 1)
    with torch.no_grad():
        difference = (model(flat).normalised - model(noisy).normalised).abs().max()
    assert difference > 1e-4


@pytest.mark.parametrize(
    "shape",
    [(1, 1, 1, 32, 32), (1, 2, 4, 32, 32), (1, 3, 32, 32), (2, 1, 1, 3, 32, 32)],
    ids=["grey", "four-channel", "no-time-axis", "six-dims"],
)
def test_wrong_input_layout_raises_value_error(tiny_model: Callable[..., DEN], shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match=r"expected clips \(B, T, 3, H, W\)"):
        tiny_model()(torch.rand(shape))


def test_smallest_single_frame_gives_finite_estimates_at_every_depth(tiny_model: Callable[..., DEN]) -> None:
    model = tiny_model(depth=4)
    with torch.no_grad():
        output = model(_clip((1, 1, 3, 32, 32)))
    assert torch.isfinite(output.normalised).all()
