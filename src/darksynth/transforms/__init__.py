"""darksynth in training loops: a low-light transform for PyTorch datasets and one for albumentations.

::

    from darksynth.transforms import LowLight
    low_light = LowLight("night.json")            # in a Dataset's __getitem__: noisy = low_light(clean)

:class:`LowLight` takes float tensors in [0, 1] (or uint8), (C, H, W) images or (T, C, H, W) clips, draws new
parameters within the profile's ranges and new noise at every call, and seeds itself correctly inside
``torch.utils.data.DataLoader`` workers (see :mod:`darksynth.transforms.low_light`).
``AlbumentationsLowLight`` is the same for ``albumentations.Compose`` pipelines on numpy (H, W, C) images; it is
imported on first use, so this package needs albumentations only when that class is asked for.
docs/training-loops.md shows both in a training loop.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from darksynth.transforms.low_light import LowLight, mix_seed

if TYPE_CHECKING:
    from darksynth.transforms._albumentations import AlbumentationsLowLight


def __getattr__(name: str) -> Any:
    # albumentations is an optional dependency that imports OpenCV and pydantic: load it only when asked.
    if name == "AlbumentationsLowLight":
        from darksynth.transforms._albumentations import AlbumentationsLowLight

        return AlbumentationsLowLight
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["AlbumentationsLowLight", "LowLight", "mix_seed"]
