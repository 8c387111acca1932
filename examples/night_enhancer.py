"""A low-light enhancer for one camera, trained on darksynth data made from a few of its dark photos.

The enhancement counterpart of ``examples/night_denoiser.py`` and the paper's own downstream experiment
(docs/tutorial.md has the figures):

1. ``darksynth estimate`` on the camera's dark photos that are not test images (``--references DIR``: every image
   there whose name is not a test pair's), with the default model and with the paper's (``--model paper``);
2. each clean training image darkened as ``darksynth.transforms.LowLight`` darkens it: its exposure matched to the
   reference's tones on the whole image (``LowLight(...).sample(image).parameters["darkening"]``), for
   ``--exposures`` references drawn per image, so that the training exposures cover the spread of the references'
   (a user has several dark photos, not one mean); then random crops, each with its own noise draw through a
   ``DataLoader`` with workers;
3. a small U-Net trained to map the synthetic low-light crop back to the clean one (a progress bar per method) on:
   ``darksynth`` (darkening and noise of the profiles), ``darkening-only`` (the same darkenings, no noise),
   ``darksynth-paper`` (the paper's white noise model, estimated the same way, with its own matched darkening), and
   what a user of albumentations writes for low light: ``MultiplicativeNoise`` (brightness x U(0.05, 0.3)) and
   ``RandomGamma`` (gamma 1-2.5) followed by ``GaussNoise`` (``albu-gamma-gauss``) or ``ISONoise``
   (``albu-gamma-iso``);
4. with ``--methods ...,real-pairs``, the ceiling: the same enhancer trained on the camera's real pairs of the other
   fold (two folds alternating in name order), tested on its own fold's (not run by default: two trainings a seed);
   with ``albu-gamma`` (albumentations' darkening, no noise) and ``albu-gamma-darksynth`` (that darkening, then the
   noise of a darksynth profile on it), which tell the darkening's share from the noise's (not run by default);
5. every enhancer tested on the real low -> normal-light pairs (``--pairs DIR``: ``low/NAME``, ``high/NAME``): PSNR,
   SSIM and GT-mean PSNR (the output scaled to the normal-light image's mean first, which leaves out the global
   brightness the pair's two exposures do not fix), per pair and averaged, for each of ``--seeds``; written to
   ``OUT/results.json`` and drawn in ``OUT/comparison.png``.

Run from the repository root (a CPU, some minutes per method and seed with the defaults)::

    .venv/bin/python examples/night_enhancer.py --out night-enhancer

With a GPU, a wider net and a longer training::

    .venv/bin/python examples/night_enhancer.py --device cuda --width 32 --steps 20000 --batch 16 --out enhancer-gpu

``--normalise-exposure`` gives the enhancer its input scaled to one mean and the log of the input's own mean;
``--match-colour`` gives each training input its reference's colour cast; ``--gain-draw`` chooses how the training
darkenings are drawn (``matched`` per image, ``even`` in log gain, ``pooled`` from other images, ``profile``: the
references' own readings, ``profile-range``: between them); ``--noise-scale F`` multiplies darksynth's noise by F
about the darkened image, to see how much its strength matters. ``--target-tone A,E`` trains toward ``A * clean ** E``
(targets flatter and brighter than the clean images for E under 1, as LOL's normal-light images are);
``--target-tone folds`` reads A and E from the normal-light images the enhancer is to imitate, none of them tested:
each fold of the test pairs (two, alternating in name order, as the ceiling's) is tested on enhancers trained toward
the tone of the other fold's normal-light images (the median of their tones against average clean scenes), two
trainings a seed (docs/tutorial.md has what each does).

albumentations' defaults do not darken (``RandomGamma``: gamma 0.8-1.2) and its default ``GaussNoise`` (20-44 % of
full scale) would bury a dark image, so the albumentations methods take the paper's darkening ranges (the exposure
and gamma a user of the paper's recipe would draw) and Gaussian noise of 1-5 % of full scale (2.5-13 levels); ISONoise
keeps its defaults.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.data import DataLoader, Dataset

from darksynth.io.atomic import atomic_output, write_text_atomic

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DEFAULT_PAIRS = SHARED / "enhance-pairs" / "lol"
DEFAULT_REFERENCES = SHARED / "real-lowlight" / "images" / "lol"
DEFAULT_CLEAN = tuple(SHARED / "clean" / "images" / name for name in ("kodak24", "cbsd68", "mcmaster", "mirflickr"))
METHODS = ("darksynth", "darkening-only", "darksynth-paper", "albu-gamma-gauss", "albu-gamma-iso")
"""What the enhancer is trained on by default (module docstring)."""
REAL_PAIRS = "real-pairs"
"""The ceiling, run only when ``--methods`` names it: trained on the camera's real pairs of the other fold (the
pairs alternate between two folds in name order), tested on those of its own; two trainings per seed."""
DIAGNOSTIC_METHODS = ("albu-gamma", "albu-gamma-darksynth", "paper-range-float")
"""Run only when ``--methods`` names them: albumentations' darkening alone, and with darksynth's noise on it; the
same ranges (brightness x U(0.05, 0.3), gamma U(1, 2.5)) computed in float and rounded to 8-bit levels once, at the
end (albumentations rounds the brightened image before its gamma, which posterises the darkest inputs)."""
TRAINING_BRIGHTNESS = (0.05, 0.3)
"""The brightness factor the albumentations methods and ``paper-range-float`` draw (the paper's alpha range)."""
TRAINING_GAMMA = (1.0, 2.5)
"""The exponent they draw after it (``RandomGamma``'s ``gamma_limit`` in percent: 100-250)."""
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
NORMALISED_MEAN = 0.5
"""The mean an input is scaled to with ``--normalise-exposure`` (about that of a normal-light photo)."""

LowLightCrop = Callable[[int, torch.Tensor, int], torch.Tensor]
"""A way to make training inputs: (the clean image's index, its clean crop (3, H, W) float in [0, 1], the sample's
seed) -> the low-light crop."""


class ExampleError(Exception):
    """Bad input: one line for the user, exit status 2."""


@dataclass(frozen=True)
class TestPair:
    name: str
    low: torch.Tensor
    """(3, H, W) float in [0, 1]."""
    high: torch.Tensor


def _read(path: Path) -> torch.Tensor:
    from darksynth.errors import DarksynthError
    from darksynth.io.images import read_image

    try:
        pixels = np.asarray(read_image(path).pixels)
    except DarksynthError as error:
        raise ExampleError(f"{path}: {error}") from None
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype != np.uint8:
        raise ExampleError(f"{path}: not an 8-bit RGB image")
    return torch.from_numpy(np.ascontiguousarray(pixels.transpose(2, 0, 1)))


def _images(folder: Path) -> list[Path]:
    if not folder.is_dir():
        raise ExampleError(f"{folder}: no such folder")
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith("."))


def read_test_pairs(root: Path) -> list[TestPair]:
    """The pairs ``low/NAME``, ``high/NAME`` of ``root``."""
    lows = _images(root / "low")
    pairs = []
    for low in lows:
        high = root / "high" / low.name
        if not high.is_file():
            raise ExampleError(f"{low}: no normal-light image {high}")
        pair = TestPair(low.name, _read(low).float() / 255.0, _read(high).float() / 255.0)
        if pair.low.shape != pair.high.shape:
            raise ExampleError(f"{low}: {tuple(pair.low.shape)} but its normal-light image is {tuple(pair.high.shape)}")
        pairs.append(pair)
    if not pairs:
        raise ExampleError(f"{root}: no pairs low/NAME, high/NAME")
    return pairs


def reference_photos(folder: Path, test_pairs: list[TestPair]) -> list[Path]:
    """The camera's dark photos that are not test images (by name)."""
    tested = {Path(pair.name).stem for pair in test_pairs}
    references = [path for path in _images(folder) if path.stem not in tested]
    if not references:
        raise ExampleError(f"{folder}: every image is a test image; the profiles need other dark photos")
    return references


def estimate_profiles(references: list[Path], folder: Path, model: str, device: str) -> list[Path]:
    """``darksynth estimate REFERENCE --model MODEL --out PROFILE`` for each reference, as a user runs it."""
    folder.mkdir(parents=True, exist_ok=True)
    profiles = []
    for reference in references:
        profile = folder / f"{reference.stem}.json"
        command = [sys.executable, "-m", "darksynth", "estimate", str(reference), "--out", str(profile)]
        command += ["--model", model, "--device", device]
        finished = subprocess.run(command, capture_output=True, text=True, check=False)
        if finished.returncode != 0:
            raise ExampleError(f"{reference}: darksynth estimate failed: {finished.stderr.strip().splitlines()[-1]}")
        profiles.append(profile)
    return profiles


def read_clean_images(folders: list[Path], crop: int) -> list[torch.Tensor]:
    """Every image of the folders with both sides at least ``crop``, as uint8 tensors (3, H, W)."""
    images = [image for folder in folders for image in map(_read, _images(folder)) if min(image.shape[1:]) >= crop]
    if not images:
        raise ExampleError(f"{', '.join(map(str, folders))}: no RGB image with both sides of at least {crop} px")
    return images


class ProfileExposures:
    """For each clean image, ``exposures`` of the profiles drawn at random, each with the darkening ``LowLight``
    gives that whole image with that profile (its exposure matched to the reference's tones) and, with
    ``match_colour``, the reference's colour cast on that image (``apply --match-colour``: per-channel factors on
    the clean image, alpha taking the rest)."""

    def __init__(
        self,
        images: list[torch.Tensor],
        profiles: list[Path],
        exposures: int,
        seed: int,
        gain_draw: str = "matched",
        match_colour: bool = False,
    ) -> None:
        from darksynth import Darkening, darken, load_profile
        from darksynth.exposure import matched_colour
        from darksynth.transforms import LowLight

        self.profiles = [load_profile(path) for path in profiles]
        self.gain_draw = gain_draw
        draw = random.Random(seed)
        self.choices: list[list[tuple[int, float, float, float]]] = []
        self.colour_scales: list[list[tuple[float, float, float] | None]] = []
        for image in images:
            chosen = draw.sample(range(len(self.profiles)), min(exposures, len(self.profiles)))
            row, scales = [], []
            for index in chosen:
                parameters = LowLight(self.profiles[index], seed=0).sample(image).parameters
                assert isinstance(parameters, dict)
                alpha, gamma = float(parameters["darkening"]["alpha"]), float(parameters["darkening"]["gamma"])
                colour = (
                    matched_colour(image, self.profiles[index].tone, Darkening(alpha, gamma)) if match_colour else None
                )
                if colour is not None:
                    alpha = colour[1].alpha
                scales.append(None if colour is None else colour[0])
                unit = image.double() / 255.0
                gain = float(unit.mean() / darken(unit, alpha, gamma).mean().clamp_min(1e-6))
                row.append((index, alpha, gamma, gain))
            self.choices.append(row)
            self.colour_scales.append(scales)
        gains = np.log([choice[3] for row in self.choices for choice in row])
        self.log_gain_range = (float(np.percentile(gains, 5)), float(np.percentile(gains, 95)))
        self.read_darkenings: list[tuple[float, float]] = []
        if gain_draw in ("profile", "profile-range"):
            if any(profile.darkening is None for profile in self.profiles):
                raise ValueError(f"--gain-draw {gain_draw}: a profile holds no darkening")
            self.read_darkenings = [
                (profile.darkening.alpha, profile.darkening.gamma)
                for profile in self.profiles
                if profile.darkening is not None
            ]

    def pick(self, image: int, seed: int) -> tuple[int, float, float, tuple[float, float, float] | None]:
        """(profile index, alpha, gamma, colour scale or None) for a sample of the image: a matched darkening of
        one of its references, with ``--gain-draw even`` its alpha scaled to a gain drawn evenly in log over the
        5th-95th percentile of the matched gains (the darkening's gain is inversely proportional to alpha), with
        ``--gain-draw pooled`` the darkening matched on another clean image drawn at random (the references'
        exposures, independent of this scene, as a camera's exposure does not look at the scene; no colour cast),
        with ``--gain-draw profile`` the darkening a reference drawn at random was read to have (its profile's
        ``darkening``, the network's reading of the reference alone: independent of the scene and of any clean
        image's tones; no colour cast), with ``--gain-draw profile-range`` alpha and gamma each drawn evenly
        between the smallest and the largest the references were read to have (their spread, not only their eight
        values)."""
        if self.gain_draw in ("profile", "profile-range"):
            draw = random.Random(seed)
            index = draw.randrange(len(self.profiles))
            if self.gain_draw == "profile":
                return index, *self.read_darkenings[index], None
            alphas, gammas = zip(*self.read_darkenings, strict=True)
            return index, draw.uniform(min(alphas), max(alphas)), draw.uniform(min(gammas), max(gammas)), None
        if self.gain_draw == "pooled":
            draw = random.Random(seed)
            row = self.choices[draw.randrange(len(self.choices))]
            index, alpha, gamma, _ = row[draw.randrange(len(row))]
            return index, alpha, gamma, None
        choice = seed % len(self.choices[image])
        index, alpha, gamma, gain = self.choices[image][choice]
        if self.gain_draw == "even":
            target = float(np.exp(random.Random(seed).uniform(*self.log_gain_range)))
            alpha *= gain / target
        return index, alpha, gamma, self.colour_scales[image][choice]


def scaled_noise(noisy: torch.Tensor, darkened: torch.Tensor, scale: float) -> torch.Tensor:
    """``noisy`` with its noise about ``darkened`` (the same image without noise) times ``scale``, on 8-bit levels
    (``--noise-scale``: how much the training noise's strength matters); ``noisy`` itself for a scale of 1."""
    if scale == 1.0:
        return noisy
    return ((darkened + scale * (noisy - darkened)).clamp(0.0, 1.0) * 255.0).round() / 255.0


def profile_low_light(exposures: ProfileExposures, *, noise: bool, noise_scale: float = 1.0) -> LowLightCrop:
    """darksynth's transform with the darkening matched on the crop's whole image, with its profile's noise (times
    ``noise_scale``), or without noise: darkening only, rounded to 8-bit levels as a camera file is."""
    from darksynth import Darkening, darken
    from darksynth.transforms import LowLight

    def low_light(image: int, clean: torch.Tensor, seed: int) -> torch.Tensor:
        index, alpha, gamma, colour_scale = exposures.pick(image, seed)
        if colour_scale is not None:
            clean = clean * torch.tensor(colour_scale, dtype=clean.dtype)[:, None, None]

        def darkened() -> torch.Tensor:
            return (darken(clean, alpha, gamma) * 255.0).round() / 255.0

        if not noise:
            return darkened()
        noisy = LowLight(exposures.profiles[index], darkening=Darkening(alpha, gamma))(clean, seed=seed)
        # The darkened image without noise is needed only to scale the noise about it.
        return noisy if noise_scale == 1.0 else scaled_noise(noisy, darkened(), noise_scale)

    return low_light


def albumentations_low_light(
    noise: str, exposures: ProfileExposures | None = None, noise_scale: float = 1.0
) -> LowLightCrop:
    """albumentations: brightness x U(0.05, 0.3), gamma U(1, 2.5), then ``noise``: ``"gauss"``, ``"iso"`` (module
    docstring), ``"none"``, or ``"darksynth"`` (the noise of one of the ``exposures``' profiles, drawn on the
    darkened image as ``LowLight(profile, darkening=None)`` draws it, times ``noise_scale``)."""
    if noise not in ("gauss", "iso", "none", "darksynth"):
        raise ValueError(f'noise must be "gauss", "iso", "none" or "darksynth", got {noise!r}')
    if noise == "darksynth" and exposures is None:
        raise ValueError('noise "darksynth" needs the exposures whose profiles it draws')
    os.environ.setdefault("NO_ALBUMENTATIONS_UPDATE", "1")  # albumentations asks the network for updates otherwise
    import albumentations as A

    from darksynth.transforms import LowLight

    darkening = [
        A.MultiplicativeNoise(multiplier=TRAINING_BRIGHTNESS, p=1.0),
        A.RandomGamma(gamma_limit=tuple(round(100 * g) for g in TRAINING_GAMMA), p=1.0),  # in percent
    ]
    albumentations_noise = {"gauss": [A.GaussNoise(std_range=(0.01, 0.05), p=1.0)], "iso": [A.ISONoise(p=1.0)]}
    compose = A.Compose([*darkening, *albumentations_noise.get(noise, [])])

    def low_light(image: int, clean: torch.Tensor, seed: int) -> torch.Tensor:
        compose.set_random_seed(seed)
        pixels = (clean.permute(1, 2, 0).clamp(0.0, 1.0).numpy() * 255.0).round().astype(np.uint8)
        low = torch.from_numpy(np.ascontiguousarray(compose(image=pixels)["image"])).permute(2, 0, 1).float() / 255.0
        if exposures is not None and noise == "darksynth":
            profile = exposures.profiles[exposures.pick(image, seed)[0]]
            low = scaled_noise(LowLight(profile, darkening=None)(low, seed=seed), low, noise_scale)
        return low

    return low_light


def float_paper_range_low_light(image: int, clean: torch.Tensor, seed: int) -> torch.Tensor:
    """``(k * clean) ** g`` with k ~ U(:data:`TRAINING_BRIGHTNESS`) and g ~ U(:data:`TRAINING_GAMMA`) drawn from
    ``seed``, rounded to 8-bit levels once (the ``paper-range-float`` diagnostic)."""
    draw = random.Random(seed)
    brightness, gamma = draw.uniform(*TRAINING_BRIGHTNESS), draw.uniform(*TRAINING_GAMMA)
    return ((brightness * clean.clamp(0.0, 1.0)) ** gamma * 255.0).round() / 255.0


class LowLightCrops(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """``length`` random crops of the clean images with their low-light versions; sample ``i`` is the same in every
    worker and run of a seed (its crop and its draws come from ``seed`` and ``i`` alone). The target is the clean
    crop rendered by ``target_tone`` (a, e): ``a * clean ** e`` (``--target-tone``, a diagnostic: for e under 1 the
    targets are flatter than the clean images, as LOL's normal-light images are; the input is made from the clean
    crop as it is)."""

    def __init__(
        self,
        images: list[torch.Tensor],
        low_light: LowLightCrop,
        crop: int,
        length: int,
        seed: int,
        target_tone: tuple[float, float] = (1.0, 1.0),
    ) -> None:
        self.images, self.low_light, self.crop, self.length, self.seed = images, low_light, crop, length, seed
        self.target_tone = target_tone

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, index: int) -> tuple[torch.Tensor, torch.Tensor]:
        sample_seed = self.seed * 1_000_003 + index
        draw = random.Random(sample_seed)
        image_index = draw.randrange(len(self.images))
        image = self.images[image_index]
        top = draw.randrange(image.shape[1] - self.crop + 1)
        left = draw.randrange(image.shape[2] - self.crop + 1)
        clean = image[:, top : top + self.crop, left : left + self.crop].float() / 255.0
        if draw.random() < 0.5:
            clean = clean.flip(-1)
        scale, exponent = self.target_tone
        target = clean if self.target_tone == (1.0, 1.0) else (scale * clean.pow(exponent)).clamp(0.0, 1.0)
        return self.low_light(image_index, clean, sample_seed).float(), target


class RealPairCrops(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """``length`` random crops of real pairs, the low crop and the same crop of the normal-light image, drawn from
    ``seed`` and the sample's index alone (as :class:`LowLightCrops`)."""

    def __init__(self, pairs: list[TestPair], crop: int, length: int, seed: int) -> None:
        self.pairs, self.crop, self.length, self.seed = pairs, crop, length, seed

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, index: int) -> tuple[torch.Tensor, torch.Tensor]:
        draw = random.Random(self.seed * 1_000_003 + index)
        pair = self.pairs[draw.randrange(len(self.pairs))]
        top = draw.randrange(pair.low.shape[1] - self.crop + 1)
        left = draw.randrange(pair.low.shape[2] - self.crop + 1)
        low, high = (image[:, top : top + self.crop, left : left + self.crop] for image in (pair.low, pair.high))
        return (low.flip(-1), high.flip(-1)) if draw.random() < 0.5 else (low, high)


def target_tone_of(images: list[torch.Tensor]) -> tuple[float, float]:
    """(A, E): the median over ``images`` (3, H, W) in [0, 1] of each one's tone against average clean scenes,
    ``image ~ A * scene ** E`` (the darkening's fit without the paper's prior, :func:`fit_darkening`): the rendering
    an enhancer trained toward ``A * clean ** E`` imitates."""
    from darksynth.light.tone_fit import fit_darkening
    from darksynth.light.tones import tone_quantiles

    readings = [fit_darkening(tone_quantiles(image.float()), use_prior=False).darkening for image in images]
    scale = float(np.median([reading.alpha for reading in readings]))
    exponent = float(np.median([1.0 / reading.gamma for reading in readings]))
    return min(scale, 1.0), exponent


def folds(pairs: list[TestPair]) -> list[tuple[list[TestPair], list[TestPair]]]:
    """(the other fold's pairs, this fold's) for the two folds, alternating in name order."""
    return [
        (
            [pair for index, pair in enumerate(pairs) if index % 2 != fold],
            [pair for index, pair in enumerate(pairs) if index % 2 == fold],
        )
        for fold in (0, 1)
    ]


def real_pair_scores(pairs: list[TestPair], arguments: argparse.Namespace, seed: int) -> dict[str, dict[str, float]]:
    """The ceiling's scores for one seed: each fold's pairs tested on an enhancer trained on the other fold's."""
    if len(pairs) < 2:
        raise ExampleError(f"{arguments.pairs}: {REAL_PAIRS} needs at least 2 pairs (one to train on, one to test)")
    scores: dict[str, dict[str, float]] = {}
    for fold, (training, tested) in enumerate(folds(pairs)):
        torch.manual_seed(seed)
        dataset = RealPairCrops(training, arguments.crop, arguments.steps * arguments.batch, seed)
        model = train(dataset, arguments, seed, f"{REAL_PAIRS} (fold {fold + 1} of 2), seed {seed}")
        scores |= test(model, tested, arguments.device)
    return {pair.name: scores[pair.name] for pair in pairs}


def _block(inputs: int, outputs: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(inputs, outputs, 3, padding=1, padding_mode="reflect"),
        nn.LeakyReLU(0.1, inplace=True),
        nn.Conv2d(outputs, outputs, 3, padding=1, padding_mode="reflect"),
        nn.LeakyReLU(0.1, inplace=True),
    )


class Enhancer(nn.Module):
    """A small U-Net (three scales) whose coarsest features also see their mean over the whole input: how bright
    the image is overall sets the gain everywhere. Any input size (padded to a multiple of 4).

    With ``normalise_exposure`` the net sees its input scaled to a mean of :data:`NORMALISED_MEAN` and, beside the
    coarsest features, the log of the input's own mean: the brightness of the output need not be reached by
    scaling the input through the layers (a 16x gain and a 3.5x gain start from the same level), and how dark the
    input was, which sets how much noise it holds, is still known."""

    def __init__(self, width: int = 16, *, seed: int = 0, normalise_exposure: bool = False) -> None:
        super().__init__()
        torch.manual_seed(seed)  # the same initial weights for every method of a seed
        self.normalise_exposure = normalise_exposure
        self.encode1, self.encode2 = _block(3, width), _block(width, 2 * width)
        self.encode3 = _block(2 * width, 4 * width)
        overall = 4 * width + (1 if normalise_exposure else 0)
        self.decode2 = _block(4 * width + overall + 2 * width, 2 * width)
        self.decode1 = _block(2 * width + width, width)
        self.out = nn.Conv2d(width, 3, 1)

    def forward(self, low: torch.Tensor) -> torch.Tensor:
        height, width = low.shape[-2:]
        level = low.mean(dim=(-3, -2, -1), keepdim=True).clamp_min(1.0 / 255.0) if self.normalise_exposure else None
        if level is not None:
            low = low * (NORMALISED_MEAN / level)
        padded = nn.functional.pad(low, (0, -width % 4, 0, -height % 4), mode="reflect")
        first = self.encode1(padded)
        second = self.encode2(nn.functional.avg_pool2d(first, 2))
        third = self.encode3(nn.functional.avg_pool2d(second, 2))
        overall = third.mean(dim=(-2, -1), keepdim=True).expand_as(third)
        if level is not None:
            overall = torch.cat([overall, level.log().expand(-1, 1, *third.shape[-2:])], 1)
        up = nn.functional.interpolate(torch.cat([third, overall], 1), scale_factor=2.0, mode="bilinear")
        decoded = self.decode2(torch.cat([up, second], 1))
        up = nn.functional.interpolate(decoded, scale_factor=2.0, mode="bilinear")
        output: torch.Tensor = self.out(self.decode1(torch.cat([up, first], 1)))
        return output[..., :height, :width]


def train(
    dataset: Dataset[tuple[torch.Tensor, torch.Tensor]], arguments: argparse.Namespace, seed: int, label: str
) -> Enhancer:
    """The enhancer trained with Adam and an L1 loss, cosine-decayed, one pass over ``dataset`` in batches of
    ``--batch``."""
    from rich.progress import Progress

    model = Enhancer(arguments.width, seed=seed, normalise_exposure=arguments.normalise_exposure).to(arguments.device)
    optimiser = torch.optim.Adam(model.parameters(), lr=arguments.learning_rate)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, arguments.steps)
    loader = DataLoader(dataset, batch_size=arguments.batch, num_workers=arguments.workers, shuffle=False)
    with Progress(transient=True) as progress:
        task = progress.add_task(f"training on {label}", total=arguments.steps)
        for low, clean in loader:
            loss = nn.functional.l1_loss(model(low.to(arguments.device)), clean.to(arguments.device))
            optimiser.zero_grad()
            loss.backward()  # type: ignore[no-untyped-call]
            optimiser.step()
            schedule.step()
            progress.update(task, advance=1, description=f"training on {label}: loss {loss.detach().item():.4f}")
    return model


def psnr(image: torch.Tensor, reference: torch.Tensor) -> float:
    return float(10.0 * torch.log10(1.0 / (image - reference).square().mean().clamp_min(1e-12)))


def pair_scores(output: torch.Tensor, pair: TestPair) -> dict[str, float]:
    """PSNR, SSIM and GT-mean PSNR (the output scaled to the normal-light image's mean, then clipped) of an output,
    with the gain the pair needs (the normal-light image's mean over the low one's)."""
    from skimage.metrics import structural_similarity

    output = output.double().clamp(0.0, 1.0)
    high = pair.high.double()
    scaled = (output * high.mean() / output.mean().clamp_min(1e-6)).clamp(0.0, 1.0)
    ssim = structural_similarity(  # type: ignore[no-untyped-call]
        output.numpy(), high.numpy(), channel_axis=0, data_range=1.0
    )
    return {
        "psnr": psnr(output, high),
        "ssim": float(ssim),
        "gt_mean_psnr": psnr(scaled, high),
        "gain": float(high.mean() / pair.low.double().mean().clamp_min(1e-6)),
    }


def test(model: nn.Module | None, pairs: list[TestPair], device: str) -> dict[str, dict[str, float]]:
    """Per test pair, the scores of the model's output (None: the low-light input as it is)."""
    scores = {}
    for pair in pairs:
        if model is None:
            output = pair.low
        else:
            model.eval()
            with torch.no_grad():
                output = model(pair.low[None].to(device))[0].cpu()
        scores[pair.name] = pair_scores(output, pair)
    return scores


def summary(per_seed: list[dict[str, dict[str, float]]]) -> dict[str, Any]:
    """Mean and spread (std over seeds of each seed's mean over pairs) of each score, and per pair its mean."""
    keys = ("psnr", "ssim", "gt_mean_psnr")
    means = {key: [float(np.mean([row[key] for row in scores.values()])) for scores in per_seed] for key in keys}
    pairs = per_seed[0].keys()
    return {
        **{key: float(np.mean(values)) for key, values in means.items()},
        **{f"{key}_spread": float(np.std(values)) for key, values in means.items()},
        "per_seed": means,
        "per_pair": {
            name: {key: float(np.mean([scores[name][key] for scores in per_seed])) for key in (*keys, "gain")}
            for name in pairs
        },
    }


def plot(results: dict[str, dict[str, Any]], path: Path, title: str) -> None:
    """PSNR and GT-mean PSNR per training method (bars with their spread over seeds), the low input as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = [name for name in results if name != "low input"]
    figure, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    for axis, key, unit in ((axes[0], "psnr", "PSNR (dB)"), (axes[1], "gt_mean_psnr", "GT-mean PSNR (dB)")):
        values = [results[name][key] for name in methods]
        axis.bar(methods, values, yerr=[results[name][f"{key}_spread"] for name in methods], color="#4c72b0")
        axis.axhline(results["low input"][key], color="#c44e52", linestyle="--", label="low input")
        axis.set_ylim(min([*values, results["low input"][key]]) - 2.0, None)
        axis.set_ylabel(unit)
        axis.tick_params(axis="x", rotation=20)
        axis.legend(loc="lower right", fontsize=8)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    with atomic_output(path) as temporary:
        figure.savefig(temporary, dpi=120, format="png")
    plt.close(figure)


def _low_lights(arguments: argparse.Namespace, images: list[torch.Tensor], references: list[Path]) -> Any:
    """Each method's way to make training inputs, built the first time a method asks (profiles and exposures are
    shared by the methods that use them)."""
    built: dict[str, Any] = {}

    def exposures(model: str) -> ProfileExposures:
        if model not in built:
            profiles = estimate_profiles(references, arguments.out / "profiles" / model, model, arguments.device)
            built[model] = ProfileExposures(
                images, profiles, arguments.exposures, arguments.seeds[0], arguments.gain_draw, arguments.match_colour
            )
            low, high = np.exp(built[model].log_gain_range)
            print(f"{model} profiles: matched training gains {low:.1f}-{high:.1f}x (5th-95th percentile)", flush=True)
        exposure: ProfileExposures = built[model]
        return exposure

    def low_light(method: str) -> LowLightCrop:
        if method == "darksynth":
            return profile_low_light(exposures("srgb"), noise=True, noise_scale=arguments.noise_scale)
        if method == "darkening-only":
            return profile_low_light(exposures("srgb"), noise=False)
        if method == "darksynth-paper":
            return profile_low_light(exposures("paper"), noise=True, noise_scale=arguments.noise_scale)
        if method == "paper-range-float":
            return float_paper_range_low_light
        if method == "albu-gamma-darksynth":
            return albumentations_low_light("darksynth", exposures("srgb"), arguments.noise_scale)
        return albumentations_low_light({"albu-gamma-gauss": "gauss", "albu-gamma-iso": "iso"}.get(method, "none"))

    return low_light


def synthetic_scores(
    pairs: list[TestPair],
    images: list[torch.Tensor],
    low_light: LowLightCrop,
    arguments: argparse.Namespace,
    seed: int,
    method: str,
) -> dict[str, dict[str, float]]:
    """One seed's scores of an enhancer trained on ``low_light``'s inputs of the clean ``images``: one training
    toward the ``--target-tone`` given, or with ``folds`` one per fold toward the other fold's tone."""
    length = arguments.steps * arguments.batch
    if arguments.target_tone != "folds":
        torch.manual_seed(seed)
        dataset = LowLightCrops(images, low_light, arguments.crop, length, seed, arguments.target_tone)
        return test(train(dataset, arguments, seed, f"{method}, seed {seed}"), pairs, arguments.device)
    scores: dict[str, dict[str, float]] = {}
    for fold, (other, tested) in enumerate(folds(pairs)):
        tone = target_tone_of([pair.high for pair in other])
        torch.manual_seed(seed)
        dataset = LowLightCrops(images, low_light, arguments.crop, length, seed, tone)
        label = f"{method} toward {tone[0]:.2f} * clean ** {tone[1]:.2f} (fold {fold + 1} of 2), seed {seed}"
        scores |= test(train(dataset, arguments, seed, label), tested, arguments.device)
    return {pair.name: scores[pair.name] for pair in pairs}


def run(arguments: argparse.Namespace) -> dict[str, Any]:
    test_pairs = read_test_pairs(arguments.pairs)
    references = reference_photos(arguments.references, test_pairs)
    arguments.out.mkdir(parents=True, exist_ok=True)
    images = read_clean_images(arguments.clean, arguments.crop)
    low_light = _low_lights(arguments, images, references)
    input_scores = test(None, test_pairs, arguments.device)
    results: dict[str, dict[str, Any]] = {"low input": summary([input_scores])}
    for method in arguments.methods:
        per_seed = []
        for seed in arguments.seeds:
            if method == REAL_PAIRS:
                per_seed.append(real_pair_scores(test_pairs, arguments, seed))
                continue
            per_seed.append(synthetic_scores(test_pairs, images, low_light(method), arguments, seed, method))
        results[method] = summary(per_seed)
        entry = results[method]
        print(
            f"{method:18s} PSNR {entry['psnr']:6.2f} +- {entry['psnr_spread']:.2f} dB  SSIM {entry['ssim']:.4f}  "
            f"GT-mean PSNR {entry['gt_mean_psnr']:6.2f} +- {entry['gt_mean_psnr_spread']:.2f} dB",
            flush=True,
        )
    record = {
        "pairs": str(arguments.pairs),
        "references": [str(path) for path in references],
        "test_pairs": [pair.name for pair in test_pairs],
        "settings": {
            key: getattr(arguments, key)
            for key in (
                "steps",
                "batch",
                "crop",
                "width",
                "normalise_exposure",
                "match_colour",
                "noise_scale",
                "exposures",
                "gain_draw",
                "target_tone",
                "learning_rate",
                "seeds",
                "device",
            )
        },
        "clean": [str(folder) for folder in arguments.clean],
        "results": results,
    }
    write_text_atomic(arguments.out / "results.json", json.dumps(record, indent=2) + "\n")
    title = f"{arguments.pairs.name}: {len(test_pairs)} real low/normal-light pairs, {len(arguments.seeds)} seeds"
    plot(results, arguments.out / "comparison.png", title)
    return record


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=Path, default=DEFAULT_PAIRS)
    parser.add_argument("--references", type=Path, default=DEFAULT_REFERENCES)
    parser.add_argument("--clean", type=Path, action="append", default=None)
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--exposures", type=int, default=3)
    parser.add_argument("--steps", type=int, default=800)
    parser.add_argument(
        "--gain-draw", choices=("matched", "even", "pooled", "profile", "profile-range"), default="matched"
    )
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--crop", type=int, default=96)
    parser.add_argument("--width", type=int, default=16)
    parser.add_argument("--normalise-exposure", action="store_true")
    parser.add_argument("--match-colour", action="store_true")
    parser.add_argument("--noise-scale", type=float, default=1.0)
    parser.add_argument("--target-tone", default="1,1")
    parser.add_argument("--learning-rate", type=float, default=2e-3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, required=True)
    arguments = parser.parse_args(argv)
    arguments.clean = arguments.clean or list(DEFAULT_CLEAN)
    arguments.methods = [name for name in arguments.methods.split(",") if name]
    try:
        arguments.seeds = [int(seed) for seed in arguments.seeds.split(",") if seed]
    except ValueError:
        parser.error(f"--seeds: integers separated by commas, got {arguments.seeds!r}")
    unknown = [name for name in arguments.methods if name not in (*METHODS, REAL_PAIRS, *DIAGNOSTIC_METHODS)]
    if unknown or min(arguments.steps, arguments.batch, arguments.exposures, len(arguments.seeds)) < 1:
        known = ", ".join((*METHODS, REAL_PAIRS, *DIAGNOSTIC_METHODS))
        parser.error(f"methods are {known}; steps, batch, exposures and seeds at least 1")
    if arguments.target_tone != "folds":
        try:
            scale, exponent = (float(value) for value in arguments.target_tone.split(","))
        except ValueError:
            parser.error(f"--target-tone: 'folds' or two numbers A,E, got {arguments.target_tone!r}")
        if not (0.0 < scale <= 1.0 and 0.0 < exponent <= 4.0):
            parser.error("--target-tone: A in (0, 1] and E in (0, 4]")
        arguments.target_tone = (scale, exponent)
    if arguments.crop < 8 or arguments.crop % 4:
        parser.error("--crop must be a multiple of 4 of at least 8")
    return arguments


def main(argv: list[str] | None = None) -> int:
    arguments = parse(argv)
    try:
        run(arguments)
    except ExampleError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {arguments.out / 'results.json'} and {arguments.out / 'comparison.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
