"""Shared by the figures of runs (:mod:`~previewctl.viz.figures`, :mod:`~previewctl.viz.animation`) and of
landscapes (:mod:`~previewctl.viz.landscapes`): matplotlib on the Agg backend, the arm's joint polyline, and
obstacles as they look in the arm's plane ``z = 0`` (sections, outlines, the view that holds them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.extras import require
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Mesh, Obstacle, Plane, Scene, Sphere
from previewctl.types import Array

Bounds = tuple[float, float, float, float]
"""``(xmin, xmax, ymin, ymax)`` of a top view [m]."""

OBSTACLE_COLOUR = "#7f7f7f"
COLLISION_COLOUR = "#d62728"


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (imported on first use: importing previewctl stays cheap). Every
    figure starts here, so a missing matplotlib is reported here, with the extra that installs it.

    Raises:
        MissingExtraError: matplotlib is not installed.
    """
    matplotlib = require("matplotlib", "viz", "drawing figures")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def arm_points(robot: Robot, Q: Array) -> Array:
    """Joint origins then the hand for each configuration: ``(T, njoints, 3)`` [m].

    Args:
        robot: the arm.
        Q: ``(T, nq)`` configurations.
    """
    model, data = robot.model, robot.model.createData()
    out = np.empty((Q.shape[0], model.njoints, 3))
    tip = robot.tip_frame_id
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        for j in range(1, model.njoints):
            out[k, j - 1] = data.oMi[j].translation
        out[k, -1] = data.oMf[tip].translation
    return out


def _radial_polygon(
    inside: Callable[[Array], NDArray[np.bool_]], centre: Array, reach: float, count: int = 180
) -> Array:
    """Boundary ``(count, 2)`` of a convex plane region around an interior point, by bisection per ray."""
    angles = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
    u = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    lo, hi = np.zeros(count), np.full(count, reach)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        ok = inside(centre + mid[:, None] * u)
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    return centre + lo[:, None] * u


def _box_section(p: Array, R: Array, half: Array) -> Array:
    """Polygon of a box cut by ``z = 0``: the crossings of its 12 edges, sorted by angle."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    corners = p + (signs * half) @ R.T
    points = []
    for i in range(8):
        for j in range(i + 1, 8):
            if np.count_nonzero(signs[i] != signs[j]) != 1:
                continue
            za, zb = corners[i, 2], corners[j, 2]
            if za == 0.0:
                points.append(corners[i, :2])
            if (za < 0 < zb) or (zb < 0 < za):
                points.append(corners[i, :2] + (corners[j, :2] - corners[i, :2]) * za / (za - zb))
    if len(points) < 3:
        return np.zeros((0, 2))
    pts = np.array(points)
    centre = pts.mean(axis=0)
    order = np.argsort(np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0]))
    return pts[order]


def clip_halfplane(polygon: Array, normal: Array, offset: float) -> Array:
    """The part of a convex polygon where ``normal . x <= offset`` (Sutherland-Hodgman, one edge)."""
    out: list[Array] = []
    for i in range(len(polygon)):
        p, q = polygon[i], polygon[(i + 1) % len(polygon)]
        dp, dq = float(normal @ p) - offset, float(normal @ q) - offset
        if dp <= 0:
            out.append(p)
        if dp * dq < 0:
            out.append(p + (q - p) * dp / (dp - dq))
    return np.array(out).reshape(-1, 2)


def obstacle_section(obstacle: Obstacle, t: float, bounds: Bounds) -> Array:
    """The obstacle's section by the plane ``z = 0`` at time ``t`` [s], a polygon ``(K, 2)`` [m].

    Args:
        obstacle: the obstacle.
        t: time [s].
        bounds: ``(xmin, xmax, ymin, ymax)`` of the view [m] (a half-space is clipped to it).

    Returns:
        The polygon; empty ``(0, 2)`` if the obstacle does not meet the plane (or is a plane or mesh).
    """
    pose = obstacle.placement(t)
    p, R, shape = np.array(pose.translation), np.array(pose.rotation), obstacle.shape
    if isinstance(shape, Sphere):
        if abs(p[2]) >= shape.radius:
            return np.zeros((0, 2))
        r = float(np.sqrt(shape.radius**2 - p[2] ** 2))
        angles = np.linspace(0.0, 2 * np.pi, 96, endpoint=False)
        return p[:2] + r * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    if isinstance(shape, Box):
        return _box_section(p, R, np.array(shape.size) / 2)
    if isinstance(shape, (Capsule, Cylinder)):
        axis, half, radius = R[:, 2], shape.length / 2, shape.radius

        def inside(x: Array) -> NDArray[np.bool_]:
            rel = np.concatenate([x, np.zeros((len(x), 1))], axis=1) - p
            s = rel @ axis
            if isinstance(shape, Capsule):
                closest = p + np.clip(s, -half, half)[:, None] * axis
                return np.linalg.norm(np.concatenate([x, np.zeros((len(x), 1))], axis=1) - closest, axis=1) <= radius
            radial = np.linalg.norm(rel - s[:, None] * axis, axis=1)
            return (np.abs(s) <= half) & (radial <= radius)

        # an interior point of the section: where the axis crosses z = 0, else its closest point
        s0 = np.clip(-p[2] / axis[2], -half, half) if abs(axis[2]) > 1e-12 else 0.0
        centre = (p + s0 * axis)[:2]
        if not inside(centre[None])[0]:
            return np.zeros((0, 2))
        return _radial_polygon(inside, centre, 2 * (half + radius) + 1e-6)
    if isinstance(shape, Halfspace):
        normal = R @ np.array(shape.normal)
        offset = shape.offset + float(normal @ p)
        xmin, xmax, ymin, ymax = bounds
        view = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
        if np.linalg.norm(normal[:2]) < 1e-12:
            return view if offset >= 0 else np.zeros((0, 2))
        return clip_halfplane(view, normal[:2], offset)
    return np.zeros((0, 2))


def obstacle_outline(obstacle: Obstacle, t: float, bounds: Bounds) -> tuple[str, Array]:
    """How an obstacle looks in the plane ``z = 0`` at time ``t`` [s].

    Args:
        obstacle: the obstacle.
        t: time [s].
        bounds: ``(xmin, xmax, ymin, ymax)`` of the view [m] (for half-spaces and planes).

    Returns:
        ``(kind, points)``: ``("polygon", (K, 2))`` a filled outline, ``("line", (2, 2))`` a line, or
        ``("marker", (1, 2))`` a position marker (meshes).
    """
    section = obstacle_section(obstacle, t, bounds)
    if len(section):
        return "polygon", section
    pose = obstacle.placement(t)
    p, R, shape = np.array(pose.translation), np.array(pose.rotation), obstacle.shape
    if isinstance(shape, Plane):
        normal = R @ np.array(shape.normal)
        offset = shape.offset + float(normal @ p)
        n2 = normal[:2]
        if np.linalg.norm(n2) < 1e-9:
            return "line", np.zeros((0, 2))
        xmin, xmax, ymin, ymax = bounds
        view = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
        inside = clip_halfplane(view, n2, offset)
        on_line = inside[np.abs(inside @ n2 - offset) < 1e-9 * max(1.0, abs(offset))]
        return "line", on_line[:2] if len(on_line) >= 2 else np.zeros((0, 2))
    if isinstance(shape, Mesh):
        return "marker", p[None, :2]
    return "polygon", np.zeros((0, 2))  # does not meet the plane z = 0


def draw_obstacle(
    ax: Any, obstacle: Obstacle, t: float, bounds: Bounds, alpha: float, label: str | None = None
) -> None:
    """Draw :func:`obstacle_outline` on the matplotlib axes ``ax`` with opacity ``alpha``."""
    from matplotlib.patches import Polygon

    kind, pts = obstacle_outline(obstacle, t, bounds)
    if len(pts) == 0:
        return
    if kind == "polygon" and len(pts) >= 3:
        ax.add_patch(Polygon(pts, closed=True, facecolor=OBSTACLE_COLOUR, edgecolor="#404040", alpha=alpha,
                             linewidth=0.8, label=label))
    elif kind == "line":
        ax.plot(pts[:, 0], pts[:, 1], color="#404040", alpha=alpha, label=label)
    else:
        ax.plot(pts[:, 0], pts[:, 1], "x", color="#404040", alpha=alpha, label=label)


def view_bounds(points: Array, path: Array, scene: Scene, pad: float = 0.25) -> Bounds:
    """A top view [m] holding the arm ``points (..., 3)``, the ``path (K, >=2)`` and the centres of the solid
    obstacles at ``t = 0``, with a margin ``pad`` [m]."""
    xy = [points.reshape(-1, 3)[:, :2], path[:, :2]]
    for obstacle in scene.obstacles:
        if isinstance(obstacle.shape, (Sphere, Box, Cylinder, Capsule)):
            xy.append(obstacle.placement(0.0).translation[None, :2])
    allxy = np.concatenate(xy)
    xmin, ymin = allxy.min(axis=0) - pad
    xmax, ymax = allxy.max(axis=0) + pad
    return float(xmin), float(xmax), float(ymin), float(ymax)
