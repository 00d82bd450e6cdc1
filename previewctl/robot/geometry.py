"""Collision geometry of a loaded arm: guarded-link selection and the convex / capsule / mesh covers."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import UnknownNameError
from previewctl.robot.model import Geometry


def mesh_exists(filename: str, urdf_dir: Path, dirs: Sequence[str]) -> bool:
    """Whether a URDF mesh reference resolves to a file."""
    if filename.startswith("package://"):
        relative = filename[len("package://") :].lstrip("/")  # "package:///pkg/..." names the same file
        return any((Path(d) / relative).is_file() for d in dirs)
    if filename.startswith("file://"):
        filename = filename[len("file://") :]
    candidate = Path(filename)
    return candidate.is_file() or (urdf_dir / candidate).is_file()


# ------------------------------------------------------------------------ points, links, geometry


def body_name(model: pin.Model, geom: pin.GeometryObject) -> str:
    """The body (link) a geometry belongs to: its parent frame's name."""
    return str(model.frames[geom.parentFrame].name)


def select_guarded_links(
    model: pin.Model,
    collision: pin.GeometryModel,
    tip_frame: str,
    requested: Sequence[str] | Literal["all", "intermediate"],
) -> tuple[str, ...]:
    """Bodies whose geometry counts for clearance, in chain order."""
    moving = [g for g in collision.geometryObjects if g.parentJoint != 0]
    bodies = list(dict.fromkeys(body_name(model, g) for g in moving))
    if isinstance(requested, str) and requested in ("all", "intermediate"):
        if requested == "all":
            return tuple(bodies)
        hand_joint = int(model.frames[model.getFrameId(tip_frame)].parentJoint)
        return tuple(dict.fromkeys(body_name(model, g) for g in moving if g.parentJoint != hand_joint))
    if isinstance(requested, str):
        raise UnknownNameError("guarded_links choice", requested, ("all", "intermediate", *bodies))
    for body in requested:
        if body not in bodies:
            raise UnknownNameError("link with collision geometry", body, bodies)
    return tuple(requested)


def keep_links(collision: pin.GeometryModel, model: pin.Model, links: tuple[str, ...]) -> pin.GeometryModel:
    """A geometry model holding only the guarded links' geometry, in ``links`` order."""
    kept = pin.GeometryModel()
    for body in links:
        for geom in collision.geometryObjects:
            if body_name(model, geom) == body:
                kept.addGeometryObject(geom)
    return kept


def prepare_geometry(collision: pin.GeometryModel, geometry: Geometry) -> pin.GeometryModel:
    """Apply the geometry choice: keep meshes, or convex hulls and capsules, or capsules only."""
    prepared = pin.GeometryModel()
    for geom in collision.geometryObjects:
        copy = geom.copy()
        shape = copy.geometry
        if isinstance(shape, coal.Cylinder) and geometry != "mesh":
            copy.geometry = coal.Capsule(shape.radius, 2.0 * shape.halfLength)
        elif isinstance(shape, coal.BVHModelBase) and geometry == "convex":
            shape.buildConvexHull(True, "Qt")
            copy.geometry = shape.convex
        elif isinstance(shape, coal.BVHModelBase) and geometry == "capsules":
            radius, half_length, placement = enclosing_capsule(np.asarray(shape.vertices()))
            copy.geometry = coal.Capsule(radius, 2.0 * half_length)
            copy.placement = geom.placement * placement
        prepared.addGeometryObject(copy)
    return prepared


def enclosing_capsule(points: NDArray[np.float64]) -> tuple[float, float, pin.SE3]:
    """A capsule containing every point ``(N, 3)`` [m]: ``(radius, half_length, placement)``.

    The axis is the points' principal direction through their centroid and the radius ``r`` the
    largest distance to that line. A point at axial coordinate ``t``, distance ``rho`` from the axis,
    is inside when the segment ``[a, b]`` reaches within ``s = sqrt(r^2 - rho^2)`` of ``t``, so the
    shortest segment is ``a = min(t + s)``, ``b = max(t - s)`` (a single point, a sphere, if
    ``a >= b``). The placement puts Coal's capsule axis (its z) on that segment.
    """
    centroid = points.mean(axis=0)
    centred = points - centroid
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    t = centred @ axis
    rho2 = np.maximum(np.sum(centred**2, axis=1) - t**2, 0.0)
    radius = float(np.sqrt(rho2.max()))
    reach = np.sqrt(np.maximum(radius**2 - rho2, 0.0))
    a, b = float(np.min(t + reach)), float(np.max(t - reach))
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]  # the basis vector least aligned with the axis
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    rotation = np.column_stack([x, np.cross(axis, x), axis])
    return radius, max(b - a, 0.0) / 2, pin.SE3(rotation, centroid + axis * (a + b) / 2)
