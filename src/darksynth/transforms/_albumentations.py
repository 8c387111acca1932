"""``AlbumentationsLowLight``: darksynth's darkening and noise as an albumentations 2.x image-only transform.

Imported only when ``darksynth.transforms.AlbumentationsLowLight`` is first asked for; needs albumentations.

Randomness follows albumentations: ``get_params`` draws one integer, the call's seed, from the transform's
``random_generator`` (which ``A.Compose(..., seed=N)`` seeds); ``get_params_dependent_on_data`` draws the clip's
parameters from it (alpha and gamma matched to the input's tones, or drawn, the noise values within the profile's
ranges and, with ``camera``, a camera), and ``apply`` draws the noise itself from it, given those parameters. A
seeded Compose is therefore reproducible, and a ``ReplayCompose`` record shows what was drawn (``seed``,
``alpha``, ``gamma``, ``noise``, ``light``, ``camera``: where a drawn camera came from) and replays the same
pixels. albumentations 2.0.8 itself copies one random state into every DataLoader worker; inside a worker the
drawn integer is therefore mixed with the worker's seed, so workers add different noise (the ``p`` decisions and
other transforms' draws remain albumentations' own).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Unpack

import numpy as np
import torch

from darksynth.io.arrays import numpy_to_tensor, tensor_to_numpy
from darksynth.light.darkening import Darkening
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, profile_to_dict
from darksynth.recipe import ClipParameters, DarkeningChoice, RecipeChoices, recipe_choices
from darksynth.transforms.low_light import (
    check_darkening,
    check_image,
    dataloader_worker_seed,
    low_light,
    mix_seed,
    transform_recipe,
)

# Importing albumentations otherwise asks the network for a newer version (and warns when offline).
os.environ.setdefault("NO_ALBUMENTATIONS_UPDATE", "1")
try:
    from albumentations.core.transforms_interface import ImageOnlyTransform
except ImportError as error:  # pragma: no cover - depends on the environment
    raise ImportError(
        "darksynth.transforms.AlbumentationsLowLight needs albumentations 2.x: pip install 'albumentations>=2.0'"
    ) from error

_SEED_LIMIT = 2**63 - 1

SerializedDarkening = str | Mapping[str, float] | None
"""The darkening as it is stored for albumentations' serialisation: "profile", None or {"alpha", "gamma"}."""


def _darkening_choice(darkening: DarkeningChoice | Mapping[str, float]) -> DarkeningChoice:
    """The darkening as the recipe takes it, checked, from that or from its serialised form."""
    if isinstance(darkening, Mapping):
        if set(darkening) != {"alpha", "gamma"}:
            raise ValueError(f"darkening as a mapping must have alpha and gamma, got {dict(darkening)!r}")
        return Darkening(alpha=float(darkening["alpha"]), gamma=float(darkening["gamma"]))
    return check_darkening(darkening)


def _serializable_darkening(darkening: DarkeningChoice) -> SerializedDarkening:
    if isinstance(darkening, Darkening):
        return {"alpha": darkening.alpha, "gamma": darkening.gamma}
    return darkening


def _hwc_to_tensor(image: np.ndarray, where: str) -> torch.Tensor:
    """(H, W) or (H, W, C) array -> (C, H, W) tensor; with a leading axis, (N, ...) -> (N, C, H, W)."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f"{where}: expected a numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8 and image.dtype not in (np.float32, np.float64):
        raise ValueError(f"{where}: unsupported dtype {image.dtype}; use uint8, or float32 in [0, 1]")
    grey = image.ndim == 2 or (where == "images" and image.ndim == 3)
    if not grey and image.shape[-1] not in (1, 3):
        raise ValueError(f"{where}: expected 1 (grey) or 3 (RGB) channels in the last axis, got shape {image.shape}")
    tensor = numpy_to_tensor(image)
    return tensor.unsqueeze(-1).movedim(-1, -3) if grey else tensor.movedim(-1, -3)


class AlbumentationsLowLight(ImageOnlyTransform):  # type: ignore[misc]  # albumentations ships no type hints
    """Darkening and sensor noise from a noise profile, for ``albumentations.Compose``.

    Targets: ``image`` (H, W) or (H, W, C) with C = 1 or 3, uint8 or float32 in [0, 1]; the result keeps shape
    and dtype (float output on 8-bit levels unless ``round_to_8bit`` is False). ``images`` and ``volume``
    (N, H, W[, C]) are one clip: its frames share one parameter draw and the temporal banding pattern, with
    new noise in every frame.

    Args:
        profile: the noise profile, a path to one, or a decoded profile document (stored as the document, so
            ``A.to_dict`` / ``A.from_dict`` round-trip the transform).
        round_to_8bit: round float output to 8-bit levels, as a camera file stores it.
        p: probability of applying the transform (albumentations' convention, 0.5 by default).
        choices: the recipe's choices (:class:`darksynth.recipe.RecipeChoices`), as ``LowLight`` takes them;
            ``darkening`` also as {"alpha": a, "gamma": g}, the form it is serialised in. A replay shows the drawn
            values, the colour cast (``colour_scale``) and where a drawn camera came from (``camera``).
    """

    def __init__(
        self,
        profile: Profile | str | Path | dict[str, Any],
        round_to_8bit: bool = True,
        p: float = 0.5,
        **choices: Unpack[RecipeChoices],
    ) -> None:
        if isinstance(p, bool) or not isinstance(p, int | float) or not 0.0 <= p <= 1.0:
            raise ValueError(f"p must be a probability in [0, 1], got {p!r}")
        super().__init__(p=p)
        if "darkening" in choices:
            choices["darkening"] = _darkening_choice(choices["darkening"])
        self.recipe = transform_recipe(profile, choices)
        # albumentations serialises the attributes its init arguments name: the recipe's choices as JSON values.
        self.profile = profile_to_dict(self.recipe.profile)
        self.round_to_8bit = bool(round_to_8bit)
        for name, value in recipe_choices(self.recipe).items():
            setattr(self, name, value)
        self.darkening = _serializable_darkening(self.recipe.darkening)

    def get_transform_init_args_names(self) -> tuple[str, ...]:
        return ("profile", "round_to_8bit", *recipe_choices(self.recipe))

    def get_params(self) -> dict[str, Any]:
        """The seed of this call, from albumentations' generator (and the DataLoader worker's seed)."""
        seed = int(self.random_generator.integers(0, _SEED_LIMIT))
        worker_seed = dataloader_worker_seed()
        if worker_seed is not None:
            seed = mix_seed("albumentations", seed, "worker", worker_seed)
        return {"seed": seed}

    def get_params_dependent_on_data(self, params: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
        """The parameters of this call's image or clip, drawn from its seed: ``alpha`` and ``gamma`` (None without
        darkening), the ``noise`` and ``light`` values as a profile writes them (a drawn camera's among them, and
        ``camera`` where it came from, None without one). A replay shows and applies these."""
        seed = int(params["seed"])
        clean = check_image(_target_tensor(data))
        generator = torch.Generator().manual_seed(mix_seed("parameters", seed))
        first = clean if clean.dim() == 3 else clean[0]
        drawn = self.recipe.choose(generator, first)
        darkening = drawn.darkening
        return {
            "seed": seed,
            "alpha": None if darkening is None else darkening.alpha,
            "gamma": None if darkening is None else darkening.gamma,
            "noise": drawn.noise.to_json("noise"),
            "light": drawn.noise.to_json("light"),
            "colour_scale": None if drawn.colour_scale is None else list(drawn.colour_scale),
            "camera": None if drawn.camera is None else drawn.camera.to_json(),
        }

    def _low_light(self, clean: torch.Tensor, drawn: Mapping[str, Any]) -> torch.Tensor:
        alpha, gamma = drawn["alpha"], drawn["gamma"]
        colour_scale = drawn.get("colour_scale")
        parameters = ClipParameters(
            noise=NoiseValues.from_json({**drawn["noise"], **drawn["light"]}),
            darkening=None if alpha is None or gamma is None else Darkening(alpha=alpha, gamma=gamma),
            colour_scale=None if colour_scale is None else tuple(colour_scale),
        )
        result = low_light(
            check_image(clean),
            self.recipe,
            generator=torch.Generator().manual_seed(mix_seed("noise", int(drawn["seed"]))),
            round_to_8bit=self.round_to_8bit,
            parameters=parameters,
        )
        assert isinstance(result.image, torch.Tensor)  # a tensor input gives a tensor result
        return result.image

    def apply(self, img: np.ndarray, **params: Any) -> np.ndarray:
        """The low-light version of one (H, W) or (H, W, C) image with the parameters drawn for it."""
        if not isinstance(img, np.ndarray) or img.ndim not in (2, 3):
            raise ValueError(f"image: expected an (H, W) or (H, W, C) array, got {_describe(img)}")
        noisy = self._low_light(_hwc_to_tensor(img, "image"), params)
        return tensor_to_numpy(noisy.movedim(-3, -1)).reshape(img.shape)

    def apply_to_images(self, images: np.ndarray, **params: Any) -> np.ndarray:
        """The low-light version of a clip (N, H, W) or (N, H, W, C): one parameter draw for all frames."""
        if not isinstance(images, np.ndarray) or images.ndim not in (3, 4):
            raise ValueError(f"images: expected an (N, H, W) or (N, H, W, C) array, got {_describe(images)}")
        noisy = self._low_light(_hwc_to_tensor(images, "images"), params)
        return tensor_to_numpy(noisy.movedim(-3, -1)).reshape(images.shape)

    def apply_to_volume(self, volume: np.ndarray, **params: Any) -> np.ndarray:
        return self.apply_to_images(volume, **params)


def _target_tensor(data: Mapping[str, Any]) -> torch.Tensor:
    """The input of a call as a tensor: ``image`` (C, H, W), else ``images`` or ``volume`` as one clip."""
    for key in ("image", "images", "volume"):
        if key in data:
            return _hwc_to_tensor(np.asarray(data[key]), "image" if key == "image" else "images")
    raise ValueError(f"AlbumentationsLowLight needs an image, images or volume target, got {sorted(data)}")


def _describe(value: object) -> str:
    if isinstance(value, np.ndarray):
        return f"shape {value.shape}"
    return type(value).__name__
