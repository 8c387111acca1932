"""The noise profile: the JSON document that ``estimate`` writes and ``apply`` reads.

```
{"format": "darksynth-profile", "version": 2,
 "noise": {"shot": s, "read": r, "quantization": q, "banding": b, "temporal_banding": bt, "periodic": [p1, p2, p3],
           "channel_gain": [g_red, g_blue], "correlation_length": l, "channel_correlation": [rg, gb, rb],
           "compression": c},                  the last four optional (neutral when absent)
 "darkening": {"alpha": a, "gamma": g},        optional
 "ranges": {"shot": [lo, hi], "alpha": [lo, hi], ...},   optional: sample per image or clip within these
 "meta": {...}}                                optional: free-form provenance, carried but not read
```

The fields of ``noise`` come from :data:`darksynth.noise.components.NOISE_PARAMETERS`; nothing here names a
component, so a new one needs no change in this module. Values are on the [0, 1] intensity scale.

Versions: 1 has the paper's parameters only (all required). 2 adds the sRGB model's (``model="srgb"`` in the
table), each optional and neutral when absent, so a version-1 document is read as the same noise. Profiles
are always written as version 2.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from darksynth.darkening import Darkening
from darksynth.errors import ProfileError
from darksynth.io.atomic import write_text_atomic
from darksynth.noise.components import NOISE_PARAMETER_NAMES, NOISE_PARAMETERS, Parameter

PROFILE_FORMAT = "darksynth-profile"
PROFILE_VERSION = 2
READABLE_VERSIONS = (1, 2)

DARKENING_LIMITS: dict[str, tuple[float, float]] = {"alpha": (0.0, 1.0), "gamma": (0.0, 10.0)}
"""Valid (exclusive low, inclusive high) bounds of the darkening parameters."""

Range = tuple[float, float]


@dataclass(frozen=True)
class Profile:
    """A validated noise profile.

    Attributes:
        noise: every noise parameter by name, each a tuple of its values (one for a scalar).
        darkening: the darkening to apply, or None to let the caller choose.
        ranges: for some parameters (noise names, ``alpha``, ``gamma``), one (low, high) interval per value;
            those parameters are drawn uniformly within it for each image or clip instead of being fixed.
        meta: free-form provenance (reference file, estimator version), carried through unchanged.
    """

    noise: Mapping[str, tuple[float, ...]]
    darkening: Darkening | None = None
    ranges: Mapping[str, tuple[Range, ...]] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProfileError(f"{where} must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ProfileError(f"{where} must be finite, got {value!r}")
    return number


def _noise_value(value: Any, where: str, parameter: Parameter) -> float:
    number = _number(value, where)
    if not parameter.minimum <= number <= parameter.maximum:
        raise ProfileError(
            f"{where} must lie in [{parameter.minimum:g}, {parameter.maximum:g}] ({parameter.unit}), got {value!r}"
        )
    return number


def _darkening_value(value: Any, where: str, name: str) -> float:
    number = _number(value, where)
    low, high = DARKENING_LIMITS[name]
    if not low < number <= high:
        raise ProfileError(f"{where} must lie in ({low:g}, {high:g}], got {value!r}")
    return number


def _values(raw: Any, where: str, parameter: Parameter) -> tuple[float, ...]:
    if parameter.size == 1:
        return (_noise_value(raw, where, parameter),)
    if not isinstance(raw, list) or len(raw) != parameter.size:
        raise ProfileError(f"{where} must be a list of {parameter.size} numbers, got {raw!r}")
    return tuple(_noise_value(item, f"{where}[{i}]", parameter) for i, item in enumerate(raw))


def _interval(raw: Any, where: str, check: Any) -> Range:
    if not isinstance(raw, list) or len(raw) != 2:
        raise ProfileError(f"{where} must be a [low, high] pair, got {raw!r}")
    low, high = check(raw[0], f"{where}[0]"), check(raw[1], f"{where}[1]")
    if low > high:
        raise ProfileError(f"{where} has low > high: {raw!r}")
    return (low, high)


def _ranges(raw: Any, where: str) -> dict[str, tuple[Range, ...]]:
    if not isinstance(raw, dict):
        raise ProfileError(f"{where} must be an object, got {raw!r}")
    parameters = {p.name: p for p in NOISE_PARAMETERS}
    ranges: dict[str, tuple[Range, ...]] = {}
    for name, entry in raw.items():
        key = f"{where}.{name}"
        if name in DARKENING_LIMITS:
            ranges[name] = (_interval(entry, key, lambda v, w, n=name: _darkening_value(v, w, n)),)
        elif name in parameters:
            parameter = parameters[name]

            def check(v: Any, w: str, p: Parameter = parameter) -> float:
                return _noise_value(v, w, p)

            # A vector parameter takes one pair per value, or one pair shared by all of them.
            if parameter.size > 1 and isinstance(entry, list) and entry and isinstance(entry[0], list):
                if len(entry) != parameter.size:
                    raise ProfileError(f"{key} must hold {parameter.size} [low, high] pairs, got {entry!r}")
                ranges[name] = tuple(_interval(item, f"{key}[{i}]", check) for i, item in enumerate(entry))
            else:
                ranges[name] = (_interval(entry, key, check),) * parameter.size
        else:
            known = ", ".join((*NOISE_PARAMETER_NAMES, *DARKENING_LIMITS))
            raise ProfileError(f"{key} is not a parameter; known: {known}")
    return ranges


def parse_profile(document: Any, *, source: str = "profile") -> Profile:
    """Validate a decoded JSON document and build the profile.

    Args:
        document: the decoded JSON value.
        source: the file name or label that error messages start with.

    Raises:
        ProfileError: naming the field and the offending value.
    """
    if not isinstance(document, dict):
        raise ProfileError(f"{source}: a profile must be a JSON object, got {type(document).__name__}")
    try:
        return _parse(document)
    except ProfileError as error:
        raise ProfileError(f"{source}: {error}") from None


def _parse(document: dict[str, Any]) -> Profile:
    known_keys = {"format", "version", "noise", "darkening", "ranges", "meta"}
    unknown = sorted(set(document) - known_keys)
    if unknown:
        raise ProfileError(f"unknown field {unknown[0]!r}; a profile has {', '.join(sorted(known_keys))}")
    if document.get("format") != PROFILE_FORMAT:
        raise ProfileError(f"format must be {PROFILE_FORMAT!r}, got {document.get('format')!r}")
    version = document.get("version")
    if version not in READABLE_VERSIONS or isinstance(version, bool):
        readable = " and ".join(str(v) for v in READABLE_VERSIONS)
        raise ProfileError(f"unsupported version {version!r}; this darksynth reads versions {readable}")
    raw_noise = document.get("noise")
    if not isinstance(raw_noise, dict):
        raise ProfileError(f"noise must be an object with {', '.join(NOISE_PARAMETER_NAMES)}, got {raw_noise!r}")
    extra = sorted(set(raw_noise) - set(NOISE_PARAMETER_NAMES))
    if extra:
        raise ProfileError(f"noise.{extra[0]} is not a noise parameter; known: {', '.join(NOISE_PARAMETER_NAMES)}")
    noise: dict[str, tuple[float, ...]] = {}
    for parameter in NOISE_PARAMETERS:
        key = f"noise.{parameter.name}"
        if parameter.model != "paper":
            # sRGB-model parameters arrived with version 2 and are optional there: neutral when absent.
            if parameter.name in raw_noise and version == 1:
                raise ProfileError(f"{key} needs profile version 2, this document is version 1")
            if parameter.name not in raw_noise:
                noise[parameter.name] = (parameter.neutral,) * parameter.size
                continue
        elif parameter.name not in raw_noise:
            raise ProfileError(f"{key} is missing")
        noise[parameter.name] = _values(raw_noise[parameter.name], key, parameter)

    darkening = None
    if document.get("darkening") is not None:
        raw = document["darkening"]
        if not isinstance(raw, dict) or set(raw) != set(DARKENING_LIMITS):
            raise ProfileError(f"darkening must be an object with alpha and gamma, got {raw!r}")
        darkening = Darkening(
            alpha=_darkening_value(raw["alpha"], "darkening.alpha", "alpha"),
            gamma=_darkening_value(raw["gamma"], "darkening.gamma", "gamma"),
        )
    ranges = _ranges(document.get("ranges", {}), "ranges")
    meta = document.get("meta", {})
    if not isinstance(meta, dict):
        raise ProfileError(f"meta must be an object, got {meta!r}")
    return Profile(noise=noise, darkening=darkening, ranges=ranges, meta=meta)


def validate_profile(profile: Profile) -> Profile:
    """Check a profile built in Python with the same rules as one read from JSON; returns the normalised copy."""
    return parse_profile(profile_to_dict(profile), source="profile")


def profile_to_dict(profile: Profile) -> dict[str, Any]:
    """The JSON document of a profile (scalars as numbers, vectors as lists)."""
    sizes = {p.name: p.size for p in NOISE_PARAMETERS}
    document: dict[str, Any] = {
        "format": PROFILE_FORMAT,
        "version": PROFILE_VERSION,
        "noise": {
            name: (list(values) if sizes.get(name, 1) > 1 else values[0]) if values else None
            for name, values in profile.noise.items()
        },
    }
    if profile.darkening is not None:
        document["darkening"] = {"alpha": profile.darkening.alpha, "gamma": profile.darkening.gamma}
    if profile.ranges:
        document["ranges"] = {
            name: ([list(pair) for pair in pairs] if sizes.get(name, 1) > 1 else list(pairs[0]))
            for name, pairs in profile.ranges.items()
        }
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
    return parse_profile(document, source=str(path))


def save_profile(path: str | Path, profile: Profile) -> None:
    """Write a profile as indented JSON, atomically."""
    write_text_atomic(Path(path), json.dumps(profile_to_dict(profile), indent=2) + "\n")


def default_profile_path() -> Path:
    """The profile shipped with the package, used by ``demo`` and as a starting point."""
    return Path(__file__).parent / "data" / "default_profile.json"
