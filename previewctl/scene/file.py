"""Obstacles, scenes that move, and arm-obstacle distances through Pinocchio's geometry layer (Coal).

A :class:`Scene` is a tuple of :class:`Obstacle`, each a Coal shape plus a :mod:`previewctl.scene.motion`
(static by default), so the scene can be asked for its state at any time. :class:`Clearance` puts
the robot's guarded geometry and the obstacles into one ``pin.GeometryModel`` with one collision pair
per (guarded geometry, obstacle); ``pin.computeDistances`` then does all pairs in one C++ call.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib
from previewctl.errors import SceneError
from previewctl.scene.motion import Static, motion_from_dict, rpy_to_matrix
from previewctl.scene.shapes import (
    Box,
    Capsule,
    Cylinder,
    Halfspace,
    Mesh,
    Obstacle,
    Plane,
    Scene,
    Shape,
    Sphere,
    positive,
    vector,
)

_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "sphere": ("radius",),
    "box": ("size",),
    "capsule": ("radius", "length"),
    "cylinder": ("radius", "length"),
    "halfspace": ("normal", "offset"),
    "plane": ("normal", "offset"),
    "mesh": ("path", "scale", "convex"),
}
_PLACEMENT_KEYS = ("position", "rpy", "motion")


def _shape_from_dict(where: str, kind: str, spec: Mapping[str, object], base_dir: Path) -> Shape:
    if kind == "sphere":
        return Sphere(positive(f"{where}.radius", spec.get("radius")))
    if kind == "box":
        size = vector(f"{where}.size", spec.get("size"))
        for axis, value in zip("xyz", size, strict=True):
            positive(f"{where}.size.{axis}", value)
        return Box(size)  # type: ignore[arg-type]
    if kind in ("capsule", "cylinder"):
        radius = positive(f"{where}.radius", spec.get("radius"))
        length = positive(f"{where}.length", spec.get("length"))
        return Capsule(radius, length) if kind == "capsule" else Cylinder(radius, length)
    if kind in ("halfspace", "plane"):
        normal = np.array(vector(f"{where}.normal", spec.get("normal")))
        if np.linalg.norm(normal) < 1e-12:
            raise SceneError(f"{where}.normal must be non-zero, got {spec.get('normal')!r}")
        offset = spec.get("offset", 0.0)
        if isinstance(offset, bool) or not isinstance(offset, (int, float)):
            raise SceneError(f"{where}.offset must be a number [m], got {offset!r}")
        unit = tuple(float(v) for v in normal / np.linalg.norm(normal))
        return (Halfspace if kind == "halfspace" else Plane)(unit, float(offset))  # type: ignore[arg-type]
    path = spec.get("path")
    if not isinstance(path, str):
        raise SceneError(f"{where}.path must be a file name, got {path!r}")
    resolved = Path(path) if Path(path).is_absolute() else base_dir / path
    if not resolved.is_file():
        raise SceneError(f"{where}.path: mesh file {str(resolved)!r} does not exist")
    scale = spec.get("scale", 1.0)
    scale3 = (float(scale),) * 3 if isinstance(scale, (int, float)) else vector(f"{where}.scale", scale)
    convex = spec.get("convex", False)
    if not isinstance(convex, bool):
        raise SceneError(f"{where}.convex must be true or false, got {convex!r}")
    return Mesh(str(resolved), scale3, convex)  # type: ignore[arg-type]


def obstacle_from_dict(spec: Mapping[str, object], where: str, base_dir: Path = Path(".")) -> Obstacle:
    """Build one obstacle from a TOML table.

    Example: ``{"name": "ball", "shape": "sphere", "radius": 0.1, "position": [0.4, 0.5, 0]}``; a
    moving one has a ``motion`` sub-table instead of ``position``/``rpy`` (see :mod:`previewctl.scene.motion`).
    """
    if not isinstance(spec, Mapping):
        raise SceneError(f"{where} must be a table, got {spec!r}")
    kind = spec.get("shape")
    if kind not in _SHAPE_KEYS:
        raise SceneError(f"{where}.shape is {kind!r}; valid: {', '.join(_SHAPE_KEYS)}")
    valid = ("name", "shape", *_SHAPE_KEYS[str(kind)], *_PLACEMENT_KEYS)
    for key in spec:
        if key not in valid:
            raise SceneError(f"{where}: unknown key {key!r} for a {kind}; valid: {', '.join(valid)}")
    name = spec.get("name", where)
    if not isinstance(name, str) or not name:
        raise SceneError(f"{where}.name must be a non-empty string, got {name!r}")
    shape = _shape_from_dict(where, str(kind), spec, base_dir)
    if "motion" in spec:
        if "position" in spec or "rpy" in spec:
            raise SceneError(f"{where}: give either 'motion' or 'position'/'rpy', not both")
        motion_spec = spec["motion"]
        if not isinstance(motion_spec, Mapping):
            raise SceneError(f"{where}.motion must be a table, got {motion_spec!r}")
        motion = motion_from_dict(motion_spec, f"{where}.motion")
    else:
        raw = spec.get("position", (0.0, 0.0, 0.0))
        if isinstance(raw, (list, tuple)) and len(raw) == 2:
            raw = (*raw, 0.0)
        position = np.array(vector(f"{where}.position", raw))
        rotation = rpy_to_matrix(np.array(vector(f"{where}.rpy", spec.get("rpy", (0.0, 0.0, 0.0)))))
        motion = Static(position, rotation)
    return Obstacle(name, shape, motion)


def scene_from_dict(
    obstacles: Sequence[Mapping[str, object]], where: str = "obstacles", base_dir: Path = Path(".")
) -> Scene:
    """Build a scene from a list of obstacle tables (``[[obstacles]]`` in TOML)."""
    if not isinstance(obstacles, (list, tuple)):
        raise SceneError(f"{where} must be a list of tables ([[{where}]]), got {obstacles!r}")
    return Scene(tuple(obstacle_from_dict(o, f"{where}[{i}]", base_dir) for i, o in enumerate(obstacles)))


def load_scene(path: str | Path) -> Scene:
    """Read a scene TOML file holding ``[[obstacles]]`` tables.

    Raises:
        SceneError: missing file, TOML syntax error, or a bad obstacle (named in the message).
    """
    file = Path(path)
    if not file.is_file():
        raise SceneError(f"scene file {str(file)!r} does not exist")
    try:
        data = tomllib.loads(file.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene file {str(file)!r} is not valid TOML: {exc}") from exc
    unknown = [k for k in data if k != "obstacles"]
    if unknown:
        raise SceneError(f"scene file {str(file)!r}: unknown key {unknown[0]!r}; valid: obstacles")
    return scene_from_dict(data.get("obstacles", []), "obstacles", file.parent)
