"""Obstacle shapes (frozen, self-validating value objects), :class:`Obstacle` and :class:`Scene`.

A shape's bounds are the annotations of its fields (checked by :func:`previewctl.validation.check_fields`);
the scene file's obstacle tables are made from the same fields (:mod:`previewctl.scene.schema`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import coal
import numpy as np
import pinocchio as pin
from pydantic import AfterValidator, BeforeValidator

from previewctl.errors import SceneError
from previewctl.scene.motion import Motion, Static
from previewctl.validation import Checked, Finite, Flag, Positive, Size, Text, invalid, show


def _nonzero(vector: tuple[float, ...]) -> tuple[float, ...]:
    if not any(vector):
        raise invalid("must be non-zero, got {value}", value=show(list(vector)))
    return vector


def _triple(value: object) -> object:
    """A scalar scale ``s`` means ``(s, s, s)``."""
    return (value,) * 3 if isinstance(value, (int, float)) and not isinstance(value, bool) else value


Lengths3 = Annotated[tuple[Positive, Positive, Positive], Size(3)]
"""Three positive lengths [m]."""
Normal = Annotated[tuple[Finite, Finite, Finite], Size(3), AfterValidator(_nonzero)]
"""A non-zero direction (3 numbers)."""
Scale = Annotated[tuple[Finite, Finite, Finite], Size(3), BeforeValidator(_triple)]
"""Scale factors along x, y, z (one number for all three)."""


class _Shape(Checked):
    """A shape checks its fields against their annotations when it is made."""

    error = SceneError


@dataclass(frozen=True)
class Sphere(_Shape):
    """A ball of ``radius`` [m] centred on the obstacle's position."""

    radius: Positive
    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Sphere(self.radius)


@dataclass(frozen=True)
class Box(_Shape):
    """A box of edge lengths ``size`` [m] (x, y, z in the obstacle frame), centred on its position."""

    size: Lengths3
    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Box(*self.size)


@dataclass(frozen=True)
class Capsule(_Shape):
    """A capsule of ``radius`` [m] whose axis of ``length`` [m] is the obstacle frame's z axis."""

    radius: Positive
    length: Positive
    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Capsule(self.radius, self.length)


@dataclass(frozen=True)
class Cylinder(_Shape):
    """A cylinder of ``radius`` [m] and ``length`` [m] along the obstacle frame's z axis."""

    radius: Positive
    length: Positive
    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Cylinder(self.radius, self.length)


@dataclass(frozen=True)
class Halfspace(_Shape):
    """The solid ``{x : n . x <= offset}`` in the obstacle frame (``n`` normalised)."""

    normal: Normal
    offset: Finite = 0.0
    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Halfspace(np.array(self.normal), self.offset)


@dataclass(frozen=True)
class Plane(_Shape):
    """The (two-sided, zero-thickness) plane ``{x : n . x = offset}`` in the obstacle frame."""

    normal: Normal
    offset: Finite = 0.0
    def geometry(self) -> coal.CollisionGeometry:
        """The Coal shape."""
        return coal.Plane(np.array(self.normal), self.offset)


@dataclass(frozen=True)
class Mesh(_Shape):
    """A triangle mesh loaded from ``path`` (STL, OBJ, DAE, ...), scaled by ``scale``.

    ``convex=True`` uses its convex hull (fast); ``False`` keeps the exact mesh.
    """

    path: Text
    scale: Scale = (1.0, 1.0, 1.0)
    convex: Flag = False
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
    """A named shape whose placement follows ``motion`` (static at the origin by default).

    ``work_surface``: the object the hand works on (the paper's target surface). The hand's own links
    may touch it; every other link is still guarded against it, and the hand against everything else.
    """

    name: str
    shape: Shape
    motion: Motion = field(default_factory=lambda: Static(np.zeros(3)))
    work_surface: bool = False

    def placement(self, t: float = 0.0) -> pin.SE3:
        """World placement at time ``t`` [s]."""
        position, rotation = self.motion.placement(t)
        return pin.SE3(np.asarray(rotation, float), np.asarray(position, float))


@dataclass(frozen=True)
class Scene:
    """The obstacles around the arm: ``Scene((ball, box))`` (a list is taken as its tuple).

    Raises:
        SceneError: ``obstacles`` is one obstacle or not a sequence, an element is not an :class:`Obstacle`, or
            two obstacles share a name.
    """

    obstacles: tuple[Obstacle, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "obstacles", _obstacle_tuple(self.obstacles))
        names = [o.name for o in self.obstacles]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise SceneError(f"obstacle names must be unique; repeated: {', '.join(duplicates)}")

    @property
    def names(self) -> tuple[str, ...]:
        """Obstacle names, in order."""
        return tuple(o.name for o in self.obstacles)


def _obstacle_tuple(obstacles: object) -> tuple[Obstacle, ...]:
    """``obstacles`` (a tuple or list of :class:`Obstacle`) as a tuple.

    Raises:
        SceneError: one obstacle instead of a sequence, something else than a tuple or list, or an element that
            is not an :class:`Obstacle`; the message names it and its type.
    """
    if isinstance(obstacles, Obstacle):
        raise SceneError(f"Scene takes a tuple of obstacles, got one Obstacle {obstacles.name!r}: pass a tuple, "
                         f"Scene((obstacle,))")
    if not isinstance(obstacles, (tuple, list)):
        raise SceneError(f"Scene takes a tuple of obstacles, got {type(obstacles).__name__} {show(obstacles)}: "
                         f"pass a tuple of Obstacle, e.g. Scene((Obstacle('ball', Sphere(0.1), Static([0.5, 0.5, "
                         f"0.0])),))")
    for i, obstacle in enumerate(obstacles):
        if not isinstance(obstacle, Obstacle):
            raise SceneError(f"Scene obstacles[{i}] must be an Obstacle, got {type(obstacle).__name__} "
                             f"{show(obstacle)}: build it with Obstacle(name, shape, motion), e.g. "
                             f"Obstacle('ball', Sphere(0.1), Static([0.5, 0.5, 0.0]))")
    return tuple(obstacles)
