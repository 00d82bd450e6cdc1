"""Solid link meshes: an obstacle wholly inside a closed link mesh collides, whatever the surface distance says.

Coal measures a mesh (``geometry="mesh"``) distance to its triangles, not to the solid they enclose:
an obstacle inside the link reads as clear. When the surface distance is positive the obstacle is
either wholly outside the mesh or wholly inside it, so one of its points tells which: the point is
inside when the generalised winding number of the triangles around it (Jacobson et al. 2013, the
sum of the triangles' solid angles over 4π) exceeds 1/2. Inside, the clearance is the (negative)
distance to the link's convex hull, a penetration measure; it is at most minus the surface distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from previewctl.types import Array


def winding_number(vertices: Array, triangles: Array, point: Array) -> float:
    """Generalised winding number of a triangle mesh around ``point``: about 1 inside a closed mesh, 0 outside.

    Args:
        vertices: ``(V, 3)`` [m].
        triangles: ``(T, 3)`` vertex indices.
        point: ``(3,)`` [m], in the vertices' frame.
    """
    a, b, c = (vertices[triangles[:, i]] - point for i in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    dots = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
        + np.einsum("ij,ij->i", c, a) * lb
    return float(abs(np.arctan2(det, dots).sum()) / (2.0 * np.pi))


@dataclass(frozen=True, eq=False)
class SolidMesh:
    """A link mesh as a solid: its triangles, bounding box and convex hull (in the mesh frame).

    Attributes:
        vertices: ``(V, 3)`` [m].
        triangles: ``(T, 3)`` vertex indices.
        low: ``(3,)`` bounding-box corner [m].
        high: ``(3,)`` bounding-box corner [m].
        hull: the convex hull, for the penetration of a contained obstacle.
    """

    vertices: Array
    triangles: Array
    low: Array
    high: Array
    hull: coal.ConvexBase

    @classmethod
    def of(cls, mesh: coal.BVHModelBase) -> SolidMesh:
        """The solid of a Coal mesh (its convex hull is built here)."""
        vertices = np.array(mesh.vertices(), dtype=float)
        triangles = np.array([[t[0], t[1], t[2]] for t in map(mesh.tri_indices, range(mesh.num_tris))], dtype=int)
        hull = mesh.clone()
        hull.buildConvexHull(True, "Qt")
        return cls(vertices, triangles, vertices.min(axis=0), vertices.max(axis=0), hull.convex)

    def contains(self, point: Array) -> bool:
        """Whether ``point`` ``(3,)`` [m, mesh frame] is inside the closed mesh."""
        if np.any(point < self.low) or np.any(point > self.high):
            return False
        return winding_number(self.vertices, self.triangles, point) > 0.5

    def solid_distance(
        self, surface: float, placement: pin.SE3, witness: Array, other: coal.CollisionGeometry, other_at: pin.SE3
    ) -> float:
        """The clearance [m] to an obstacle ``other`` given its positive ``surface`` distance to the mesh.

        Args:
            surface: Coal's distance between the mesh triangles and ``other`` [m].
            placement: the mesh's world placement.
            witness: a world point of ``other`` (its nearest point to the mesh) [m].
            other: the obstacle's shape.
            other_at: its world placement.

        Returns:
            ``surface`` when ``other`` is outside the mesh, else ``min(hull distance, −surface)`` (< 0).
        """
        if surface <= 0.0 or not self.contains(placement.actInv(np.asarray(witness, dtype=float))):
            return surface
        request, result = coal.DistanceRequest(), coal.DistanceResult()
        hull = coal.distance(self.hull, coal.Transform3s(placement.rotation, placement.translation), other,
                             coal.Transform3s(other_at.rotation, other_at.translation), request, result)
        return min(float(hull), -surface)
