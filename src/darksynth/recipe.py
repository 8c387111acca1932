"""A clip's parameters, chosen in one place: the recipe that ``apply``, ``convert``, ``synthesize`` and the
training transforms all follow.

A :class:`ClipRecipe` is what the user asked for: the profile, how the darkening is chosen, whether the profile's
ranges are drawn per clip (``--jitter``), whether its blur and flicker stay on, whether the reference's colour cast
is matched, and whether each clip gets a whole camera drawn from the prior over real cameras (``--camera``). It is
the one declaration of these choices: ``apply``'s and ``convert``'s options hold one, the command line's options
take their defaults from its fields (``tests/test_cli.py`` checks every field has its option), and ``synthesize``
and the transforms build one from their keywords (:class:`RecipeChoices`, :func:`augmenting_recipe`). A new choice is
a field here (and its keyword in :class:`RecipeChoices`), the code that acts on it in :meth:`ClipRecipe.choose` or
the synthesizer, and its option.
:meth:`ClipRecipe.choose` turns it, a generator and the clip's first frame into the clip's :class:`ClipParameters`,
in one fixed order of draws, so that a seed gives the same parameters from the library, the command line and a
transform.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal, TypedDict, cast

import torch

from darksynth.cameras.presets import CAMERA_CHOICES, camera_source
from darksynth.cameras.prior import BLIND_OCTAVES, CameraPrior, measured_entries, on_measured_scale
from darksynth.errors import DarksynthError
from darksynth.exposure import ColourScale, matched_colour, matched_darkening
from darksynth.light.darkening import ALPHA_RANGE, GAMMA_RANGE, Darkening
from darksynth.noise.components import noise_parameter, noise_parameters
from darksynth.noise.sampling import random_uniform
from darksynth.noise.spectral_components import SPECTRUM_REPLACES
from darksynth.noise.structure_translation import spectral_tensors
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile, profile_to_dict, without_light

DarkeningChoice = Darkening | Literal["profile"] | None
"""``"profile"``: the profile's darkening, else alpha/gamma drawn from its ranges, else from the paper's
ranges. A :class:`Darkening`: exactly that. None: no darkening (the input already has the target brightness)."""

AUGMENTING = True
"""The ``jitter`` of the library's calls (``synthesize``, the transforms): they make training data, where each clip
drawn within the profile's ranges is the augmentation; the command line reproduces the profile unless ``--jitter``."""


@dataclass(frozen=True)
class CameraDraw:
    """Where a clip's camera came from.

    Attributes:
        source: what it was drawn from, one of :data:`~darksynth.cameras.presets.CAMERA_CHOICES`.
        given_profile: drawn given the profile's measured values (its level curve, JPEG strength and finer
            octaves, kept), rather than whole.
    """

    source: str
    given_profile: bool

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record for manifests."""
        return {"source": self.source, "given_profile": self.given_profile}


@dataclass(frozen=True)
class ClipParameters:
    """The parameters chosen for one clip (or one image): noise values, the darkening, if any, the channel
    factors that give it the reference's colour cast (:func:`darksynth.exposure.matched_colour`) and, when
    its camera was drawn, where from (its values are in ``noise``)."""

    noise: NoiseValues
    darkening: Darkening | None
    colour_scale: ColourScale | None = None
    camera: CameraDraw | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record for manifests: the noise and light values as a profile writes them, the darkening and
        (when matched) the colour scale, (when drawn) where the camera came from."""
        darkening = None if self.darkening is None else {"alpha": self.darkening.alpha, "gamma": self.darkening.gamma}
        record: dict[str, Any] = {
            "noise": self.noise.to_json("noise"),
            "light": self.noise.to_json("light"),
            "darkening": darkening,
        }
        if self.colour_scale is not None:
            record["colour_scale"] = list(self.colour_scale)
        if self.camera is not None:
            record["camera"] = self.camera.to_json()
        return record


def check_camera(name: str | None) -> str | None:
    """``name`` if it is None or one of :data:`~darksynth.cameras.presets.CAMERA_CHOICES`.

    Raises:
        DarksynthError: any other name.
    """
    if name is not None and name not in CAMERA_CHOICES:
        raise DarksynthError(f"unknown camera {name!r}; choose one of {', '.join(CAMERA_CHOICES)}")
    return name


def has_measured_spectrum(noise: NoiseValues) -> bool:
    """Whether noise values hold a spectral level curve (a profile from ``estimate``), not the paper model's or
    the sRGB structure's description of the noise."""
    return bool((noise["level_curve"] != 0.0).any())


def random_camera(
    noise: NoiseValues, prior: CameraPrior, *, given_measured: bool, generator: torch.Generator
) -> NoiseValues:
    """Unbatched ``noise`` with a camera drawn from ``prior``: its spectral values (those the prior holds) drawn,
    the heteroscedastic parameters they take over (:data:`SPECTRUM_REPLACES`) neutral, the rest kept.

    With ``given_measured`` the draw is conditional on what a blind estimate measures of ``noise``
    (:func:`~darksynth.cameras.prior.measured_entries`), and those entries are kept exactly; otherwise the whole
    camera is drawn. Drawn values are clamped to their parameters' valid ranges.
    """
    if given_measured:
        known, mask = measured_entries(noise)
        drawn = prior.draw_given(known, mask, generator)
        values = {name: drawn[name] for name in prior.names} | _kept_measured(drawn, known, mask)
    else:
        drawn = prior.draw(generator).clip(0)
        values = {name: drawn[name] for name in prior.names}
    # A Gaussian's tail can leave a parameter's valid range, which the values' readers assume.
    valid = {
        name: value.clamp(noise_parameter(name).minimum, noise_parameter(name).maximum)
        for name, value in values.items()
    }
    neutral = {name: noise_parameter(name).neutral for name in SPECTRUM_REPLACES}
    return noise.replace(**neutral, **valid)


def _kept_measured(
    drawn: NoiseValues, known: dict[str, torch.Tensor], mask: dict[str, torch.Tensor]
) -> dict[str, torch.Tensor]:
    """The drawn values of the measured names with the measured entries put back exactly: the prior's space is a
    log and snaps JPEG strengths to steps, which would move them by rounding or by a step."""
    kept = {}
    for name, value in known.items():
        fill = drawn[name]
        if name == "octave_power":
            # Only the spectrum's shape counts in the prior's space: the drawn coarse powers go on the measured
            # ones' scale.
            fill = on_measured_scale(fill, value.to(fill), BLIND_OCTAVES)
        kept[name] = torch.where(mask[name], value.to(fill), fill)
    return kept


def draw_clip_parameters(
    profile: Profile, *, darkening: DarkeningChoice = "profile", generator: torch.Generator | None = None
) -> ClipParameters:
    """Fix the parameters for one clip: values from the profile, drawn within its ranges where it has them.

    Draws happen in the order of the parameter table, then alpha and gamma, so a seed fixes them all. The sRGB
    structure of a version-2 or version-3 profile, once drawn, is given as the spectral model's values
    (:func:`darksynth.noise.structure_translation.spectral_tensors`): what the clip draws and what its record says.
    """
    # Draws happen on the generator's device (a CUDA generator cannot fill a CPU tensor).
    device = generator.device if generator is not None else None
    drawn: dict[str, torch.Tensor] = {}
    for parameter in noise_parameters():
        if parameter.name in profile.ranges:
            drawn[parameter.name] = random_uniform(
                profile.ranges[parameter.name], generator=generator, device=device, dtype=torch.float64
            ).cpu()
    noise = profile.noise.replace(**drawn) if drawn else profile.noise
    noise = NoiseValues(spectral_tensors(noise))
    chosen: Darkening | None
    if darkening is None or isinstance(darkening, Darkening):
        chosen = darkening
    else:
        # Fixed values stay exact; only what has a range (or no value at all) is drawn, alpha before gamma.
        fixed = profile.darkening
        values = {}
        for name, paper_range in (("alpha", ALPHA_RANGE), ("gamma", GAMMA_RANGE)):
            if name in profile.ranges or fixed is None:
                interval = profile.ranges[name][0] if name in profile.ranges else paper_range
                drawn_value = random_uniform((interval,), generator=generator, device=device, dtype=torch.float64)
                values[name] = float(drawn_value[0])
            else:
                values[name] = getattr(fixed, name)
        chosen = Darkening(alpha=values["alpha"], gamma=values["gamma"])
    return ClipParameters(noise=noise, darkening=chosen)


def fixed_darkening(profile: Profile) -> Darkening:
    """The darkening when nothing is drawn: the profile's, else the centre of its alpha/gamma ranges or the paper's."""
    if profile.darkening is not None:
        return profile.darkening
    centres = {}
    for name, paper in (("alpha", ALPHA_RANGE), ("gamma", GAMMA_RANGE)):
        low, high = profile.ranges[name][0] if name in profile.ranges else paper
        centres[name] = (low + high) / 2
    return Darkening(alpha=centres["alpha"], gamma=centres["gamma"])


@dataclass(frozen=True)
class ClipRecipe:
    """How every clip's parameters are chosen.

    Attributes:
        profile: the noise profile (its tones, when it has the reference's, match each input's darkening).
        darkening: see :data:`DarkeningChoice`.
        jitter: draw each clip's values within the profile's ranges; otherwise (the default: the reference's camera
            as measured) every clip gets the profile's values and a fixed darkening (:func:`fixed_darkening`), and
            its seed drives only the noise itself. ``synthesize`` and the transforms, which make training data,
            draw (:data:`AUGMENTING`).
        blur, flicker: False switches off the profile's motion blur and camera shake, or its flicker.
        match_colour: also give each input the reference's colour cast (needs the profile's ``tone.colour`` and a
            darkening).
        camera: draw each clip's camera from this source (one of
            :data:`~darksynth.cameras.presets.CAMERA_CHOICES`): given the profile's measured level curve, JPEG
            strength and finer octaves when it has them (a profile from ``estimate``), whole otherwise. None keeps
            the profile's noise.
    """

    profile: Profile
    darkening: DarkeningChoice = "profile"
    jitter: bool = False
    blur: bool = True
    flicker: bool = True
    match_colour: bool = False
    camera: str | None = None

    def __post_init__(self) -> None:
        check_camera(self.camera)

    def to_json(self) -> dict[str, Any]:
        """Every choice as a JSON value under its field's name (a manifest's and a resumable run's record)."""
        darkening = self.darkening
        return {
            "profile": profile_to_dict(self.profile),
            "darkening": darkening if isinstance(darkening, str | None) else dataclasses.asdict(darkening),
            "jitter": self.jitter,
            "blur": self.blur,
            "flicker": self.flicker,
            "match_colour": self.match_colour,
            "camera": self.camera,
        }

    def drawn_from(self) -> tuple[Profile, DarkeningChoice]:
        """The profile and darkening choice the draws start from, before an input is seen."""
        profile = without_light(self.profile, blur=not self.blur, flicker=not self.flicker)
        if self.jitter:
            return profile, self.darkening
        darkening = fixed_darkening(profile) if self.darkening == "profile" else self.darkening
        return dataclasses.replace(profile, ranges={}), darkening

    def choose(
        self, generator: torch.Generator | None, first_frame: torch.Tensor | None = None, *, source: str = "input"
    ) -> ClipParameters:
        """One clip's parameters: the draws from :meth:`drawn_from`, with the darkening matched to the reference's
        tones on ``first_frame`` (C, H, W; uint8, uint16 or float) when the profile carries them
        (:func:`darksynth.exposure.matched_darkening`), and with ``match_colour`` the colour cast too.
        ``source`` names the input in the log when no match can be made. With ``camera``, the clip's camera is
        drawn last, after the draws every recipe makes, so that a seed gives the same darkening and ranges with or
        without it (:func:`random_camera`)."""
        profile, darkening = self.drawn_from()
        if first_frame is not None and self.darkening == "profile":
            tone, noise = self.profile.tone, self.profile.noise
            darkening = matched_darkening(first_frame, tone, noise=noise, source=source) or darkening
        parameters = draw_clip_parameters(profile, darkening=darkening, generator=generator)
        if self.camera is not None:
            given = has_measured_spectrum(self.profile.noise)
            noise = random_camera(
                parameters.noise,
                camera_source(self.camera),
                given_measured=given,
                generator=generator if generator is not None else _unseeded_generator(),
            )
            parameters = dataclasses.replace(parameters, noise=noise, camera=CameraDraw(self.camera, given))
        if self.match_colour and first_frame is not None and parameters.darkening is not None:
            colour = matched_colour(first_frame, self.profile.tone, parameters.darkening)
            if colour is not None:
                parameters = dataclasses.replace(parameters, colour_scale=colour[0], darkening=colour[1])
        return parameters


class RecipeChoices(TypedDict, total=False):
    """The choices of :class:`ClipRecipe` but its profile, as keywords of the library's calls (``synthesize``,
    ``LowLight``, ``AlbumentationsLowLight``): one meaning each, the field's; an omitted one takes the field's
    default (:func:`augmenting_recipe`). ``tests/transforms/test_recipe_choices.py`` holds its keys to the fields."""

    darkening: DarkeningChoice
    jitter: bool
    blur: bool
    flicker: bool
    match_colour: bool
    camera: str | None


def augmenting_recipe(profile: Profile, choices: RecipeChoices) -> ClipRecipe:
    """The recipe of a library call, which makes training data: the ``choices`` given, the recipe's defaults for
    the others, but ``jitter`` :data:`AUGMENTING` unless chosen.

    Raises:
        TypeError: a choice the recipe does not have (as Python does for an unknown keyword).
    """
    names = tuple(RecipeChoices.__annotations__)
    unknown = sorted(set(choices) - set(names))
    if unknown:
        raise TypeError(f"unexpected keyword argument {unknown[0]!r}: the recipe's choices are {', '.join(names)}")
    return ClipRecipe(profile, **({"jitter": AUGMENTING} | choices))


def recipe_choices(recipe: ClipRecipe) -> RecipeChoices:
    """The recipe's choices by field name, its profile left out: the keywords that build it again
    (:func:`augmenting_recipe`), what a transform's repr and serialisation show."""
    return cast(
        RecipeChoices,
        {field.name: getattr(recipe, field.name) for field in dataclasses.fields(recipe) if field.name != "profile"},
    )


def _unseeded_generator() -> torch.Generator:
    """A generator of its own for a caller that gave none, seeded from the system's entropy: never the global one."""
    generator = torch.Generator()
    generator.seed()
    return generator
