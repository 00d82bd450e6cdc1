"""Obstacle shapes (frozen, self-validating value objects), :class:`Obstacle` and :class:`Scene`."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

if sys.version_info >= (3, 11):
    pass
else:  # pragma: no cover - Python 3.10
    pass
from previewctl.errors import SceneError
from previewctl.scene.motion import Motion, Static


def positive(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise SceneError(f"{where} must be a positive number [m], got {value!r}")
    return float(value)


def vector(where: str, value: object, size: int = 3) -> tuple[float, ...]:
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
