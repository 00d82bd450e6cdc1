"""Triangle meshes with a colour for the browser replay: Coal shapes and mesh files (STL, OBJ, DAE, ...).

Pinocchio's own viewers cannot show everything a run holds (its ``ViserVisualizer`` rejects Coal
capsules and drops the colours of ``.dae`` files), so the replay draws from :class:`Part` values:

* :func:`shape_parts` -- any Coal shape (sphere, box, capsule, cylinder, cone, ellipsoid, convex,
  triangle mesh) as it sits in its own frame; a half-space or plane as a thin square
  ``plane_size`` [m] wide on its boundary (its solid side is unbounded).
* :func:`file_parts` -- a mesh file with its materials' colours, one part per colour (``.dae``
  materials need ``pycollada``, which trimesh uses).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import coal
import numpy as np
from numpy.typing import NDArray

from previewctl.errors import PreviewctlError
from previewctl.extras import require
from previewctl.types import Array

if TYPE_CHECKING:
    from trimesh import Trimesh

PLANE_THICKNESS = 0.002
"""Thickness [m] of the square drawn for a half-space or a plane."""
_SPHERE_SUBDIVISIONS = 3


@dataclass(frozen=True, eq=False)
class Part:
    """One colour of a mesh.

    Attributes:
        vertices: ``(V, 3)`` float32 vertex positions [m].
        faces: ``(F, 3)`` uint32 vertex indices of the triangles.
        rgba: colour, 4 values in [0, 1].
    """

    vertices: NDArray[np.float32]
    faces: NDArray[np.uint32]
    rgba: tuple[float, float, float, float]

    @property
    def extents(self) -> Array:
        """``(3,)`` size of the axis-aligned bounding box [m]."""
        return np.ptp(self.vertices, axis=0).astype(float)


def _trimesh() -> ModuleType:
    """trimesh, imported on first use (a core install has no ``[viz]``).

    Raises:
        MissingExtraError: trimesh is not installed.
    """
    return require("trimesh", "viz", "the browser replay's meshes")


def _part(mesh: Trimesh, rgba: tuple[float, float, float, float]) -> Part:
    return Part(np.ascontiguousarray(mesh.vertices, np.float32), np.ascontiguousarray(mesh.faces, np.uint32), rgba)


def shape_mesh(shape: coal.CollisionGeometry, plane_size: float = 2.0) -> Trimesh:
    """The surface of a Coal ``shape`` in its own frame, as a triangle mesh.

    Args:
        shape: the Coal geometry.
        plane_size: side [m] of the square drawn for a half-space or a plane.

    Raises:
        PreviewctlError: a Coal shape this adapter does not know (its type is named).
        MissingExtraError: trimesh is not installed.
    """
    trimesh = _trimesh()
    if isinstance(shape, coal.Sphere):
        return trimesh.creation.icosphere(_SPHERE_SUBDIVISIONS, radius=shape.radius)
    if isinstance(shape, coal.Ellipsoid):
        mesh = trimesh.creation.icosphere(_SPHERE_SUBDIVISIONS, radius=1.0)
        mesh.apply_scale(np.asarray(shape.radii, float))
        return mesh
    if isinstance(shape, coal.Box):
        return trimesh.creation.box(extents=2.0 * np.asarray(shape.halfSide, float))
    if isinstance(shape, coal.Capsule):
        return trimesh.creation.capsule(height=2.0 * shape.halfLength, radius=shape.radius)
    if isinstance(shape, coal.Cylinder):
        return trimesh.creation.cylinder(radius=shape.radius, height=2.0 * shape.halfLength)
    if isinstance(shape, coal.Cone):  # Coal's cone is centred; trimesh's has its base at z = 0
        mesh = trimesh.creation.cone(radius=shape.radius, height=2.0 * shape.halfLength)
        mesh.apply_translation([0.0, 0.0, -shape.halfLength])
        return mesh
    if isinstance(shape, (coal.Halfspace, coal.Plane)):
        return _square(np.asarray(shape.n, float), float(shape.d), plane_size)
    if isinstance(shape, coal.ConvexBase):
        return trimesh.convex.convex_hull(np.asarray(shape.points(), float))
    if isinstance(shape, coal.BVHModelBase):
        triangles = [shape.tri_indices(i) for i in range(shape.num_tris)]
        faces = np.array([[t[0], t[1], t[2]] for t in triangles], dtype=int).reshape(-1, 3)
        return trimesh.Trimesh(np.asarray(shape.vertices(), float), faces, process=False)
    raise PreviewctlError(
        f"cannot draw a Coal {type(shape).__name__}; drawable: sphere, ellipsoid, box, capsule, cylinder, cone, "
        "half-space, plane, convex, triangle mesh"
    )


def _square(normal: Array, offset: float, size: float) -> Trimesh:
    """A thin square of side ``size`` [m] on the plane ``n . x = offset``, centred on the point nearest the origin."""
    n = normal / np.linalg.norm(normal)
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    transform = np.eye(4)
    transform[:3, :3] = np.column_stack([u, np.cross(n, u), n])
    transform[:3, 3] = offset * n
    return _trimesh().creation.box(extents=(size, size, PLANE_THICKNESS), transform=transform)


def shape_parts(
    shape: coal.CollisionGeometry, rgba: tuple[float, float, float, float], plane_size: float = 2.0
) -> tuple[Part, ...]:
    """:func:`shape_mesh` as one :class:`Part` of colour ``rgba``."""
    return (_part(shape_mesh(shape, plane_size), rgba),)


def file_parts(
    path: str | Path, scale: Array, default_rgba: tuple[float, float, float, float]
) -> tuple[Part, ...] | None:
    """The meshes of a file, scaled by ``scale`` ``(3,)``, one part per material colour.

    Parts without a material colour get ``default_rgba``. Coincident vertices are merged (file formats
    often repeat them per face), which shrinks the replay without changing the surface.

    Returns:
        The parts, or ``None`` when trimesh cannot read the file (the caller falls back to Coal's mesh).

    Raises:
        MissingExtraError: trimesh is not installed.
    """
    trimesh = _trimesh()
    try:
        scene = trimesh.load_scene(str(path))
    except Exception:  # trimesh raises many types (ValueError, KeyError, import errors of optional readers)
        return None
    by_colour: dict[tuple[float, float, float, float], list[Trimesh]] = {}
    for node in scene.graph.nodes_geometry:  # each placed instance of a geometry, in the file's frame
        transform, name = scene.graph[node]
        mesh = scene.geometry[name]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        placed = mesh.copy()
        placed.apply_transform(transform)
        by_colour.setdefault(_colour(mesh, default_rgba), []).append(placed)
    parts = []
    for rgba, meshes in by_colour.items():
        offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        vertices = np.vstack([m.vertices for m in meshes]) * np.asarray(scale, float)
        faces = np.vstack([m.faces + offset for m, offset in zip(meshes, offsets, strict=True)])
        parts.append(_part(trimesh.Trimesh(vertices, faces, process=True), rgba))  # process: merges vertices
    return tuple(parts) or None


def _colour(mesh: Trimesh, default: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The main colour of a loaded mesh's material (RGBA in [0, 1]), or ``default``."""
    material = getattr(mesh.visual, "material", None)
    main = getattr(material, "main_color", None)
    if main is None:
        return default
    r, g, b, a = (round(float(c) / 255.0, 3) for c in np.asarray(main)[:4])
    return (r, g, b, a)
