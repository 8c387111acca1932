"""The noise profile: loading, saving and validation with errors that name the field and the value."""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path
from typing import Any

import pytest
import torch

from darksynth.errors import DarksynthError, ProfileError
from darksynth.light.darkening import Darkening
from darksynth.noise.components import noise_parameter_names, profile_version
from darksynth.profile import (
    Profile,
    default_profile_path,
    load_profile,
    parse_profile,
    save_profile,
)


def _document() -> dict[str, Any]:
    return {
        "format": "darksynth-profile",
        "version": 1,
        "noise": {
            "shot": 0.05,
            "read": 0.01,
            "quantization": 0.004,
            "banding": 0.003,
            "temporal_banding": 0.002,
            "periodic": [0.001, 0.002, 0.003],
        },
        "darkening": {"alpha": 0.2, "gamma": 0.7},
    }


def _write(tmp_path: Path, document: Any) -> Path:
    path = tmp_path / "profile.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


def test_default_profile_loads_with_all_parameters() -> None:
    profile = load_profile(default_profile_path())
    assert tuple(profile.noise) == noise_parameter_names()
    assert profile.noise.to_json()["shot"] == 0.06
    assert profile.noise.to_json()["periodic"] == [0.002, 0.002, 0.002]
    assert profile.darkening == Darkening(alpha=0.2, gamma=0.7)
    assert profile.ranges == {}
    assert "source" in profile.meta


def test_round_trip_of_the_default_profile(tmp_path: Path) -> None:
    profile = load_profile(default_profile_path())
    save_profile(tmp_path / "copy.json", profile)
    assert load_profile(tmp_path / "copy.json") == profile


def test_round_trip_with_ranges_and_meta(tmp_path: Path) -> None:
    document = _document()
    document["ranges"] = {
        "shot": [0.01, 0.1],
        "periodic": [[0.0, 0.01], [0.0, 0.02], [0.001, 0.03]],
        "alpha": [0.1, 0.3],
        "gamma": [0.2, 1.0],
    }
    document["meta"] = {"reference": "night.mp4", "estimator": {"version": 3}}
    profile = load_profile(_write(tmp_path, document))
    path = tmp_path / "saved.json"
    save_profile(path, profile)
    reloaded = load_profile(path)
    assert reloaded == profile
    assert reloaded.ranges["periodic"] == ((0.0, 0.01), (0.0, 0.02), (0.001, 0.03))
    assert reloaded.ranges["alpha"] == ((0.1, 0.3),)
    assert reloaded.meta == {"reference": "night.mp4", "estimator": {"version": 3}}
    assert json.loads(path.read_text(encoding="utf-8"))["noise"]["periodic"] == [0.001, 0.002, 0.003]


def test_periodic_range_as_one_shared_pair_applies_to_all_three_values() -> None:
    document = _document()
    document["ranges"] = {"periodic": [0.0, 0.02]}
    profile = parse_profile(document)
    assert profile.ranges["periodic"] == ((0.0, 0.02),) * 3


def test_periodic_range_as_three_pairs() -> None:
    document = _document()
    document["ranges"] = {"periodic": [[0.0, 0.01], [0.0, 0.02], [0.0, 0.03]]}
    assert parse_profile(document).ranges["periodic"] == ((0.0, 0.01), (0.0, 0.02), (0.0, 0.03))


def _edit(path: tuple[str, ...], value: Any) -> dict[str, Any]:
    document = copy.deepcopy(_document())
    target = document
    for key in path[:-1]:
        target = target.setdefault(key, {})
    target[path[-1]] = value
    return document


def _without_read() -> dict[str, Any]:
    document = _document()
    del document["noise"]["read"]
    return document


# (case, document, fragments the message must contain: the field and the value)
BAD_DOCUMENTS: list[tuple[str, dict[str, Any], tuple[str, ...]]] = [
    ("missing read", _without_read(), ("noise.read", "missing")),
    ("negative", _edit(("noise", "shot"), -0.1), ("noise.shot", "-0.1")),
    ("above maximum", _edit(("noise", "banding"), 1.5), ("noise.banding", "1.5")),
    ("boolean", _edit(("noise", "read"), True), ("noise.read", "True")),
    ("string value", _edit(("noise", "read"), "0.1"), ("noise.read", "'0.1'")),
    ("periodic too short", _edit(("noise", "periodic"), [0.1, 0.2]), ("noise.periodic", "[0.1, 0.2]")),
    ("periodic too long", _edit(("noise", "periodic"), [0.1, 0.2, 0.3, 0.4]), ("noise.periodic", "0.4")),
    ("periodic scalar", _edit(("noise", "periodic"), 0.1), ("noise.periodic", "0.1")),
    ("periodic item negative", _edit(("noise", "periodic"), [0.1, -0.2, 0.3]), ("noise.periodic[1]", "-0.2")),
    ("version 7", _edit(("version",), 7), ("version", "7")),
    ("srgb field in version 1", _edit(("noise", "compression"), 0.3), ("noise.compression", "version 2")),
    (
        "gain below minimum",
        _edit(("version",), 2) | {"noise": {**_document()["noise"], "channel_gain": [0.1, 1.0]}},
        ("noise.channel_gain[0]", "0.1", "0.25"),
    ),
    (
        "correlation out of range",
        _edit(("version",), 2) | {"noise": {**_document()["noise"], "channel_correlation": [0.2, 0.99, 0.1]}},
        ("noise.channel_correlation[1]", "0.99"),
    ),
    (
        "three gains",
        _edit(("version",), 2) | {"noise": {**_document()["noise"], "channel_gain": [1.0, 1.0, 1.0]}},
        ("noise.channel_gain", "list of 2"),
    ),
    ("version true", _edit(("version",), True), ("version", "True")),
    ("wrong format", _edit(("format",), "other-profile"), ("format", "other-profile")),
    ("unknown noise key", _edit(("noise", "dark_current"), 0.1), ("noise.dark_current",)),
    ("unknown top-level key", _edit(("colour",), 1), ("colour",)),
    ("range low > high", _edit(("ranges", "shot"), [0.2, 0.1]), ("ranges.shot", "[0.2, 0.1]")),
    ("range above maximum", _edit(("ranges", "read"), [0.0, 2.0]), ("ranges.read[1]", "2.0")),
    ("range not a pair", _edit(("ranges", "read"), [0.1]), ("ranges.read", "[0.1]")),
    ("range unknown name", _edit(("ranges", "iso"), [1, 2]), ("ranges.iso",)),
    (
        "periodic two pairs",
        _edit(("ranges", "periodic"), [[0.0, 0.1], [0.0, 0.2]]),
        ("ranges.periodic", "[[0.0, 0.1], [0.0, 0.2]]"),
    ),
    (
        "periodic pair reversed",
        _edit(("ranges", "periodic"), [[0.0, 0.1], [0.3, 0.2], [0.0, 0.1]]),
        ("ranges.periodic[1]", "[0.3, 0.2]"),
    ),
    ("alpha range at zero", _edit(("ranges", "alpha"), [0.0, 0.3]), ("ranges.alpha[0]", "0.0")),
    ("alpha zero", _edit(("darkening", "alpha"), 0.0), ("darkening.alpha", "0.0")),
    ("alpha above one", _edit(("darkening", "alpha"), 1.2), ("darkening.alpha", "1.2")),
    ("gamma negative", _edit(("darkening", "gamma"), -1.0), ("darkening.gamma", "-1.0")),
    ("darkening without gamma", _edit(("darkening",), {"alpha": 0.2}), ("darkening", "alpha")),
    ("meta not an object", _edit(("meta",), [1, 2]), ("meta", "[1, 2]")),
    # Found by tests/test_fuzz.py: an integer literal beyond any float raised OverflowError.
    ("integer beyond float", _edit(("noise", "shot"), 10**400), ("noise.shot", "too large for a float")),
    ("range integer beyond float", _edit(("ranges", "shot"), [0, 10**400]), ("ranges.shot[1]", "too large")),
    ("gamma integer beyond float", _edit(("darkening", "gamma"), -(10**400)), ("darkening.gamma", "too large")),
    # Found by tests/test_fuzz.py: a key with a control character broke the message's single line.
    ("range name with a control character", _edit(("ranges", "sh\x1fot"), [0, 1]), ("ranges.'sh\\x1fot'",)),
    ("noise key with a line break", _edit(("noise", "dark\ncurrent"), 0.1), ("noise.'dark\\ncurrent'",)),
]


@pytest.mark.parametrize(("case", "document", "fragments"), BAD_DOCUMENTS, ids=[c[0] for c in BAD_DOCUMENTS])
def test_bad_profile_raises_an_error_naming_field_and_value(
    tmp_path: Path, case: str, document: dict[str, Any], fragments: tuple[str, ...]
) -> None:
    path = _write(tmp_path, document)
    with pytest.raises(ProfileError) as raised:
        load_profile(path)
    message = str(raised.value)
    assert message.startswith(f"{path}: "), message
    for fragment in fragments:
        assert fragment in message, f"{case}: {fragment!r} not in {message!r}"
    assert message.isprintable(), message  # one line: no line break nor other control character
    assert isinstance(raised.value, DarksynthError)


def test_nan_literal_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "nan.json"
    text = json.dumps(_document()).replace('"read": 0.01', '"read": NaN')
    assert "NaN" in text
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProfileError, match=r"noise\.read.*nan") as raised:
        load_profile(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_infinity_literal_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "inf.json"
    path.write_text(json.dumps(_document()).replace('"alpha": 0.2', '"alpha": Infinity'), encoding="utf-8")
    with pytest.raises(ProfileError, match=r"darkening\.alpha.*inf"):
        load_profile(path)


def test_not_json_at_all(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text("shot = 0.1\n", encoding="utf-8")
    with pytest.raises(ProfileError, match="not valid JSON") as raised:
        load_profile(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_deeply_nested_json_is_a_one_line_error(tmp_path: Path) -> None:
    # Found by tests/test_fuzz.py: the JSON decoder's RecursionError came through.
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000, encoding="utf-8")
    with pytest.raises(ProfileError, match="nested too deeply") as raised:
        load_profile(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_a_number_of_too_many_digits_is_a_one_line_error(tmp_path: Path) -> None:
    # Found by tests/test_fuzz.py: Python refuses to convert integers of over 4300 digits with a ValueError.
    path = tmp_path / "digits.json"
    path.write_text('{"version": ' + "9" * 5000 + "}", encoding="utf-8")
    with pytest.raises(ProfileError, match=f"more than {sys.get_int_max_str_digits()} digits") as raised:
        load_profile(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_json_that_is_not_an_object(tmp_path: Path) -> None:
    path = _write(tmp_path, [1, 2, 3])
    with pytest.raises(ProfileError, match="list") as raised:
        load_profile(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "absent.json"
    with pytest.raises(ProfileError, match="no such profile file") as raised:
        load_profile(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_valid_edges_are_accepted() -> None:
    document = _edit(("noise", "shot"), 1.0)
    document["noise"]["read"] = 0
    document["darkening"] = {"alpha": 1.0, "gamma": 10.0}
    document["ranges"] = {"quantization": [0.01, 0.01]}
    profile = parse_profile(document)
    assert profile.noise.to_json()["shot"] == 1.0 and profile.noise.to_json()["read"] == 0.0
    assert profile.darkening == Darkening(1.0, 10.0)
    assert isinstance(profile.noise.to_json()["read"], float)


def test_parse_profile_names_its_source_label() -> None:
    with pytest.raises(ProfileError, match=r"^my label: noise\.shot"):
        parse_profile(_edit(("noise", "shot"), -1), source="my label")


def test_profile_values_are_finite_floats() -> None:
    profile: Profile = parse_profile(_document())
    for values in profile.noise.values():
        assert values.dtype == torch.float64 and bool(values.isfinite().all())


def test_version_1_profile_reads_as_white_uncompressed_noise(tmp_path: Path) -> None:
    profile = load_profile(_write(tmp_path, _document()))
    assert profile.noise.to_json()["channel_gain"] == [1.0, 1.0]
    assert profile.noise.to_json()["correlation_length"] == 0.0
    assert profile.noise.to_json()["channel_correlation"] == [0.0, 0.0, 0.0]
    assert profile.noise.to_json()["compression"] == 0.0
    # Saved again, it becomes a document of the newest version with the same noise.
    save_profile(tmp_path / "v2.json", profile)
    document = json.loads((tmp_path / "v2.json").read_text(encoding="utf-8"))
    assert document["version"] == profile_version() == 6
    assert document["noise"]["channel_gain"] == [1.0, 1.0]
    assert load_profile(tmp_path / "v2.json") == profile


def test_version_2_profile_with_srgb_fields_and_ranges(tmp_path: Path) -> None:
    document = _document()
    document["version"] = 2
    document["noise"].update(
        channel_gain=[1.3, 1.5], correlation_length=0.8, channel_correlation=[0.4, 0.3, 0.6], compression=0.35
    )
    document["ranges"] = {"correlation_length": [0.5, 1.0], "channel_correlation": [-0.2, 0.7]}
    profile = load_profile(_write(tmp_path, document))
    assert profile.noise.to_json()["channel_gain"] == [1.3, 1.5]
    assert profile.noise.to_json()["compression"] == 0.35
    assert profile.ranges["channel_correlation"] == ((-0.2, 0.7),) * 3
    save_profile(tmp_path / "copy.json", profile)
    assert load_profile(tmp_path / "copy.json") == profile
