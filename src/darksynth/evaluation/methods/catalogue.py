"""The noise-synthesis methods compared by `darksynth evaluate`, by name.

A method fits its parameters to one real pair (zero-shot methods read only the noisy image; oracle methods
may read the clean one too) and synthesises a noisy version of a clean image with them. The clean image of a
real pair already has the reference's brightness, so no method darkens. Every output is clipped and rounded
to 8-bit levels, as the real noisy image was.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import torch

from darksynth.cameras.prior import CameraPrior, held_out_sets, shipped_prior
from darksynth.errors import DarksynthError
from darksynth.evaluation.methods.albumentations import ALBUMENTATIONS_METHODS, albumentations_method
from darksynth.evaluation.methods.classical import (
    PoissonGaussian,
    add_poisson_gaussian,
    blind_gaussian_sigma,
    blind_poisson_gaussian,
    oracle_poisson_gaussian,
)
from darksynth.evaluation.methods.method import Fit, NoiseMethod, Synthesize
from darksynth.models.den import DEN
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.tensors import to_8bit_levels
from darksynth.training.weights import DENChoice

if TYPE_CHECKING:
    from darksynth.estimation.assemble import Estimate

AWGN_SIGMA = 5.0 / 255.0
"""Fixed sigma of the `awgn` baseline: 5 of 255, the middle of the real sets' noise std (2.2-8.3 of 255 on
polyu and nam-cc15), fixed before any metric was computed."""

PG_FIXED = PoissonGaussian(a=(8e-4, 8e-4, 8e-4), b=((2.0 / 255.0) ** 2,) * 3)
"""Fixed law of the `pg` baseline: var = 8e-4 x + (2/255)^2, a std of 2/255 in black and 5.9/255 at mid-grey,
the same middle of the real sets."""


class MethodUnavailableError(DarksynthError):
    """A method that cannot run here: unknown name or missing weights."""


def _gaussian(sigmas: Sequence[float]) -> PoissonGaussian:
    return PoissonGaussian(a=(0.0, 0.0, 0.0), b=(sigmas[0] ** 2, sigmas[1] ** 2, sigmas[2] ** 2))


def _fixed(law: PoissonGaussian) -> Fit:
    return lambda noisy, clean: law


POISSON_GAUSSIAN_METHODS: dict[str, tuple[str, Fit]] = {
    "awgn": (f"Gaussian, fixed sigma {AWGN_SIGMA * 255:.0f}/255", _fixed(_gaussian([AWGN_SIGMA] * 3))),
    "awgn-blind": (
        "Gaussian, per-channel sigma from skimage.restoration.estimate_sigma on the noisy image",
        lambda noisy, clean: _gaussian(blind_gaussian_sigma(noisy)),
    ),
    "pg": ("Poisson-Gaussian, fixed var = 8e-4 x + (2/255)^2", _fixed(PG_FIXED)),
    "pg-blind": (
        "Poisson-Gaussian fitted on the noisy image alone (smooth blocks, after Foi et al. 2008)",
        lambda noisy, clean: blind_poisson_gaussian(noisy),
    ),
    "pg-oracle": (
        "Poisson-Gaussian fitted with the clean image (variance against intensity, per channel)",
        oracle_poisson_gaussian,
    ),
}
"""The baselines that add Poisson-Gaussian (or Gaussian) noise: name -> (summary, fit); pg-oracle is an oracle."""


def load_den_weights(name: str, weights: Path, device: str) -> DEN:
    """The DEN a method called ``name`` runs, or MethodUnavailableError naming the method and the file."""
    from darksynth.training.weights import load_weights

    if not weights.is_file():
        raise MethodUnavailableError(f"{name}: no trained weights at {weights}")
    try:
        return load_weights(weights, device=device)
    except DarksynthError as error:
        raise MethodUnavailableError(f"{name}: {error}") from None


def synthesize_image(clean: torch.Tensor, values: NoiseValues, generator: torch.Generator) -> torch.Tensor:
    """clean + f(v) through the composer (:func:`~darksynth.noise.simulate.add_noise`) on the clean image as it is
    (it already has the reference's brightness), on 8-bit levels: (3, H, W) in [0, 1] in and out."""
    return to_8bit_levels(add_noise(clean[None], values, generator=generator)[0])


ESTIMATES_KEPT = 1024
"""How many estimates :class:`_Estimates` keeps (each a profile of a few kilobytes)."""


@dataclass
class _Estimates:
    """The estimates of the noisy images seen, by their pixels, shared by the DEN methods that start from them
    (``den`` and ``den-prior``, which adds the texture dependence the prior expects) and by later runs in the same
    process (the downstream check after the evaluation, one per seed): the estimate depends on the image alone."""

    found: OrderedDict[bytes, Estimate] = field(default_factory=OrderedDict)

    def get(self, noisy: torch.Tensor, compute: Callable[[], Estimate]) -> Estimate:
        pixels = noisy.detach().to(device="cpu", dtype=torch.float64).contiguous().numpy()
        key = hashlib.blake2b(pixels.tobytes(), digest_size=16).digest() + repr(pixels.shape).encode()
        if key not in self.found:
            self.found[key] = compute()
            if len(self.found) > ESTIMATES_KEPT:
                self.found.popitem(last=False)
        return self.found[key]


@dataclass
class _LatestReading:
    """What a DEN method's latest fit read of the spectrum (:attr:`NoiseMethod.read_octaves`)."""

    octaves: Mapping[str, int] | None = None


def _read_octaves(found: Estimate) -> Mapping[str, int] | None:
    spectrum = found.profile.meta.get("spectrum")
    return spectrum.get("read_octaves") if isinstance(spectrum, dict) else None


_ESTIMATES: dict[tuple[str, str, bool, tuple[str, ...]], _Estimates] = {}


def _den_method(
    name: str, weights: Path, device: str, *, refine: bool = True, prior: bool = False, octaves: bool = False
) -> NoiseMethod:
    from darksynth.estimation.assemble import estimate
    from darksynth.estimation.noise.camera_conditional import CameraPriorUse, expected_texture
    from darksynth.estimation.noise.noise_estimate import NoiseEstimateOptions, refines

    model = load_den_weights(name, weights, device)
    refined = refines(model.noise_model, refine)
    with_prior = prior and refined
    options = NoiseEstimateOptions(device=device, refine=refine)

    latest = _LatestReading()

    def fitted_with(camera_prior: CameraPrior | None, texture_prior: CameraPrior) -> Fit:
        # The texture dependence a camera JPEG takes from the prior (NoiseEstimateOptions.jpeg_texture) comes from
        # the prior fitted without the set judged; the estimates are shared per such prior (named by its sets).
        estimates = _ESTIMATES.setdefault((str(weights), device, refine, texture_prior.sets), _Estimates())
        judged = dataclasses.replace(options, jpeg_texture_prior=texture_prior)

        def fit(noisy: torch.Tensor, clean: torch.Tensor) -> NoiseValues:
            reference = noisy.to(torch.float32)[None]
            if camera_prior is not None and octaves:
                use = CameraPriorUse(camera_prior, octaves=True)
                found = estimate(reference, model, options=dataclasses.replace(judged, camera_prior=use))
                latest.octaves = _read_octaves(found)
                return found.profile.noise
            found = estimates.get(noisy, lambda: estimate(reference, model, options=judged))
            latest.octaves = _read_octaves(found)
            values = found.profile.noise
            # The texture dependence does not enter the fit (it reads flat blocks): added to the shared estimate,
            # it is what estimate --camera-prior gives.
            return values if camera_prior is None else values.replace(**expected_texture(values, camera_prior))

        return fit

    def on_set(set_name: str) -> NoiseMethod:
        without_set = shipped_prior(held_out_sets(set_name))
        camera_prior = without_set if with_prior else None
        details = method.details | {"jpeg_texture_prior_sets": without_set.sets}
        details |= {"prior_sets": without_set.sets} if with_prior else {}
        return dataclasses.replace(method, fit=fitted_with(camera_prior, without_set), for_set=None, details=details)

    method = NoiseMethod(
        name=name,
        summary=f"DEN {model.config.variant}, {model.noise_model} noise model ({weights.name}): v from the noisy "
        + ("image, its spectrum measured on it" if refined else "image")
        + (", the texture dependence from the camera prior fitted without the set" if with_prior else "")
        + (" (and the coarse octaves)" if with_prior and octaves else "")
        + ", f(v) added to the clean",
        fit=fitted_with(shipped_prior() if with_prior else None, shipped_prior()),
        synthesize=synthesize_image,
        details={"weights": str(weights)},
        for_set=on_set if refined else None,
        read_octaves=lambda: latest.octaves,
    )
    return method


def _prior_method() -> NoiseMethod:
    """Whole cameras drawn from the prior, one per pair, no reference read: on a named set the prior fitted without
    it (and the sets of the same cameras), elsewhere the shipped one."""

    def drawn_from(camera_prior: CameraPrior) -> Synthesize:
        def synthesize(clean: torch.Tensor, _: None, generator: torch.Generator) -> torch.Tensor:
            return synthesize_image(clean, camera_prior.draw(generator).clip(0), generator)

        return synthesize

    def on_set(set_name: str) -> NoiseMethod:
        camera_prior = shipped_prior(held_out_sets(set_name))
        details = {"prior_sets": camera_prior.sets}
        return dataclasses.replace(method, synthesize=drawn_from(camera_prior), for_set=None, details=details)

    method = NoiseMethod(
        name="prior",
        summary="a whole camera drawn from the prior over real cameras fitted without the set (and sets of the same "
        "cameras), one per pair; the noisy image is not read",
        fit=lambda noisy, clean: None,
        synthesize=drawn_from(shipped_prior()),
        for_set=on_set,
    )
    return method


def _den_v1_method(weights: Path | None, device: str) -> NoiseMethod:
    from darksynth.baselines.den_v1 import default_den_v1_path, load_den_v1

    path = weights or default_den_v1_path()
    try:
        model = load_den_v1(path, device=device)
    except DarksynthError as error:
        raise MethodUnavailableError(f"den-v1: {error}") from None

    def fit(noisy: torch.Tensor, clean: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            return model.encode(noisy.to(device=device, dtype=torch.float32)[None, None])

    def synthesize(clean: torch.Tensor, code: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        with torch.no_grad():
            noisy = model.generate(clean.to(device=device, dtype=torch.float32)[None, None], code, generator)
        return to_8bit_levels(noisy[0, 0].to(clean.dtype).cpu())

    return NoiseMethod(
        name="den-v1",
        summary=f"the paper's ablation v1 ({path.name}): a code read from the noisy image by the DEN's encoder, "
        "and a U-Net that makes the clean image noisy from it directly, without f",
        fit=fit,
        synthesize=synthesize,
        details={"weights": str(path)},
    )


def _starlight_method(device: str) -> NoiseMethod:
    try:
        from darksynth.baselines.starlight import load_starlight
    except ImportError:
        raise MethodUnavailableError("starlight: the Starlight baseline is not built in this version") from None
    try:
        generator_model = load_starlight(device=device)
    except DarksynthError as error:
        raise MethodUnavailableError(f"starlight: {error}") from None

    def synthesize(clean: torch.Tensor, _: None, generator: torch.Generator) -> torch.Tensor:
        with torch.no_grad():
            noisy = generator_model(clean.to(device=device, dtype=torch.float32)[None], generator=generator)[0]
        return to_8bit_levels(noisy.to(clean.dtype).cpu())

    return NoiseMethod(
        name="starlight",
        summary="Starlight generator (physics + U-Net residual) trained on darksynth's synthetic data; not adaptive",
        fit=lambda noisy, clean: None,
        synthesize=synthesize,
    )


def _spectral_oracle_method() -> NoiseMethod:
    from darksynth.estimation.noise.spectral_fit import oracle_spectral_fit

    def fit(noisy: torch.Tensor, clean: torch.Tensor) -> NoiseValues:
        return NoiseValues.from_values(oracle_spectral_fit(noisy.to(torch.float32), clean.to(torch.float32)))

    return NoiseMethod(
        name="spectral-oracle",
        summary="the spectral model (per-octave colour covariances, level curves, JPEG stage) fitted with the "
        "clean image by re-synthesis (docs/spectral-noise.md)",
        fit=fit,
        synthesize=synthesize_image,
        oracle=True,
    )


DEN_METHODS: dict[str, tuple[str, str]] = {
    "den": ("srgb", "v3"),
    "den-prior": ("srgb", "v3"),
    "den-prior-octaves": ("srgb", "v3"),
    "den-network": ("srgb", "v3"),
    "den-paper": ("paper", "v3"),
    "den-v2": ("paper", "v2"),
}
"""The DEN methods and the (noise model, variant) of the shipped DEN each uses unless given weights. ``den`` is
what ``darksynth estimate`` gives (the sRGB DEN, the spectrum measured on the reference);
``den-prior`` the same with the texture dependence from the camera prior fitted without the set judged
(``estimate --camera-prior``); ``den-prior-octaves`` with the coarse octaves from it too (``--prior-octaves``);
``den-network`` the network's values alone (its ablation)."""

PRIOR_DEN_METHODS = frozenset({"den-prior", "den-prior-octaves"})

UNREFINED_DEN_METHODS = frozenset({"den-network"})

DEFAULT_METHODS: tuple[str, ...] = (
    "den",
    "den-paper",
    "den-v1",
    "den-v2",
    "awgn",
    "awgn-blind",
    "pg",
    "pg-blind",
    "pg-oracle",
    "starlight",
)
"""What `darksynth evaluate` compares unless told otherwise: the DEN (sRGB noise model), the paper-faithful DEN
(``den-paper``) and its ablations (``den-v1``, ``den-v2``, both of the paper's model), and the paper's peers."""

METHOD_NAMES: tuple[str, ...] = (
    *DEFAULT_METHODS,
    # The sRGB DEN's values alone, without the spectrum measured on the reference, run by name only.
    "den-network",
    # The spectral model's clean-aided fit.
    "spectral-oracle",
    # The blind estimate with what it cannot show from the camera prior, and whole cameras drawn from the prior with
    # no reference.
    "den-prior",
    "den-prior-octaves",
    "prior",
    # What users add to their training today: albumentations' noise at its default ranges.
    *ALBUMENTATIONS_METHODS,
)


def build_method(name: str, *, weights: dict[str, Path] | None = None, device: str = "cpu") -> NoiseMethod:
    """The method called ``name``.

    Args:
        weights: weights files by method name for the DEN methods (the shipped weights by default, see
            :data:`DEN_METHODS`).

    Raises:
        MethodUnavailableError: an unknown name, or a method whose weights do not exist.
    """
    weights = weights or {}
    if name in DEN_METHODS:
        noise_model, variant = DEN_METHODS[name]
        path = DENChoice(weights.get(name), noise_model=noise_model, variant=variant).path()
        return _den_method(
            name,
            path,
            device,
            refine=name not in UNREFINED_DEN_METHODS,
            prior=name in PRIOR_DEN_METHODS,
            octaves=name == "den-prior-octaves",
        )
    if name == "den-v1":
        return _den_v1_method(weights.get(name), device)
    if name in POISSON_GAUSSIAN_METHODS:
        summary, fit = POISSON_GAUSSIAN_METHODS[name]
        return NoiseMethod(name, summary, fit, add_poisson_gaussian, oracle=name == "pg-oracle")
    if name == "starlight":
        return _starlight_method(device)
    if name == "spectral-oracle":
        return _spectral_oracle_method()
    if name == "prior":
        return _prior_method()
    if name in ALBUMENTATIONS_METHODS:
        return albumentations_method(name)
    raise MethodUnavailableError(f"{name}: unknown method (known: {', '.join(METHOD_NAMES)})")


def build_methods(
    names: Sequence[str], *, weights: dict[str, Path] | None = None, device: str = "cpu"
) -> tuple[dict[str, NoiseMethod], list[str]]:
    """The methods that can run, by name, and one problem line for each that cannot.

    Raises:
        DarksynthError: none of them can run.
    """
    methods: dict[str, NoiseMethod] = {}
    problems: list[str] = []
    for name in names:
        try:
            methods[name] = build_method(name, weights=weights, device=device)
        except MethodUnavailableError as error:
            problems.append(str(error))
    if not methods:
        raise DarksynthError("no method can run: " + "; ".join(problems))
    return methods, problems
