"""The noise profile: the JSON document that ``estimate`` writes and ``apply`` reads.

```
{"format": "darksynth-profile", "version": 2,
 "noise": {"shot": s, "read": r, "quantization": q, "banding": b, "temporal_banding": bt, "periodic": [p1, p2, p3],
           "channel_gain": [g_red, g_blue], "correlation_length": l, "channel_correlation": [rg, gb, rb],
           "compression": c},                  the last four optional (neutral when absent)
 "darkening": {"alpha": a, "gamma": g},        optional
 "ranges": {"shot": [lo, hi], "alpha": [lo, hi], ...},   optional: sample per image or clip within these
 "tone": {"quantiles": [q1, ..., q49], "noise": n, "colour": [r, g, b], "luminance": [l1, ..., l49]},
                                               optional: the reference's exposure (block-median and pixel
                                               luminance quantiles, colour cast), matched per input
 "light": {"exposure_fraction": s, "flicker": f, ...},   optional (version 5): motion blur, shake, flicker
 "meta": {...}}                                optional: free-form provenance, carried but not read
```

The fields of ``noise`` and ``light`` come from the parameter table
(:func:`darksynth.noise.components.noise_parameters`): the schema (:func:`profile_schema`, a pydantic model) is
built from it, each field declaring its bounds, unit and the profile version it arrived in; nothing here names a
component, so a new one needs no change in this module. Values are on the [0, 1] intensity scale.

Versions: a parameter that arrived in version 1 (the paper's) is required; one that arrived later (the sRGB
model's, version 2) is optional and neutral when absent, and refused in a document of an older version, so a
version-1 document is read as the same noise. Profiles are written with the newest version of the table.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import json
import math
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import pydantic
from pydantic import BaseModel, BeforeValidator, ConfigDict, WithJsonSchema
from pydantic_core import PydanticCustomError

from darksynth.errors import ProfileError
from darksynth.io.atomic import write_text_atomic
from darksynth.light.darkening import Darkening
from darksynth.light.tones import ToneTarget
from darksynth.noise.components import (
    NoiseComponent,
    Parameter,
    light_parameters,
    noise_components,
    noise_parameters,
    profile_section,
    profile_version,
)
from darksynth.noise.values import NoiseValues

PROFILE_FORMAT = "darksynth-profile"

DARKENING_LIMITS: dict[str, tuple[float, float]] = {"alpha": (0.0, 1.0), "gamma": (0.0, 10.0)}
"""Valid (exclusive low, inclusive high) bounds of the darkening parameters."""

Range = tuple[float, float]


TONE_QUANTILE_COUNT = 49
"""Quantiles in a tone target: at 0.02, 0.04, ..., 0.98 (:data:`darksynth.light.tones.PROBABILITIES`)."""


@dataclass(frozen=True)
class Profile:
    """A validated noise profile.

    Attributes:
        noise: every parameter's values of the one table (unbatched; neutral where the document has none): the
            noise, and light (``exposure_fraction``, ``flicker``...), which the document keeps in its ``light``
            section.
        darkening: the darkening to apply, or None to let the caller choose.
        ranges: for some parameters (noise names, ``alpha``, ``gamma``), one (low, high) interval per value;
            those parameters are drawn uniformly within it for each image or clip instead of being fixed.
        meta: free-form provenance (reference file, estimator version), carried through unchanged.
        tone: the reference's exposure, or None (an older profile, a reference too dark to read): with it,
            ``apply`` darkens each input to the reference's tones instead of using ``darkening`` as it is.
    """

    noise: NoiseValues
    darkening: Darkening | None = None
    ranges: Mapping[str, tuple[Range, ...]] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)
    tone: ToneTarget | None = None


def without_light(profile: Profile, *, blur: bool = False, flicker: bool = False) -> Profile:
    """The profile with its motion blur and camera shake (``blur``) or its flicker (``flicker``) switched off:
    those values neutral and their ranges gone (``--no-blur``, ``--no-flicker``)."""
    names = {name for name, off in (("scene", blur), ("flicker", flicker)) if off}
    parameters = [p for c in noise_components() if c.name in names for p in c.parameters]
    if not parameters:
        return profile
    noise = profile.noise.replace(**{p.name: p.neutral for p in parameters})
    ranges = {name: pairs for name, pairs in profile.ranges.items() if name not in {p.name for p in parameters}}
    return dataclasses.replace(profile, noise=noise, ranges=ranges)


def readable_versions() -> tuple[int, ...]:
    """The profile versions this darksynth reads: 1 up to the one it writes."""
    return tuple(range(1, profile_version() + 1))


# --- checks that name the field, the bound and the value -----------------------------------------------------


def _fail(message: str) -> PydanticCustomError:
    return PydanticCustomError("darksynth", "{message}", {"message": message})


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _fail(f"{where} must be a number, got {value!r}")
    try:
        number = float(value)
    except OverflowError:  # an integer literal beyond any float, such as 1 followed by 400 zeros
        raise _fail(f"{where} must be finite, got an integer too large for a float") from None
    if not math.isfinite(number):
        raise _fail(f"{where} must be finite, got {value!r}")
    return number


def _key(name: object) -> str:
    """A document's key as it appears in a field name: quoted when it holds a line break or another control
    character, so that the message stays on one line."""
    text = str(name)
    return text if text.isprintable() else repr(text)


def _noise_value(value: Any, where: str, parameter: Parameter) -> float:
    number = _number(value, where)
    if not parameter.minimum <= number <= parameter.maximum:
        raise _fail(
            f"{where} must lie in [{parameter.minimum:g}, {parameter.maximum:g}] ({parameter.unit}), got {value!r}"
        )
    return number


def _darkening_value(value: Any, where: str, name: str) -> float:
    number = _number(value, where)
    low, high = DARKENING_LIMITS[name]
    if not low < number <= high:
        raise _fail(f"{where} must lie in ({low:g}, {high:g}], got {value!r}")
    return number


def _values(raw: Any, where: str, parameter: Parameter) -> tuple[float, ...]:
    if parameter.size == 1:
        return (_noise_value(raw, where, parameter),)
    if not isinstance(raw, list) or len(raw) != parameter.size:
        raise _fail(f"{where} must be a list of {parameter.size} numbers, got {raw!r}")
    return tuple(_noise_value(item, f"{where}[{i}]", parameter) for i, item in enumerate(raw))


def _interval(raw: Any, where: str, check: Callable[[Any, str], float]) -> Range:
    if not isinstance(raw, list) or len(raw) != 2:
        raise _fail(f"{where} must be a [low, high] pair, got {raw!r}")
    low, high = check(raw[0], f"{where}[0]"), check(raw[1], f"{where}[1]")
    if low > high:
        raise _fail(f"{where} has low > high: {raw!r}")
    return (low, high)


def _ranges(raw: Any) -> dict[str, tuple[Range, ...]]:
    if not isinstance(raw, dict):
        raise _fail(f"ranges must be an object, got {raw!r}")
    parameters = {p.name: p for p in noise_parameters()}
    ranges: dict[str, tuple[Range, ...]] = {}
    for name, entry in raw.items():
        key = f"ranges.{_key(name)}"
        if name in DARKENING_LIMITS:
            ranges[name] = (_interval(entry, key, functools.partial(_darkening_value, name=name)),)
        elif name in parameters:
            parameter = parameters[name]
            check = functools.partial(_noise_value, parameter=parameter)
            # A vector parameter takes one pair per value, or one pair shared by all of them.
            if parameter.size > 1 and isinstance(entry, list) and entry and isinstance(entry[0], list):
                if len(entry) != parameter.size:
                    raise _fail(f"{key} must hold {parameter.size} [low, high] pairs, got {entry!r}")
                ranges[name] = tuple(_interval(item, f"{key}[{i}]", check) for i, item in enumerate(entry))
            else:
                ranges[name] = (_interval(entry, key, check),) * parameter.size
        else:
            known = ", ".join((*parameters, *DARKENING_LIMITS))
            raise _fail(f"{key} is not a parameter; known: {known}")
    return ranges


def _darkening(raw: Any) -> Darkening | None:
    if raw is None:
        return None
    if not isinstance(raw, dict) or set(raw) != set(DARKENING_LIMITS):
        raise _fail(f"darkening must be an object with alpha and gamma, got {raw!r}")
    return Darkening(
        alpha=_darkening_value(raw["alpha"], "darkening.alpha", "alpha"),
        gamma=_darkening_value(raw["gamma"], "darkening.gamma", "gamma"),
    )


def _quantile_list(values: Any, where: str) -> tuple[float, ...]:
    """:data:`TONE_QUANTILE_COUNT` non-decreasing numbers in [0, 1], or a message naming ``where``."""
    if (
        not isinstance(values, list)
        or len(values) != TONE_QUANTILE_COUNT
        or not all(isinstance(q, int | float) and not isinstance(q, bool) and 0.0 <= q <= 1.0 for q in values)
        or any(b < a for a, b in itertools.pairwise(values))
    ):
        raise _fail(f"{where} must be {TONE_QUANTILE_COUNT} non-decreasing numbers in [0, 1], got {values!r}")
    return tuple(float(q) for q in values)


_TONE_FIELDS = frozenset({"quantiles", "noise", "colour", "luminance"})


def _tone(raw: Any) -> ToneTarget | None:
    if raw is None:
        return None
    if not isinstance(raw, dict) or not {"quantiles", "noise"} <= set(raw) <= _TONE_FIELDS:
        raise _fail(f"tone must be an object with quantiles, noise and optionally colour and luminance, got {raw!r}")
    quantiles = _quantile_list(raw["quantiles"], "tone.quantiles")
    noise = raw["noise"]
    if isinstance(noise, bool) or not isinstance(noise, int | float) or not 0.0 <= noise < 1.0:
        raise _fail(f"tone.noise must be a number in [0, 1), got {noise!r}")
    colour = raw.get("colour")
    if colour is not None and (
        not isinstance(colour, list)
        or len(colour) != 3
        or not all(isinstance(c, int | float) and not isinstance(c, bool) and 0.0 <= c <= 3.0 for c in colour)
    ):
        raise _fail(f"tone.colour must be 3 numbers in [0, 3] (red, green, blue shares of the light), got {colour!r}")
    cast = None if colour is None else (float(colour[0]), float(colour[1]), float(colour[2]))
    # Profiles written before the luminance quantiles have none: apply then matches on the block medians alone.
    luminance = None if raw.get("luminance") is None else _quantile_list(raw["luminance"], "tone.luminance")
    return ToneTarget(quantiles=quantiles, noise=float(noise), colour=cast, luminance=luminance)


def _version(raw: Any) -> int:
    if isinstance(raw, bool) or raw not in readable_versions():
        readable = " and ".join(str(v) for v in readable_versions())
        raise _fail(f"unsupported version {raw!r}; this darksynth reads versions {readable}")
    return int(raw)


def _format(raw: Any) -> str:
    if raw != PROFILE_FORMAT:
        raise _fail(f"format must be {PROFILE_FORMAT!r}, got {raw!r}")
    return PROFILE_FORMAT


def _meta(raw: Any) -> dict[str, Any]:
    if not isinstance(raw, dict):
        raise _fail(f"meta must be an object, got {raw!r}")
    return raw


# --- the schema, built from the parameter table --------------------------------------------------------------


def _number_schema(parameter: Parameter) -> dict[str, Any]:
    number = {"type": "number", "minimum": parameter.minimum, "maximum": parameter.maximum}
    schema: dict[str, Any] = (
        number
        if parameter.size == 1
        else {"type": "array", "items": number, "minItems": parameter.size, "maxItems": parameter.size}
    )
    return schema | {"description": parameter.unit, "since_version": parameter.since_version}


def _noise_field(parameter: Parameter) -> tuple[Any, Any]:
    def check(raw: Any) -> tuple[float, ...]:
        return _values(raw, f"{profile_section(parameter)}.{parameter.name}", parameter)

    annotated = Annotated[tuple[float, ...], BeforeValidator(check), WithJsonSchema(_number_schema(parameter))]
    if parameter.since_version == 1:
        return (annotated, pydantic.Field(json_schema_extra={"since_version": 1}))
    return (
        annotated | None,
        pydantic.Field(default=None, json_schema_extra={"since_version": parameter.since_version}),
    )


_DARKENING_SCHEMA = {
    "type": "object",
    "properties": {
        name: {"type": "number", "exclusiveMinimum": low, "maximum": high}
        for name, (low, high) in DARKENING_LIMITS.items()
    },
}


class _ProfileDocument(BaseModel):
    """The fields of a profile document that do not depend on the table; ``noise`` is added per table."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Annotated[str, BeforeValidator(_format), WithJsonSchema({"const": PROFILE_FORMAT})]
    version: Annotated[int, BeforeValidator(_version), WithJsonSchema({"type": "integer", "minimum": 1})]
    darkening: Annotated[Darkening | None, BeforeValidator(_darkening), WithJsonSchema(_DARKENING_SCHEMA)] = None
    ranges: Annotated[dict[str, tuple[Range, ...]], BeforeValidator(_ranges), WithJsonSchema({"type": "object"})] = (
        pydantic.Field(default_factory=dict)
    )
    meta: Annotated[dict[str, Any], BeforeValidator(_meta), WithJsonSchema({"type": "object"})] = pydantic.Field(
        default_factory=dict
    )
    tone: Annotated[ToneTarget | None, BeforeValidator(_tone), WithJsonSchema({"type": "object"})] = None


@functools.cache
def _schema_for(components: tuple[NoiseComponent, ...]) -> type[_ProfileDocument]:
    parameters = tuple(p for c in components for p in c.parameters)
    sections: dict[str, type[BaseModel]] = {}
    for section in ("noise", "light"):
        fields: dict[str, Any] = {p.name: _noise_field(p) for p in parameters if profile_section(p) == section}
        sections[section] = pydantic.create_model(
            f"{section.title()}Section", __config__=ConfigDict(extra="forbid", frozen=True), **fields
        )
    noise: Any = sections["noise"]
    light: Any = sections["light"] | None
    document: type[_ProfileDocument] = pydantic.create_model(
        "ProfileDocument",
        __base__=_ProfileDocument,
        noise=(noise, ...),
        light=(light, pydantic.Field(default=None, json_schema_extra={"since_version": 5})),
    )
    return document


def profile_schema() -> type[_ProfileDocument]:
    """The pydantic model of a profile document, built from the parameter table as it is now;
    ``profile_schema().model_json_schema()`` is its JSON Schema (each noise field with its ``since_version``)."""
    return _schema_for(noise_components())


def _error_message(error: Mapping[str, Any]) -> str:
    where = ".".join(_key(part) for part in error["loc"])
    kind = error["type"]
    if kind == "darksynth":
        return str(error["ctx"]["message"])
    if kind == "missing":
        return f"{where} is missing"
    if kind == "extra_forbidden":
        if len(error["loc"]) == 1:
            known = ", ".join(profile_schema().model_fields)
            return f"unknown field {error['loc'][0]!r}; a profile has {known}"
        section = str(error["loc"][0])
        known = ", ".join(p.name for p in noise_parameters() if profile_section(p) == section)
        return f"{where} is not a {section} parameter; known: {known}"
    if where in ("noise", "light"):
        known = ", ".join(p.name for p in noise_parameters() if profile_section(p) == where)
        return f"{where} must be an object with {known}, got {error['input']!r}"
    return f"{where}: {error['msg']}, got {error['input']!r}"


def parse_profile(document: Any, *, source: str = "profile") -> Profile:
    """Validate a decoded JSON document and build the profile.

    Args:
        document: the decoded JSON value.
        source: the file name or label that error messages start with.

    Raises:
        ProfileError: naming the field, the bound and the offending value.
    """
    if not isinstance(document, dict):
        raise ProfileError(f"{source}: a profile must be a JSON object, got {type(document).__name__}")
    try:
        parsed = profile_schema().model_validate(document)
    except pydantic.ValidationError as error:
        raise ProfileError(f"{source}: {_error_message(error.errors()[0])}") from None
    given: dict[str, tuple[float, ...]] = {}
    for parameter in noise_parameters():
        section = getattr(parsed, profile_section(parameter))
        values = None if section is None else getattr(section, parameter.name)
        if values is None:
            continue
        if parameter.since_version > parsed.version:
            raise ProfileError(
                f"{source}: {profile_section(parameter)}.{parameter.name} needs profile version "
                f"{parameter.since_version}, this document is version {parsed.version}"
            )
        given[parameter.name] = values
    return Profile(
        noise=NoiseValues.from_values(given),
        darkening=parsed.darkening,
        ranges=parsed.ranges,
        meta=parsed.meta,
        tone=parsed.tone,
    )


def validate_profile(profile: Profile) -> Profile:
    """Check a profile built in Python with the same rules as one read from JSON; returns the normalised copy."""
    return parse_profile(profile_to_dict(profile), source="profile")


def profile_to_dict(profile: Profile) -> dict[str, Any]:
    """The JSON document of a profile (scalars as numbers, vectors as lists)."""
    sizes = {p.name: p.size for p in noise_parameters()}
    document: dict[str, Any] = {
        "format": PROFILE_FORMAT,
        "version": profile_version(),
        "noise": profile.noise.to_json("noise"),
    }
    if any(not profile.noise.is_neutral(p) for p in light_parameters()):
        document["light"] = profile.noise.to_json("light")
    if profile.darkening is not None:
        document["darkening"] = {"alpha": profile.darkening.alpha, "gamma": profile.darkening.gamma}
    if profile.ranges:
        document["ranges"] = {
            name: ([list(pair) for pair in pairs] if sizes.get(name, 1) > 1 else list(pairs[0]))
            for name, pairs in profile.ranges.items()
        }
    if profile.tone is not None:
        document["tone"] = {"quantiles": list(profile.tone.quantiles), "noise": profile.tone.noise}
        if profile.tone.colour is not None:
            document["tone"]["colour"] = list(profile.tone.colour)
        if profile.tone.luminance is not None:
            document["tone"]["luminance"] = list(profile.tone.luminance)
    if profile.meta:
        document["meta"] = dict(profile.meta)
    return document


def load_profile(path: str | Path) -> Profile:
    """Read and validate a profile file.

    Raises:
        ProfileError: the file is missing, is not JSON, or fails validation; the message starts with the path.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ProfileError(f"{path}: no such profile file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ProfileError(f"{path}: cannot read profile ({error.__class__.__name__})") from None
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise ProfileError(f"{path}: not valid JSON ({error.msg} at line {error.lineno})") from None
    except ValueError:  # an integer literal of more digits than Python converts
        limit = sys.get_int_max_str_digits()
        raise ProfileError(f"{path}: not a usable JSON document (a number has more than {limit} digits)") from None
    except RecursionError:
        raise ProfileError(f"{path}: not a usable JSON document (nested too deeply)") from None
    return parse_profile(document, source=str(path))


def save_profile(path: str | Path, profile: Profile) -> None:
    """Write a profile as indented JSON, atomically."""
    write_text_atomic(Path(path), json.dumps(profile_to_dict(profile), indent=2) + "\n")


def default_profile_path() -> Path:
    """The profile shipped with the package, used by ``demo`` and as a starting point."""
    return Path(__file__).parent / "data" / "default_profile.json"
