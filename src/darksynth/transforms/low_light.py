"""``LowLight``: a callable transform that turns a clean tensor into a low-light one, for training loops.

It is a thin wrapper of :func:`darksynth.synthesize.synthesize`: each call draws the parameters of one image
or clip within the profile's ranges (:meth:`darksynth.recipe.ClipRecipe.choose`) and new noise, so the
result is what ``darksynth apply`` would make of the same input with the same generator state.

Dtypes: uint8 in gives uint8 out (the fused 8-bit kernel, as ``apply`` runs it), uint16 gives uint16, a float
tensor in [0, 1] gives the same float dtype. Float output is rounded to the 256 levels of an 8-bit file by
default, as a camera's JPEG or PNG stores them and as real low-light references arrive; ``round_to_8bit=False``
keeps the continuous values.

Seeding: the transform owns a ``torch.Generator``, created on the first call in each process (and again after
``fork`` or unpickling in a ``spawn`` worker: the generator is never copied into a worker). Its seed:

* ``seed=None``: one draw from torch's global generator of that process, so ``torch.manual_seed`` fixes it.
  In a DataLoader worker the draw is also mixed with the worker's seed (``get_worker_info().seed``, which torch
  derives from the loader's base seed, new every epoch, plus the worker id).
* ``seed=N``: N; in a DataLoader worker, N mixed with the worker's seed. Workers thus never repeat each other
  or the previous epoch, and a run repeats exactly when N and the loader's base seed (``torch.manual_seed`` or
  ``DataLoader(generator=...)``) are fixed. No ``worker_init_fn`` is needed.
* per sample: ``low_light(x, seed=index)`` uses a fresh generator seeded from (N or 0, index): the output then
  depends only on the input, the profile, N and the index, never on workers, epochs or order.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Unpack, cast

import numpy as np
import torch
import torch.utils.data

from darksynth.cameras.presets import CAMERA_CHOICES
from darksynth.light.darkening import Darkening
from darksynth.profile import Profile, load_profile, parse_profile, validate_profile
from darksynth.recipe import (
    ClipParameters,
    ClipRecipe,
    DarkeningChoice,
    RecipeChoices,
    augmenting_recipe,
    recipe_choices,
)
from darksynth.seeding import derive_seed
from darksynth.synthesize import LowLightResult, synthesize
from darksynth.tensors import to_8bit_levels

FLOAT_RANGE_TOLERANCE = 0.25
"""How far outside [0, 1] float values may lie (resampling overshoot, clipped away); normalised tensors
(ImageNet mean and std) and 0-255 floats lie much further out and are refused."""

_SUPPORTED_CHANNELS = (1, 3)


def mix_seed(*parts: int | str) -> int:
    """A 63-bit seed from several parts (a user seed, a worker's seed, a sample index): a hash, so that nearby
    parts (worker 0 and 1, index 7 and 8) give unrelated generator streams."""
    return derive_seed("darksynth-transform", *parts)


def dataloader_worker_seed() -> int | None:
    """The seed torch gave the current DataLoader worker (base seed + worker id), None outside a worker."""
    worker = torch.utils.data.get_worker_info()
    return None if worker is None else int(worker.seed)


def as_profile(profile: Profile | str | Path | dict[str, Any]) -> Profile:
    """A validated profile from a :class:`Profile`, a profile file's path or a decoded profile document."""
    if isinstance(profile, Profile):
        return validate_profile(profile)
    if isinstance(profile, str | Path):
        return load_profile(profile)
    if isinstance(profile, dict):
        return parse_profile(profile, source="profile")
    raise ValueError(f"profile must be a Profile, a path or a profile document, got {type(profile).__name__}")


def check_darkening(darkening: object) -> DarkeningChoice:
    """The darkening choice, checked: ``"profile"``, None or a :class:`Darkening`."""
    if darkening is None or darkening == "profile" or isinstance(darkening, Darkening):
        return darkening
    raise ValueError(f'darkening must be "profile", None or a Darkening, got {darkening!r}')


def check_camera_name(camera: object) -> str | None:
    """The camera choice, checked: None or one of :data:`~darksynth.cameras.presets.CAMERA_CHOICES`."""
    if camera is None or (isinstance(camera, str) and camera in CAMERA_CHOICES):
        return camera
    raise ValueError(f"camera must be None or one of {', '.join(CAMERA_CHOICES)}, got {camera!r}")


def check_image(image: object) -> torch.Tensor:
    """The image, if it is a tensor LowLight can take; else a ValueError saying what is wrong with it."""
    if not isinstance(image, torch.Tensor):
        raise ValueError(f"LowLight takes a torch tensor (C, H, W) or (T, C, H, W), got {type(image).__name__}")
    if image.dim() not in (3, 4):
        raise ValueError(
            f"expected a (C, H, W) image or a (T, C, H, W) clip, got shape {tuple(image.shape)}; "
            "apply LowLight to each sample, not to a batch of clips"
        )
    if image.shape[-3] not in _SUPPORTED_CHANNELS:
        raise ValueError(
            f"expected 1 (grey) or 3 (RGB) channels at dimension -3, got shape {tuple(image.shape)}; "
            "drop an alpha channel, and permute (H, W, C) images to (C, H, W)"
        )
    if image.numel() == 0:
        raise ValueError(f"empty image, shape {tuple(image.shape)}")
    if image.dtype.is_floating_point:
        low, high = (float(value) for value in torch.aminmax(image.detach()))
        # Float values not on the [0, 1] scale are refused, NaN included (it fails both comparisons).
        if not (low >= -FLOAT_RANGE_TOLERANCE and high <= 1.0 + FLOAT_RANGE_TOLERANCE):
            raise ValueError(
                f"float pixel values must lie in [0, 1], got min {low:.4g} and max {high:.4g}; "
                "apply the low-light transform before normalising, and divide 0-255 floats by 255"
            )
    elif image.dtype not in (torch.uint8, torch.uint16):
        raise ValueError(f"unsupported pixel type {image.dtype}; use uint8, uint16 or float in [0, 1]")
    return image


def low_light(
    image: torch.Tensor,
    recipe: ClipRecipe,
    *,
    generator: torch.Generator,
    round_to_8bit: bool = True,
    device: torch.device | str | None = None,
    parameters: ClipParameters | None = None,
) -> LowLightResult:
    """The low-light version of a checked image (C, H, W) or clip (T, C, H, W) and the parameters drawn for it by
    ``recipe`` (or ``parameters``, chosen before): :func:`darksynth.synthesize.synthesize`, then float output
    rounded to 8-bit levels if asked."""
    choices = recipe_choices(recipe)
    result = synthesize(image, recipe.profile, generator=generator, device=device, parameters=parameters, **choices)
    assert isinstance(result.image, torch.Tensor)  # a tensor input gives a tensor result
    output = result.image
    if round_to_8bit and output.dtype.is_floating_point:
        output = to_8bit_levels(output).to(output.dtype)
    return LowLightResult(image=output, parameters=result.parameters)


def transform_recipe(profile: Profile | str | Path | dict[str, Any], choices: RecipeChoices) -> ClipRecipe:
    """The recipe a transform holds (:func:`darksynth.recipe.augmenting_recipe`), its profile read and its
    darkening and camera checked (a ValueError names the wrong one)."""
    checked = dict(choices)
    if "darkening" in checked:
        checked["darkening"] = check_darkening(checked["darkening"])
    if "camera" in checked:
        checked["camera"] = check_camera_name(checked["camera"])
    return augmenting_recipe(as_profile(profile), cast(RecipeChoices, checked))


class LowLight:
    """Darkening and sensor noise from a noise profile, as a transform for tensors in a training loop.

    Works wherever a callable transform does: a Dataset's ``__getitem__``, ``torchvision.transforms.v2.Compose``
    (after ``ToDtype(torch.float32, scale=True)`` and before ``Normalize``). A 4-D tensor is one clip, not a
    batch: its frames share one parameter draw and the temporal banding pattern.

    Args:
        profile: the noise profile, a path to one, or a decoded profile document.
        seed: the stream's seed (see the module docstring); None follows torch's global seed.
        round_to_8bit: round float output to 8-bit levels (k / 255), as a camera file stores it.
        device: where to compute and return the result; the device of the first input when None.
        choices: the recipe's choices (:class:`darksynth.recipe.RecipeChoices`), with the meaning and default of
            :class:`~darksynth.recipe.ClipRecipe`'s fields, but ``jitter`` :data:`~darksynth.recipe.AUGMENTING`
            (each call draws within the profile's ranges). ``darkening``: ``"profile"`` (the profile's darkening
            or its ranges, matched to each input's tones), a :class:`Darkening` to fix it, or None to add noise
            only. ``camera``: draw each call's camera from real ones (``"prior"`` or a preset of
            :data:`darksynth.cameras.presets.CAMERA_CHOICES`); :meth:`sample` shows the drawn values.

    The recipe built from these is :attr:`recipe`.

    Example::

        low_light = LowLight("night.json")
        noisy = low_light(clean)                    # clean: float (3, H, W) in [0, 1]
        fixed = low_light(clean, seed=index)        # the same result for this index, always
    """

    def __init__(
        self,
        profile: Profile | str | Path | dict[str, Any],
        *,
        seed: int | None = None,
        round_to_8bit: bool = True,
        device: torch.device | str | None = None,
        **choices: Unpack[RecipeChoices],
    ) -> None:
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)):
            raise ValueError(f"seed must be an integer or None, got {seed!r}")
        self.recipe = transform_recipe(profile, choices)
        self.seed = None if seed is None else int(seed)
        self.round_to_8bit = bool(round_to_8bit)
        self.device = None if device is None else torch.device(device)
        self._generator: torch.Generator | None = None
        self._owner: tuple[int, int | None] | None = None

    def __call__(self, image: torch.Tensor, *, seed: int | None = None) -> torch.Tensor:
        """The low-light version of ``image`` (C, H, W) or (T, C, H, W), in its dtype (rules in the module
        docstring); with ``seed``, reproducible from that seed alone (a sample index, for instance)."""
        result = self.sample(image, seed=seed)
        assert isinstance(result.image, torch.Tensor)
        return result.image

    def sample(self, image: torch.Tensor, *, seed: int | None = None) -> LowLightResult:
        """Like calling the transform, but also returns the parameters drawn (noise values and darkening), for
        a dataset that trains on them or logs them."""
        image = check_image(image)
        device = self.device if self.device is not None else image.device
        generator = self._stream_generator(device) if seed is None else self._sample_generator(seed, device)
        return low_light(image, self.recipe, generator=generator, round_to_8bit=self.round_to_8bit, device=device)

    def _sample_generator(self, seed: int, device: torch.device) -> torch.Generator:
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
            raise ValueError(f"seed must be an integer, got {seed!r}")
        return torch.Generator(device).manual_seed(mix_seed("sample", self.seed or 0, int(seed)))

    def _stream_generator(self, device: torch.device) -> torch.Generator:
        worker_seed = dataloader_worker_seed()
        owner = (os.getpid(), worker_seed)
        # A generator made in another process (the parent, before a fork) would give every worker the same
        # noise: each process, and each worker incarnation, starts its own.
        if self._generator is None or self._owner != owner:
            base = self.seed if self.seed is not None else int(torch.randint(2**62, (), dtype=torch.int64).item())
            parts = ("stream", base) if worker_seed is None else ("stream", base, "worker", worker_seed)
            self._generator = torch.Generator(device).manual_seed(mix_seed(*parts))
            self._owner = owner
        elif self._generator.device != device:
            raise ValueError(
                f"this LowLight draws on {self._generator.device} but got a tensor on {device}; "
                "pass device= to move inputs, or use one transform per device"
            )
        return self._generator

    def __getstate__(self) -> dict[str, Any]:
        # A spawned worker unpickles the transform: it must start its own generator, not continue a copy.
        state = self.__dict__.copy()
        state["_generator"] = None
        state["_owner"] = None
        return state

    def __repr__(self) -> str:
        choices = ", ".join(f"{name}={value!r}" for name, value in recipe_choices(self.recipe).items())
        return f"LowLight(seed={self.seed}, round_to_8bit={self.round_to_8bit}, device={self.device}, {choices})"
