"""Imports go strictly downward: the layer of every darksynth module and what it may import.

Layers, lowest first (a module may import its own package and any lower layer, never a higher one or a
sibling of its own layer):

0. ``errors``, ``tensors``, ``seeding``, ``version``: conventions that import nothing of darksynth;
1. ``io`` (files, videos, atomic writes), ``light`` (light beyond noise, pure: the darkening, the tone distribution
   of images and the darkening line fitted between two of them, the per-block tone statistics, motion blur, camera
   shake, flicker, the shutter stage), ``commands`` (the command line's shape, without its code),
   ``console_progress`` (how a command shows its progress), ``worker_pool`` (worker processes that end with their
   parent);
2. ``noise``: the components, their table, the carrier of values, the composer;
3. ``profile``, ``cameras`` (the bank of real cameras, the prior over them and its presets), ``exposure``
   (an input's darkening matched to the reference's tones: it simulates the profile's noise on the input, so it sits
   above ``noise``, out of ``light``, which sits below: no package imports one above it);
4. ``recipe`` (a clip's parameters chosen in one place: the draws, the matched darkening and colour cast),
   ``models``, ``apply_outputs`` (what ``apply`` may write where: claiming outputs, resuming);
5. ``synthesize`` (the composer run on images, clips and streams);
6. ``apply``, ``training``, ``transforms``;
7. ``baselines``, ``datasets``, ``estimation`` (reference -> profile, one module per stage, see below), ``preview``
   (it runs ``apply``'s synthesis);
8. ``evaluation``, ``demo``;
9. ``cli``, the package ``__init__``; 10. ``main``, the entry point (the light app, or the cli); 11. ``__main__``,
   which only calls it.

A unit is a top-level module or package, or a module of a package named on its own in :data:`LAYERS` (none is
today): such a module has its layer, the rest of its package the package's.

The pure core (``tensors``, ``light``, ``noise``) also never imports ``io``: reading and writing files is
for the edges, so the core runs on tensors alone.

Inside ``estimation`` the stages have layers of their own: the reading of the reference, the column decision, the
denoiser, the flat blocks and the spectral statistics import no other stage; the spectral fit reads the spectral
statistics; the coarse anchor, the still blocks of a clip and the frame-to-frame fit read the flat blocks and the
spectral fit; the spectrum's checks read the anchor, and the spectrum all of them; the self-check (the profile put
back on its own denoised reference) reads the flat blocks and the noise estimate reads it; the network reads the
crop grid and the darkening the reference's frames; ``assemble`` alone runs them all. Inside ``evaluation`` the parts
(the pairs, methods, measures, report, run) have layers of their own in the same way (``EVALUATION_PARTS``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parent.parent / "src" / "darksynth"

LAYERS: dict[str, int] = {
    "errors": 0,
    "tensors": 0,
    "seeding": 0,
    "version": 0,
    "commands": 1,
    "console_progress": 1,
    "io": 1,
    "light": 1,
    "worker_pool": 1,
    "noise": 2,
    "profile": 3,
    "cameras": 3,
    "exposure": 3,
    "recipe": 4,
    "models": 4,
    "apply_outputs": 4,
    "synthesize": 5,
    "apply": 6,
    "training": 6,
    "transforms": 6,
    "baselines": 7,
    "datasets": 7,
    "estimation": 7,
    "preview": 7,
    "evaluation": 8,
    "demo": 8,
    "cli": 9,
    "main": 10,
    "__main__": 11,
    "__init__": 9,
}

PURE_CORE = frozenset({"tensors", "light", "noise"})

ESTIMATION_STAGES: dict[str, int] = {
    "__init__": 0,
    "reference": 0,
    "findings": 0,
    "columns": 0,
    "nonlocal_means": 0,
    "flat_blocks": 0,
    "jpeg_grid": 0,
    "jpeg_quality": 0,
    "spectral_statistics": 0,
    "texture_fit": 0,
    "spectral_fit": 1,
    "block_check": 1,
    "self_check": 2,
    "coarse_anchor": 2,
    "camera_conditional": 2,
    "still_blocks": 2,
    "spectrum_checks": 3,
    "resynthesis": 3,
    "persistence_fit": 4,
    "readings": 5,
    "spectrum": 6,
    "network_reading": 1,
    "darkening_reading": 1,
    "noise_estimate": 7,
    "light_reading": 3,
    "flicker_reading": 0,
    "cross_spectra": 0,
    "shutter_confidence": 0,
    "shutter_fit": 1,
    "motion": 2,
    "assemble": 8,
}
"""The layer of every module of the ``estimation`` package among its siblings."""


def _named_unit(parts: list[str]) -> str:
    """The unit of a module's dotted path below ``darksynth``: the module itself where :data:`LAYERS` names it,
    else its top-level module or package."""
    module = ".".join(parts[:2])
    return module if module in LAYERS else parts[0]


def _unit(path: Path) -> str:
    """The unit (see :data:`LAYERS`) a source file belongs to."""
    return _named_unit([part.removesuffix(".py") for part in path.relative_to(SOURCE).parts])


def _imported_units(path: Path) -> set[str]:
    units = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "darksynth" and len(parts) > 2:
                units.add(_named_unit(parts[1:]))
            elif parts[0] == "darksynth" and len(parts) > 1 and isinstance(node, ast.ImportFrom):
                # `from darksynth.light import x`: x may be a unit of its own.
                units.update(_named_unit([parts[1], alias.name]) for alias in node.names)
            elif parts[0] == "darksynth" and len(parts) > 1:
                units.add(parts[1])
            elif parts[0] == "darksynth" and isinstance(node, ast.ImportFrom):
                # `from darksynth import x`: x is the unit.
                units.update(alias.name for alias in node.names)
    return units


def _imported_parts(path: Path, package: str) -> set[str]:
    """The modules (or subpackages) of a darksynth package a source file imports, in any of the three forms:
    ``from darksynth.<package> import x``, ``from darksynth.<package>.x import ...``,
    ``import darksynth.<package>.x``."""
    prefix = ["darksynth", *package.split(".")]
    parts_seen = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module == f"darksynth.{package}" and node.level == 0:
            parts_seen.update(alias.name for alias in node.names)
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[: len(prefix)] == prefix and len(parts) > len(prefix):
                parts_seen.add(parts[len(prefix)])
    return parts_seen


ESTIMATION_PARTS = tuple(sorted(p.parent.name for p in (SOURCE / "estimation").glob("*/__init__.py")))
"""The subpackages of ``estimation`` (split by what is measured): their modules are stages like the package's own."""


def _imported_stages(path: Path) -> set[str]:
    """The modules of the ``estimation`` package and its subpackages a source file imports."""
    stages = _imported_parts(path, "estimation") - set(ESTIMATION_PARTS)
    for part in ESTIMATION_PARTS:
        stages |= _imported_parts(path, f"estimation.{part}")
    return stages


SOURCES = sorted(p for p in SOURCE.rglob("*.py"))
STAGES = sorted((SOURCE / "estimation").rglob("*.py"))


def test_every_module_has_a_layer() -> None:
    units = {_unit(p) for p in SOURCES}
    assert units <= set(LAYERS), f"modules without a layer: {sorted(units - set(LAYERS))}"


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(SOURCE)))
def test_imports_only_go_down(path: Path) -> None:
    unit = _unit(path)
    if unit == "__init__":
        return
    wrong = []
    for imported in _imported_units(path) - {unit}:
        if imported not in LAYERS:
            continue  # a name re-exported by the package, not a module
        if LAYERS[imported] >= LAYERS[unit]:
            wrong.append(f"{imported} (layer {LAYERS[imported]})")
        if unit in PURE_CORE and imported == "io":
            wrong.append("io (the pure core reads no files)")
    assert not wrong, f"{path.relative_to(SOURCE)} (layer {LAYERS[unit]}) imports upward or sideways: {wrong}"


def test_every_estimation_module_has_a_stage_layer() -> None:
    stages = {p.stem for p in STAGES}
    assert stages == set(ESTIMATION_STAGES), f"stages without a layer: {sorted(stages - set(ESTIMATION_STAGES))}"


@pytest.mark.parametrize("path", STAGES, ids=lambda p: str(p.relative_to(SOURCE / "estimation")))
def test_estimation_stages_import_only_lower_stages(path: Path) -> None:
    wrong = [
        f"{stage} (stage {ESTIMATION_STAGES[stage]})"
        for stage in _imported_stages(path) - {path.stem}
        if ESTIMATION_STAGES.get(stage, 0) >= ESTIMATION_STAGES[path.stem]
    ]
    assert not wrong, (
        f"estimation/{path.name} (stage {ESTIMATION_STAGES[path.stem]}) imports upward or sideways: {wrong}"
    )


EVALUATION_PARTS: dict[str, int] = {
    "__init__": 0,
    "pairs": 0,
    "methods": 1,
    "measures": 2,
    "report": 3,
    "run": 4,
}
"""The layer of every part of the ``evaluation`` package: the real pairs, the methods that make synthetic noise for
them, the measures that compare it with the real (a downstream denoiser runs the methods), the reports of the
results, and the run that does it all."""

EVALUATION_SOURCES = sorted((SOURCE / "evaluation").rglob("*.py"))


def _evaluation_part(path: Path) -> str:
    return path.relative_to(SOURCE / "evaluation").parts[0].removesuffix(".py")


def _imported_evaluation_parts(path: Path) -> set[str]:
    """The parts of the ``evaluation`` package a source file imports."""
    return _imported_parts(path, "evaluation")


def test_every_evaluation_part_has_a_layer() -> None:
    parts = {_evaluation_part(p) for p in EVALUATION_SOURCES}
    assert parts == set(EVALUATION_PARTS), f"parts without a layer: {sorted(parts - set(EVALUATION_PARTS))}"


@pytest.mark.parametrize("path", EVALUATION_SOURCES, ids=lambda p: str(p.relative_to(SOURCE)))
def test_evaluation_parts_import_only_lower_parts(path: Path) -> None:
    own = _evaluation_part(path)
    wrong = [
        f"{part} (layer {EVALUATION_PARTS[part]})"
        for part in _imported_evaluation_parts(path) - {own}
        if EVALUATION_PARTS.get(part, 0) >= EVALUATION_PARTS[own]
    ]
    assert not wrong, f"{path.relative_to(SOURCE)} (layer {EVALUATION_PARTS[own]}) imports upward or sideways: {wrong}"


def test_the_evaluation_check_sees_a_part_import(tmp_path: Path) -> None:
    """The control: a module importing parts in each of the three forms is seen to."""
    module = tmp_path / "bad.py"
    module.write_text(
        "from darksynth.evaluation.run.job import run_evaluation\n"
        "import darksynth.evaluation.report.summary\n"
        "from darksynth.evaluation import pairs\n",
        encoding="utf-8",
    )
    assert _imported_evaluation_parts(module) == {"run", "report", "pairs"}


def test_the_check_sees_an_upward_import(tmp_path: Path) -> None:
    """The control: a module of the noise layer importing the profile is caught."""
    module = tmp_path / "bad.py"
    module.write_text("from darksynth.profile import load_profile\nimport darksynth.io.arrays\n", encoding="utf-8")
    assert _imported_units(module) == {"profile", "io"}


def test_a_module_with_a_layer_of_its_own_is_its_own_unit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The control: a module of a package given a layer of its own (here ``light.tones``, for the test) is a unit
    apart from its package both as a file and as an import, so a module of the package importing it is caught as
    importing upward. (``exposure`` was such a module of ``light`` until it became a module of its own.)"""
    monkeypatch.setitem(LAYERS, "light.tones", 3)
    assert _unit(SOURCE / "light" / "tones.py") == "light.tones"
    assert _unit(SOURCE / "light" / "darkening.py") == "light"
    module = tmp_path / "bad.py"
    module.write_text(
        "from darksynth.light.tones import colour_cast\n"
        "from darksynth.light import darkening\n"
        "import darksynth.light.shutter\n",
        encoding="utf-8",
    )
    assert _imported_units(module) == {"light.tones", "light"}


def test_the_stage_check_sees_a_stage_import(tmp_path: Path) -> None:
    """The control: a module importing stages in each of the three forms is seen to."""
    module = tmp_path / "bad.py"
    module.write_text(
        "from darksynth.estimation.assemble import estimate\n"
        "import darksynth.estimation.noise.network_reading\n"
        "from darksynth.estimation.noise import columns\n",
        encoding="utf-8",
    )
    assert _imported_stages(module) == {"assemble", "network_reading", "columns"}
