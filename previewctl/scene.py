"""Obstacles, scenes that move, and arm-obstacle distances through Pinocchio's geometry layer (Coal).

A :class:`Scene` is a tuple of :class:`Obstacle`, each a Coal shape plus a :mod:`previewctl.motion`
(static by default), so the scene can be asked for its state at any time. :class:`Clearance` puts
the robot's guarded geometry and the obstacles into one ``pin.GeometryModel`` with one collision pair
per (guarded geometry, obstacle); ``pin.computeDistances`` then does all pairs in one C++ call.
"""

from __future__ import annotations

import math
import sys
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import SceneError
from previewctl.motion import Motion, Static, motion_from_dict, rpy_to_matrix
from previewctl.robot import Robot

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

Array = NDArray[np.float64]


def _positive(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise SceneError(f"{where} must be a positive number [m], got {value!r}")
    return float(value)


def _vector(where: str, value: object, size: int = 3) -> tuple[float, ...]:
    if (
        not isinstance(value, (list, tuple, np.ndarray))
        or len(value) != size
        or not all(isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(float(v)) for v in value)
    ):
        raise SceneError(f"{where} must be a list of {size} finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


@dataclass(frozen=True)
class Sphere:
    """A ball of ``radius`` [m] centred on the obstacle's position."""

    radius: float

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Sphere(self.radius)


@dataclass(frozen=True)
class Box:
    """A box of edge lengths ``size`` [m] (x, y, z in the obstacle frame), centred on its position."""

    size: tuple[float, float, float]

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Box(*self.size)


@dataclass(frozen=True)
class Capsule:
    """A capsule of ``radius`` [m] whose axis of ``length`` [m] is the obstacle frame's z axis."""

    radius: float
    length: float

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Capsule(self.radius, self.length)


@dataclass(frozen=True)
class Cylinder:
    """A cylinder of ``radius`` [m] and ``length`` [m] along the obstacle frame's z axis."""

    radius: float
    length: float

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Cylinder(self.radius, self.length)


@dataclass(frozen=True)
class Halfspace:
    """The solid ``{x : n . x <= offset}`` in the obstacle frame (``n`` normalised)."""

    normal: tuple[float, float, float]
    offset: float = 0.0

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Halfspace(np.array(self.normal), self.offset)


@dataclass(frozen=True)
class Plane:
    """The (two-sided, zero-thickness) plane ``{x : n . x = offset}`` in the obstacle frame."""

    normal: tuple[float, float, float]
    offset: float = 0.0

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Plane(np.array(self.normal), self.offset)


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh loaded from ``path`` (STL, OBJ, DAE, ...), scaled by ``scale``.

    ``convex=True`` uses its convex hull (fast); ``False`` keeps the exact mesh.
    """

    path: str
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    convex: bool = False

    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape (loaded from disk)."""
        if not Path(self.path).is_file():
            raise SceneError(f"mesh file {self.path!r} does not exist")
        try:
            mesh = coal.MeshLoader().load(self.path, np.array(self.scale))
        except (ValueError, RuntimeError) as exc:
            raise SceneError(f"mesh file {self.path!r} could not be loaded: {exc}") from exc
        if self.convex:
            mesh.buildConvexHull(True, "Qt")
            return mesh.convex
        return mesh


Shape = Sphere | Box | Capsule | Cylinder | Halfspace | Plane | Mesh


@dataclass(frozen=True)
class Obstacle:
    """A named shape whose placement follows ``motion`` (static at the origin by default)."""

    name: str
    shape: Shape
    motion: Motion = field(default_factory=lambda: Static(np.zeros(3)))

    def placement(self, t: float = 0.0) -> pin.SE3:
        """World placement at time ``t`` [s]."""
        position, rotation = self.motion.placement(t)
        return pin.SE3(np.asarray(rotation, float), np.asarray(position, float))


@dataclass(frozen=True)
class Scene:
    """The obstacles around the arm."""

    obstacles: tuple[Obstacle, ...] = ()

    def __post_init__(self) -> None:
        names = [o.name for o in self.obstacles]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise SceneError(f"obstacle names must be unique; repeated: {', '.join(duplicates)}")

    @property
    def names(self) -> tuple[str, ...]:
        """Obstacle names, in order."""
        return tuple(o.name for o in self.obstacles)


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
        return Sphere(_positive(f"{where}.radius", spec.get("radius")))
    if kind == "box":
        size = _vector(f"{where}.size", spec.get("size"))
        for axis, value in zip("xyz", size, strict=True):
            _positive(f"{where}.size.{axis}", value)
        return Box(size)  # type: ignore[arg-type]
    if kind in ("capsule", "cylinder"):
        radius = _positive(f"{where}.radius", spec.get("radius"))
        length = _positive(f"{where}.length", spec.get("length"))
        return Capsule(radius, length) if kind == "capsule" else Cylinder(radius, length)
    if kind in ("halfspace", "plane"):
        normal = np.array(_vector(f"{where}.normal", spec.get("normal")))
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
    scale3 = (float(scale),) * 3 if isinstance(scale, (int, float)) else _vector(f"{where}.scale", scale)
    convex = spec.get("convex", False)
    if not isinstance(convex, bool):
        raise SceneError(f"{where}.convex must be true or false, got {convex!r}")
    return Mesh(str(resolved), scale3, convex)  # type: ignore[arg-type]


def obstacle_from_dict(spec: Mapping[str, object], where: str, base_dir: Path = Path(".")) -> Obstacle:
    """Build one obstacle from a TOML table.

    Example: ``{"name": "ball", "shape": "sphere", "radius": 0.1, "position": [0.4, 0.5, 0]}``; a
    moving one has a ``motion`` sub-table instead of ``position``/``rpy`` (see :mod:`previewctl.motion`).
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
        position = np.array(_vector(f"{where}.position", raw))
        rotation = rpy_to_matrix(np.array(_vector(f"{where}.rpy", spec.get("rpy", (0.0, 0.0, 0.0)))))
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


class Clearance:
    """Distances between a robot's guarded geometry and a scene, through one Pinocchio geometry model.

    Attributes:
        pair_links: ``(P,)`` guarded-link index of each (robot geometry, obstacle) pair.
        pair_obstacles: ``(P,)`` obstacle index of each pair.
    """

    def __init__(self, robot: Robot, scene: Scene) -> None:
        self.robot, self.scene = robot, scene
        self.geometry = pin.GeometryModel()
        model = robot.model
        self._link_of_geom = []
        for geom in robot.collision_model.geometryObjects:
            self.geometry.addGeometryObject(geom.copy())
            self._link_of_geom.append(robot.guarded_links.index(str(model.frames[geom.parentFrame].name)))
        n_robot = len(self._link_of_geom)
        self._obstacle_ids = []
        for obstacle in scene.obstacles:
            shape = obstacle.shape.geometry()
            obj = pin.GeometryObject(f"obstacle:{obstacle.name}", 0, 0, obstacle.placement(0.0), shape)
            self._obstacle_ids.append(self.geometry.addGeometryObject(obj))
        pair_links, pair_obstacles = [], []
        for g in range(n_robot):
            for k, o in enumerate(self._obstacle_ids):
                self.geometry.addCollisionPair(pin.CollisionPair(g, o))
                pair_links.append(self._link_of_geom[g])
                pair_obstacles.append(k)
        self.pair_links = np.array(pair_links, dtype=int)
        self.pair_obstacles = np.array(pair_obstacles, dtype=int)
        # pairs grouped by link, for one minimum.reduceat per batch
        self._by_link = np.argsort(self.pair_links, kind="stable")
        self._links_present, self._link_starts = np.unique(self.pair_links[self._by_link], return_index=True)
        self.data = self.geometry.createData()
        for request in self.data.distanceRequests:  # no warm start: results must not depend on call order
            request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
            with warnings.catch_warnings():  # deprecated in Coal 3, but still the switch that stops the cache
                warnings.simplefilter("ignore", DeprecationWarning)
                request.enable_cached_gjk_guess = False
        self._results = list(self.data.distanceResults)  # element references: no lookup per read
        self._time = 0.0

    def set_time(self, t: float) -> None:
        """Move the obstacles to their placements at time ``t`` [s] (nothing to do if already there)."""
        if float(t) == self._time:
            return
        self._time = float(t)
        for obstacle, gid in zip(self.scene.obstacles, self._obstacle_ids, strict=True):
            self.geometry.geometryObjects[gid].placement = obstacle.placement(t)

    def pair_distances(self, data: pin.Data) -> list[float]:
        """Distance [m] per (guarded geometry, obstacle) pair for the joint placements in ``data``.

        A plain list: a batch collects one per configuration and converts them to an array once.
        """
        pin.updateGeometryPlacements(self.robot.model, data, self.geometry, self.data)
        pin.computeDistances(self.geometry, self.data)
        return [result.min_distance for result in self._results]

    def per_link(self, pair_distances: Array) -> Array:
        """Reduce pair distances ``(B, P)`` to the minimum per guarded link ``(B, L)`` (``inf`` if none)."""
        out = np.full((pair_distances.shape[0], len(self.robot.guarded_links)), np.inf)
        if self._links_present.size:
            grouped = pair_distances[:, self._by_link]
            out[:, self._links_present] = np.minimum.reduceat(grouped, self._link_starts, axis=1)
        return out
