"""The one-way data flow of the layout (docs/layout.md), checked on the import graph of the package.

Folders are layers. Every *unit* of the package (a subpackage such as ``robot``, or a top-level module
such as ``path``) sits in one layer, and a module may import from its own layer and the layers before
it, never from a later one (that would be reaching back up the flow)::

    shared ground (errors, extras, types, files, validation) -> path -> robot, kinematics -> scene -> sensing -> planar
    -> index -> search -> control -> sim -> viz -> bench -> cli (and the public API, __init__)

``scene`` comes after ``robot`` because its clearance measures the robot's links, and ``planar`` (pure
kernels) after ``scene`` because its distances take the scene's shapes. ``index`` holds the robot
loader: a loaded robot carries its structural ranks, which the AMSI computes.

Besides the layers: no two units import each other, even within a layer (a folder cycle); no two
modules import each other (a module cycle, which only an import inside a function can hide, as
``bench.scenes`` once did with the witness); and no module of ``control/laws/`` (one class per
controller name) imports another law. Every import counts, those inside functions too. One test
collects every violation and prints them all.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "previewctl"

API = "__init__"
"""The unit of the package's own ``__init__`` (the public API), which imports from every layer."""

LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "extras", "types", "files", "validation"),
    ("path",),
    ("robot", "kinematics"),
    ("scene",),
    ("sensing",),
    ("planar",),
    ("index",),
    ("search",),
    ("control",),
    ("sim",),
    ("viz",),
    ("bench",),
    ("cli", "__main__", API),
)

LAWS = "control.laws"
"""The folder of the control laws: none of its modules imports another (its ``__init__`` may list them)."""


@dataclass(frozen=True)
class Import:
    """One import of a package module by another.

    Attributes:
        where: ``file:line`` of the import statement.
        importer: the importing module, dotted and relative to the package (``""``: the package itself).
        imported: the imported module, likewise.
        lazy: whether the import runs inside a function (at call time, not when the module loads).
    """

    where: str
    importer: str
    imported: str
    lazy: bool = False


def unit(module: str) -> str:
    """The unit of ``module``: its folder (first dotted part), or the module itself at the top level."""
    return module.split(".")[0] or API


def layer_of(module: str) -> int:
    """The layer of ``module``'s unit, or -1 if the unit has none."""
    return next((i for i, units in enumerate(LAYERS) if unit(module) in units), -1)


def package_modules() -> dict[str, Path]:
    """Every module of the package by dotted name (relative; a package by its ``__init__``)."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _resolve(node: ast.Import | ast.ImportFrom, importer: str, is_package: bool, known: set[str]) -> list[str]:
    """The package modules ``node`` imports (relative names), resolving ``from x import module``."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
        return [n.removeprefix("previewctl").removeprefix(".") for n in names if n.split(".")[0] == "previewctl"]
    if node.level:  # relative: from its package (``level`` 1), or further up
        base = importer.split(".") if is_package else importer.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        absolute = ".".join(["previewctl", *filter(None, base), *([node.module] if node.module else [])])
    else:
        absolute = node.module or ""
    if absolute.split(".")[0] != "previewctl":
        return []
    module = absolute.removeprefix("previewctl").removeprefix(".")
    found = [f"{module}.{a.name}".lstrip(".") for a in node.names if f"{module}.{a.name}".lstrip(".") in known]
    return found if len(found) == len(node.names) else [*found, module]


def read_imports(module: str, where: str, source: str, is_package: bool, known: set[str]) -> list[Import]:
    """The imports of package modules in ``source``, the text of ``module`` (in file ``where``)."""
    tree = ast.parse(source, where)
    lazy = {
        id(node)
        for scope in ast.walk(tree)
        if isinstance(scope, (ast.FunctionDef, ast.AsyncFunctionDef))
        for node in ast.walk(scope)
    }
    return [
        Import(f"{where}:{node.lineno}", module, imported, id(node) in lazy)
        for node in ast.walk(tree)
        if isinstance(node, (ast.Import, ast.ImportFrom))
        for imported in _resolve(node, module, is_package, known)
    ]


def imports() -> list[Import]:
    """Every import of a package module in the package, those inside functions too."""
    modules = package_modules()
    return [
        found
        for module, path in modules.items()
        for found in read_imports(
            module, str(path.relative_to(PACKAGE.parent)), path.read_text(), path.name == "__init__.py", set(modules)
        )
    ]


# ----------------------------------------------------------------------------------- the rules


def unplaced(modules: Iterable[str]) -> list[str]:
    """Modules whose unit has no layer, and listed units with no module (a stale entry)."""
    units = {unit(m) for m in modules}
    listed = {u for layer in LAYERS for u in layer}
    return [f"{u}: no layer (add it to LAYERS)" for u in sorted(units - listed)] + [
        f"{u}: listed in LAYERS but no such module or folder" for u in sorted(listed - units)
    ]


def back_up(found: Iterable[Import]) -> list[str]:
    """Imports that reach a later layer."""
    return [
        f"{i.where}: {i.importer} ({unit(i.importer)}, layer {layer_of(i.importer)}) imports {i.imported} "
        f"({unit(i.imported)}, layer {layer_of(i.imported)}){' inside a function' if i.lazy else ''}"
        for i in found
        if layer_of(i.imported) > layer_of(i.importer)
    ]


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return out


def cycles(found: Iterable[Import], kind: str) -> list[str]:
    """Folders (``kind="folder"``: units) or modules (``"module"``) that import each other, directly or round a
    loop: each loop with one import of every step of it (and how many more there are)."""
    key = unit if kind == "folder" else str
    steps: dict[tuple[str, str], list[Import]] = {}
    for i in found:
        if key(i.importer) != key(i.imported):
            steps.setdefault((key(i.importer), key(i.imported)), []).append(i)
    edges: dict[str, set[str]] = {}
    for a, b in steps:
        edges.setdefault(a, set()).add(b)
    out = []
    for component in _cycles(edges):
        lines = [
            f"    {a} -> {b}: {i.where} ({i.importer} imports {i.imported}{' inside a function' if i.lazy else ''})"
            + (f" and {len(rest)} more" if rest else "")
            for (a, b), (i, *rest) in sorted(steps.items())
            if a in component and b in component
        ]
        out.append(f"{kind} cycle {' <-> '.join(component)}:\n" + "\n".join(lines))
    return out


def law_imports(found: Iterable[Import], laws: str = LAWS) -> list[str]:
    """Imports of one control law (or of the laws' package) by another law."""

    def is_law(module: str) -> bool:
        return module.startswith(laws + ".")

    return [
        f"{i.where}: law {i.importer} imports {i.imported}; a law stands alone"
        for i in found
        if is_law(i.importer) and (is_law(i.imported) or i.imported == laws) and i.importer != i.imported
    ]


def violations(found: Iterable[Import], modules: Iterable[str]) -> list[str]:
    """Every broken rule of the import graph."""
    found = list(found)
    return [*unplaced(modules), *back_up(found), *cycles(found, "folder"), *cycles(found, "module"),
            *law_imports(found)]


# ----------------------------------------------------------------------------------------- tests


def test_the_import_graph_follows_the_layers() -> None:
    found = violations(imports(), package_modules())
    assert found == [], f"{len(found)} violation(s) of the layers:\n" + "\n".join(found)


def test_every_form_of_import_is_read() -> None:
    """Absolute, relative, of a module or of a name, at the top or inside a function: each is one edge."""
    source = """
import numpy
import previewctl.scene.shapes
from previewctl import errors
from previewctl.planar import kernels
from previewctl.robot.model import Robot
from . import amsi
from .potential import Potential
from ..scene import motion


def later():
    from previewctl.search.ga import OneStepGA
"""
    known = {"errors", "scene.shapes", "scene.motion", "planar.kernels", "robot.model", "index.amsi",
             "index.potential", "search.ga"}
    found = read_imports("index.evaluator", "e.py", source, False, known)
    assert [(i.where, i.imported, i.lazy) for i in found] == [
        ("e.py:3", "scene.shapes", False),
        ("e.py:4", "errors", False),
        ("e.py:5", "planar.kernels", False),
        ("e.py:6", "robot.model", False),
        ("e.py:7", "index.amsi", False),
        ("e.py:8", "index.potential", False),
        ("e.py:9", "scene.motion", False),
        ("e.py:13", "search.ga", True),
    ]


def test_the_check_can_fail() -> None:
    """Synthetic graphs with each kind of violation are caught, all of them in one list."""
    up = Import("search/ga.py:1", "search.ga", "control.preview")
    loop = [Import("a:1", "robot.model", "kinematics"), Import("b:2", "kinematics", "robot.reach")]
    hidden = [Import("c:3", "bench.scenes", "bench.witness", lazy=True), Import("d:4", "bench.witness", "bench.scenes")]
    law = Import("e:5", "control.laws.multi", "control.laws.preview")
    found = violations([up, *loop, *hidden, law], ["search.ga", "widgets.thing", *package_modules()])
    assert len(found) == 5, "\n".join(found)
    assert found[0].startswith("widgets: no layer")
    assert found[1].startswith("search/ga.py:1: search.ga (search, layer 7) imports control.preview (control, layer 8)")
    assert found[2].startswith("folder cycle kinematics <-> robot:")
    assert found[3] == (
        "module cycle bench.scenes <-> bench.witness:\n"
        "    bench.scenes -> bench.witness: c:3 (bench.scenes imports bench.witness inside a function)\n"
        "    bench.witness -> bench.scenes: d:4 (bench.witness imports bench.scenes)"
    )
    assert found[4].startswith("e:5: law control.laws.multi imports control.laws.preview")


def test_law_imports_on_synthetic_laws() -> None:
    """A law may import anything below it, and the laws' ``__init__`` may list the laws; a law never imports
    another law or the laws' package."""
    allowed = [
        Import("a:1", "control.laws.multi", "control.tracking"),
        Import("b:2", "control.laws", "control.laws.multi"),
        Import("c:3", "control.factory", "control.laws.multi"),
    ]
    assert law_imports(allowed) == []
    refused = [
        Import("d:4", "control.laws.reach", "control.laws.multi"),
        Import("e:5", "control.laws.reach", "control.laws"),
    ]
    assert [line.split(":")[0] for line in law_imports(refused)] == ["d", "e"]
