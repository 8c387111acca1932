"""The settings every trainer shares (training.scaffold.SyntheticTrainingConfig) as the adversarial baselines and
the DEN declare them."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from darksynth.baselines.adversarial import AdversarialConfig
from darksynth.baselines.den_v1_training import V1TrainConfig
from darksynth.baselines.starlight_training import StarlightTrainConfig
from darksynth.models.den import DENConfig
from darksynth.training.corpus import CleanCorpus
from darksynth.training.loop import TrainConfig
from darksynth.training.scaffold import SyntheticTrainingConfig

SHARED = {option.name for option in dataclasses.fields(SyntheticTrainingConfig)}


@pytest.mark.parametrize("config_type", [TrainConfig, V1TrainConfig, StarlightTrainConfig])
def test_every_trainer_declares_the_shared_fields_once_and_writes_its_network_by_its_own_to_dict(
    config_type: type[SyntheticTrainingConfig],
) -> None:
    config = config_type()
    names = [option.name for option in dataclasses.fields(config)]
    assert set(names) >= SHARED
    document = json.loads(json.dumps(config.to_dict()))
    assert set(document) == set(names)
    nested = {name: getattr(config, name) for name in names if hasattr(getattr(config, name), "to_dict")}
    assert len(nested) == 1
    for name, value in nested.items():
        assert document[name] == json.loads(json.dumps(value.to_dict()))
    assert issubclass(config_type, AdversarialConfig) == (config_type is not TrainConfig)


def test_each_trainer_keeps_its_own_defaults() -> None:
    assert (TrainConfig().steps, TrainConfig().crop, TrainConfig().learning_rate) == (4000, 128, 2e-4)
    assert TrainConfig().to_dict()["den"] == DENConfig().to_dict()
    assert (V1TrainConfig().steps, V1TrainConfig().max_seconds, V1TrainConfig().validation_size) == (18000, 1200.0, 32)
    assert (StarlightTrainConfig().steps, StarlightTrainConfig().crop, StarlightTrainConfig().log_every) == (
        1500,
        64,
        50,
    )


def test_clip_lengths_and_clean_clips_follow_the_config() -> None:
    config = SyntheticTrainingConfig(batch=3, frames=5, single_frame_every=2)
    assert [config.frames_at(step) for step in range(1, 7)] == [5, 1, 5, 1, 5, 1]
    assert {dataclasses.replace(config, single_frame_every=0).frames_at(step) for step in range(1, 7)} == {5}
    rng = np.random.default_rng(0)
    corpus = CleanCorpus(images=[rng.integers(0, 256, (40, 48, 3), dtype=np.uint8)], sources=["a"])
    clips = config.clean_clips(corpus, 5, 16, torch.Generator().manual_seed(0))
    assert clips.shape == (3, 5, 3, 16, 16) and float(clips.min()) >= 0.0 and float(clips.max()) <= 1.0
    assert config.clean_clips(corpus, 1, 16, torch.Generator().manual_seed(0), batch=2).shape == (2, 1, 3, 16, 16)
