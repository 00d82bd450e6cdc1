"""Shared by the figures of :mod:`previewctl.viz.figures` (runs) and :mod:`previewctl.viz.landscapes` (landscapes):
matplotlib on the Agg backend, the arm's joint polyline and obstacle sections by the arm's plane.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.robot.model import Robot
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Obstacle, Sphere
from previewctl.types import Array

Bounds = tuple[float, float, float, float]
"""``(xmin, xmax, ymin, ymax)`` of a top view [m]."""


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (imported on first use: importing previewctl stays cheap)."""
    import matplotlib

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
