"""The one-way data flow of the README's layout, checked on the import graph of the package.

Every module belongs to one layer; a module may import from its own layer and the layers before it,
never from a later one (that would be reaching back up the flow):

    base -> inputs -> robot -> index -> search -> control -> sim -> viz -> bench -> cli

``robot.load`` sits after the index: loading a robot computes its structural ranks with
:func:`previewctl.index.amsi.avoidance` (a fact of the robot, computed once), and nothing upstream
imports the loader. ``control.params`` sits in control although ``sim.scenario`` reads it: the
scenario builds the controller's parameters, as it builds the robot and the scene.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "previewctl"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "types", "files", "validation"),
    ("path", "scene.motion", "scene.shapes", "scene.schema", "scene.file", "scene.solid", "robot.joints",
     "robot.chain", "planar", "robot.planar", "planar.kernels", "planar.distance"),
    ("robot.model", "robot.geometry", "robot.reach", "kinematics", "scene.clearance"),
    ("index",),
    ("search",),
    ("control",),
    ("sim",),
    ("viz",),
    ("bench",),
    ("cli", "__main__", ""),
)


def layer_of(module: str) -> int:
    """The layer of ``module`` (dotted, relative to the package): its longest listed prefix."""
    best, found = -1, -1
    for index, prefixes in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".") or prefix == "") and len(prefix) > best:
                best, found = len(prefix), index
    return found


def imports() -> list[tuple[str, str]]:
    """``(importer, imported)`` pairs of package modules (relative dotted names)."""
    pairs = []
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("previewctl."):
                pairs.append((module, node.module.removeprefix("previewctl.")))
    return pairs


def test_every_module_has_a_layer() -> None:
    modules = {importer for importer, _ in imports()} | {imported for _, imported in imports()}
    assert [m for m in modules if layer_of(m) < 0] == []


@pytest.mark.parametrize(("importer", "imported"), sorted(set(imports())))
def test_no_import_reaches_back_up_the_flow(importer: str, imported: str) -> None:
    assert layer_of(imported) <= layer_of(importer), (
        f"{importer} (layer {layer_of(importer)}) imports {imported} (layer {layer_of(imported)})"
    )


def test_the_check_can_fail() -> None:
    """A reversed import is caught: the search importing the controller would be a violation."""
    assert layer_of("control.preview") > layer_of("search.ga")
