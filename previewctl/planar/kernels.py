"""Closed-form distance kernels for the obstacles a planar arm can meet in its plane (else ``None``: use Coal)."""

from __future__ import annotations

import numpy as np

from previewctl.planar import distance as planar_distance
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Obstacle, Sphere


def planar_kernel(obstacle: Obstacle, t: float) -> planar_distance.Kernel | None:
    """The validated planar distance kernel of ``obstacle`` at time ``t`` [s], or ``None`` when the
    closed form does not apply (meshes, planes, boxes/cylinders not straddling the arm's plane)."""
    shape, pose = obstacle.shape, obstacle.placement(t)
    p, R = pose.translation, pose.rotation
    if isinstance(shape, Sphere):
        return planar_distance.sphere_kernel(p, shape.radius)
    if isinstance(shape, Capsule):
        axis = R[:, 2] * shape.length / 2
        return planar_distance.capsule_kernel(p - axis, p + axis, shape.radius)
    if isinstance(shape, Box):
        half = np.array(shape.size) / 2
        return planar_distance.box_kernel(p, R, half) if planar_distance.box_is_planar(p, R, half) else None
    if isinstance(shape, Cylinder):
        if not planar_distance.cylinder_is_planar(p, R, shape.length / 2):
            return None
        return planar_distance.vertical_cylinder_kernel(p, shape.radius, shape.length / 2)
    if isinstance(shape, Halfspace):
        normal = R @ np.array(shape.normal)
        return planar_distance.halfspace_kernel(normal, shape.offset + float(normal @ p))
    return None
