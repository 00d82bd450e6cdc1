"""Distances between an arm's own links: its self pairs (:mod:`previewctl.robot.self_pairs`) through Coal.

The self pairs have their own Pinocchio geometry model (:attr:`SelfPairs.geometry
<previewctl.robot.self_pairs.SelfPairs.geometry>`): every pair in one ``pin.computeDistances`` call when all are
wanted. Most pairs of most configurations are far apart, so the batches and the witnesses first bound each pair from
below (compiled loops over the batch), and ask Coal only about the pairs whose bound is below the distance that matters
(the potential's self influence distance, a damper's reach); the others keep their bound, which is then at least that
distance.

1. Every pair of the batch at once: each geometry is enclosed in a sphere carried by its joint (centred on its
   bounding box), and ``d >= |c_a - c_b| - r_a - r_b``.
2. The pairs that pass 1: each geometry is also enclosed in a capsule (:func:`~previewctl.robot.geometry.
   enclosing_capsule` of its vertices) and in its 26-DOP (the slab ``n . x <= h(n)`` for each of 26 fixed directions
   ``n`` of its joint frame, ``h`` its support). The capsule ``[b0, b1] + r_b`` of the slimmer geometry ``b`` and the
   DOP of the other, ``a``, are at least ``max_n (min(n . b0, n . b1) - h_a(n)) - r_b`` apart (the slab of ``n``
   separates them by that much); the larger of the two bounds counts.

On random Panda configurations (convex hulls, 44 pairs) 1 leaves about 4.5 pairs per configuration, 2 about 1.2,
of which 0.8 are within 5 cm: hence the cheap first step on every pair and the finer second on few. The batch
distances are unsigned (Coal skips the penetration depth, which only EPA computes): a pair in contact is at 0. The
witnesses are signed.

Mesh (BVH) geometry is hollow here: two meshes that intersect are at distance 0 (or below), but a mesh wholly inside
another without crossing it is not seen; the exact check runs every control period, so a contact is met as a
crossing first.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import coal
import numba
import numpy as np
import pinocchio as pin

from previewctl.robot.geometry import enclosing_capsule
from previewctl.robot.model import Robot
from previewctl.types import Array, IntArray

BOUND_SLACK = 1e-6
"""[m] taken off every bound: a bound must never exceed the true distance, rounding included."""

_DIRECTIONS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                        if (i, j, k) != (0, 0, 0)], dtype=float)
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1)[:, None]
"""The 26 unit directions of the DOP covers (axes, face and body diagonals)."""


@dataclass(frozen=True)
class SelfWitnesses:
    """The nearest points of self pairs (``R`` of them), for a damper on each (both links move).

    Attributes:
        pairs: ``(R,)`` indices of the pairs in ``robot.self_pairs`` (geometry pairs; their links:
            ``robot.self_pairs.pair_names(k)``).
        distance: ``(R,)`` signed distance [m] (negative: penetration depth).
        point_a: ``(R, 3)`` nearest point on link ``a`` (the one nearer the base) [m], world frame.
        point_b: ``(R, 3)`` nearest point on link ``b`` [m], world frame.
        normal: ``(R, 3)`` unit vector from ``a`` towards ``b``, world frame: the distance grows at
            ``normal . (p_b_dot - p_a_dot)``.
        joint_a: ``(R,)`` Pinocchio joint that carries ``a``'s geometry (its Jacobian moves ``point_a``).
        joint_b: ``(R,)`` Pinocchio joint that carries ``b``'s geometry.
    """

    pairs: IntArray
    distance: Array
    point_a: Array
    point_b: Array
    normal: Array
    joint_a: IntArray
    joint_b: IntArray


def geometry_data(geometry: pin.GeometryModel, signed: bool = True) -> pin.GeometryData:
    """A workspace of ``geometry`` whose distance requests start GJK from a fixed guess, not the pair's last result;
    ``signed=False`` skips the penetration depth. The obstacle pairs (:class:`~previewctl.scene.clearance.Clearance`)
    and the self pairs use it.

    Coal 3 still starts the support function of a convex hull of more than 32 vertices (a hill climb) from the vertex
    the pair's previous call ended on, whatever the request says. So such a pair's distance can differ in its last
    bits with what the pair computed before (the xArm7's obstacle pairs, 3,000 random configurations computed twice:
    4 changed, by up to 1.6e-7 m, GJK's tolerance); the same calls in the same order give the same bits. Primitive
    shapes and smaller hulls are searched from scratch each call."""
    data = geometry.createData()
    for request in data.distanceRequests:
        request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
        request.enable_signed_distance = signed
        with warnings.catch_warnings():  # deprecated in Coal 3, but still the switch that stops the cache
            warnings.simplefilter("ignore", DeprecationWarning)
            request.enable_cached_gjk_guess = False
    return data


class SelfClearance:
    """Distances between the self pairs of ``robot`` (``P = len(robot.self_pairs)`` geometry pairs).

    Attributes:
        geometry: the self geometry model (``robot.self_pairs.geometry``), one collision pair per self pair.
        pair_links: ``(P,)`` index of each pair's link pair in ``robot.self_pairs.links``.
        joint_a, joint_b: ``(P,)`` the joints that carry each pair's two geometries.
        joints: the joints that carry self geometry, in the order of :meth:`joint_placements` (the placements the
            bounds read; :func:`~previewctl.kinematics.kinematics_reader` can read them on its pass).
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        pairs = robot.self_pairs
        self.geometry: pin.GeometryModel = pairs.geometry
        self.pair_links = np.asarray(pairs.pair_links, dtype=np.int64)
        collision_pairs = list(self.geometry.collisionPairs)
        self._a = np.array([p.first for p in collision_pairs], dtype=np.int64)
        self._b = np.array([p.second for p in collision_pairs], dtype=np.int64)
        objects = list(self.geometry.geometryObjects)
        parent = np.array([int(g.parentJoint) for g in objects], dtype=np.int64)
        self.joint_a, self.joint_b = parent[self._a], parent[self._b]
        self.joints: tuple[int, ...] = tuple(sorted(set(parent.tolist())))
        self._slot = np.array([self.joints.index(j) for j in parent], dtype=np.int64)
        centres, spheres, ends, radii, supports = [], [], [], [], []
        for g in objects:  # the covers, in the frame of the geometry's joint
            points, rho = cover_points(g.geometry)
            points = points.reshape(-1, 3) @ g.placement.rotation.T + g.placement.translation
            centre = (points.min(axis=0) + points.max(axis=0)) / 2
            centres.append(centre)
            spheres.append(float(np.linalg.norm(points - centre, axis=1).max()) + rho)
            radius, half_length, placement = enclosing_capsule(points)
            half = np.array([0.0, 0.0, half_length])
            ends.append([placement.act(-half), placement.act(half)])
            radii.append(radius + rho)
            supports.append((points @ _DIRECTIONS.T).max(axis=0) + rho)
        self._centres = np.array(centres).reshape(-1, 3)
        self._reach = np.array(spheres)[self._a] + np.array(spheres)[self._b] + BOUND_SLACK
        # step 2 per pair: the DOP of the geometry with the larger capsule, the capsule of the other
        capsule_radius = np.array(radii)
        wider = capsule_radius[self._a] >= capsule_radius[self._b]
        dop, capsule = np.where(wider, self._a, self._b), np.where(wider, self._b, self._a)
        self._dop_slot, self._capsule_slot = self._slot[dop], self._slot[capsule]
        self._dop_support = np.array(supports).reshape(-1, len(_DIRECTIONS))[dop]
        self._capsule_ends = np.array(ends).reshape(-1, 2, 3)[capsule]
        self._capsule_radius = capsule_radius[capsule] + BOUND_SLACK
        self.data = geometry_data(self.geometry, signed=True)
        self._results = list(self.data.distanceResults)
        self._batch = geometry_data(self.geometry, signed=False)
        self._own = robot.model.createData()  # for configurations given as q
        self._reader: tuple[pin.Data, list[pin.SE3]] | None = None
        self._none, self._no_points = np.zeros(0), np.zeros((0, 3))  # read only: the witnesses of no pair
        self._none.flags.writeable = self._no_points.flags.writeable = False

    def __len__(self) -> int:
        return int(self._a.size)

    # ----------------------------------------------------------------------------- one configuration

    def pair_distances(self, data: pin.Data) -> Array:
        """Signed distance [m] of every pair ``(P,)`` for the joint placements in ``data`` (one Coal call)."""
        pin.updateGeometryPlacements(self.robot.model, data, self.geometry, self.data)
        pin.computeDistances(self.geometry, self.data)
        return np.array([r.min_distance for r in self._results], dtype=float)

    def witnesses(self, data: pin.Data, within: float = np.inf) -> SelfWitnesses:
        """The pairs closer than ``within`` [m] for the joint placements in ``data`` (``data.oMi``): their indices,
        signed distances, nearest points, normals and joints. Pairs that the bounds put ``within`` apart or more
        are not computed."""
        if np.isfinite(within):
            _, _, candidates = self.candidates(np.array(self.joint_placements(data))[None], within)
            if not candidates.size:  # most cycles
                return SelfWitnesses(candidates, self._none, self._no_points, self._no_points, self._no_points,
                                     candidates, candidates)
            pin.updateGeometryPlacements(self.robot.model, data, self.geometry, self.data)
            for k in candidates.tolist():
                pin.computeDistance(self.geometry, self.data, k)
        else:
            candidates = np.arange(len(self))
            self.pair_distances(data)
        distance = np.array([self._results[k].min_distance for k in candidates], dtype=float)
        close = distance < within
        near = candidates[close]
        results = [self._results[k] for k in near]
        points = np.array([(r.getNearestPoint1(), r.getNearestPoint2(), r.normal) for r in results]).reshape(-1, 3, 3)
        return SelfWitnesses(near, distance[close], points[:, 0], points[:, 1], points[:, 2],
                             self.joint_a[near], self.joint_b[near])

    # ------------------------------------------------------------------------------------- batches

    def joint_placements(self, data: pin.Data) -> list[Array]:
        """The ``4 x 4`` placements of the joints that carry self geometry, from ``data.oMi`` (read through
        references kept for the last ``data`` seen: a lookup through the bindings costs about a microsecond)."""
        if self._reader is None or self._reader[0] is not data:
            placements = list(data.oMi)
            self._reader = (data, [placements[j] for j in self.joints])
        return [p.homogeneous for p in self._reader[1]]

    def bounds(self, placements: Array) -> Array:
        """Lower bounds ``(B, P)`` [m] of the pair distances from the joint placements ``(B, J, 4, 4)`` (the
        :meth:`joint_placements` of each configuration): step 1 of the module docstring, the spheres."""
        out = np.empty((placements.shape[0], len(self)))
        _sphere_bounds(np.ascontiguousarray(placements), self._slot, self._centres, self._a, self._b, self._reach, out)
        return out

    def refine(self, placements: Array, rows: IntArray, pairs: IntArray) -> Array:
        """Lower bounds ``(C,)`` [m] of pair ``pairs[c]`` at configuration ``rows[c]`` from the DOP covers (step 2 of
        the module docstring; combine them with :meth:`bounds` by the larger)."""
        out = np.empty(len(rows))
        _dop_gaps(np.ascontiguousarray(placements), rows, pairs, self._dop_slot, self._capsule_slot, self._capsule_ends,
                  self._dop_support, _DIRECTIONS, out)
        return out - self._capsule_radius[pairs]

    def candidates(self, placements: Array, within: float) -> tuple[Array, IntArray, IntArray]:
        """The bounds ``(B, P)`` [m] (steps 1 and 2) and the (configuration, pair) entries still below ``within``
        [m], as two index arrays: the pairs Coal must compute."""
        bound = self.bounds(placements)
        rows, pairs = np.nonzero(bound < within)
        if rows.size:
            refined = np.maximum(bound[rows, pairs], self.refine(placements, rows, pairs))
            bound[rows, pairs] = refined
            keep = refined < within
            rows, pairs = rows[keep], pairs[keep]
        return bound, rows, pairs

    def nearest(self, Q: Array, placements: Array, within: float) -> tuple[Array, IntArray]:
        """The smallest pair distance [m] of each configuration ``(B,)`` and its pair ``(B,)`` (``-1`` without
        pairs): exact where below ``within`` [m] (0 in contact: unsigned), else a lower bound at least ``within``.
        Coal computes a configuration's candidate pairs in the order of their bounds, and skips those whose bound
        exceeds the nearest distance found so far.

        Args:
            Q: ``(B, nq)`` configurations.
            placements: ``(B, J, 4, 4)`` their :meth:`joint_placements`.
            within: the distance [m] below which distances are computed exactly.
        """
        B = Q.shape[0]
        if not len(self):
            return np.full(B, np.inf), np.full(B, -1, dtype=np.int64)
        distance, rows, pairs = self.candidates(placements, within)
        if rows.size:
            # each configuration's candidates nearest first: once a pair is computed, those bounded beyond its
            # distance cannot be the nearest, and keep their bound
            bounds = distance[rows, pairs]
            order = np.lexsort((bounds, rows))
            model, own, geometry, gdata = self.robot.model, self._own, self.geometry, self._batch
            last, placed, best = -1, -1, within
            for i, b, k, bound in zip(order.tolist(), rows[order].tolist(), pairs[order].tolist(),
                                      bounds[order].tolist(), strict=True):
                if b != last:
                    last, best = b, within
                if bound > best:
                    continue
                if b != placed:
                    pin.updateGeometryPlacements(model, own, geometry, gdata, Q[b])
                    placed = b
                bounds[i] = pin.computeDistance(geometry, gdata, k).min_distance
                best = min(best, bounds[i])
            distance[rows, pairs] = bounds
        pair = np.argmin(distance, axis=1)
        return distance[np.arange(B), pair], pair.astype(np.int64)


# ------------------------------------------------------------------------------------- covers and bounds


def cover_points(shape: coal.CollisionGeometry) -> tuple[Array, float]:
    """Points ``(N, 3)`` [m] and a radius ``rho`` [m] whose convex hull, grown by ``rho``, contains a Coal shape (in
    the shape's frame): a capsule's axis ends and radius, a sphere's centre and radius, a mesh's or convex hull's
    vertices, a box's corners, a cylinder's rims (polygons circumscribing its circles), else the corners of its local
    bounding box."""
    if isinstance(shape, coal.Capsule):
        return np.array([[0.0, 0.0, -shape.halfLength], [0.0, 0.0, shape.halfLength]]), float(shape.radius)
    if isinstance(shape, coal.Sphere):
        return np.zeros((1, 3)), float(shape.radius)
    if isinstance(shape, coal.ConvexBase):
        return np.asarray(shape.points(), dtype=float), 0.0
    if isinstance(shape, coal.BVHModelBase):
        return np.asarray(shape.vertices(), dtype=float), 0.0
    if isinstance(shape, coal.Box):
        return _corners(-np.asarray(shape.halfSide), np.asarray(shape.halfSide)), 0.0
    if isinstance(shape, coal.Cylinder):
        sides = 64
        angle = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
        rim = np.column_stack([np.cos(angle), np.sin(angle)]) * (shape.radius / np.cos(np.pi / sides))
        ends = (-shape.halfLength, shape.halfLength)
        return np.vstack([np.column_stack([rim, np.full(sides, z)]) for z in ends]), 0.0
    shape.computeLocalAABB()
    return _corners(np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)), 0.0


def _corners(low: Array, high: Array) -> Array:
    """The 8 corners ``(8, 3)`` of the box ``[low, high]``."""
    return np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])


@numba.njit(cache=True, nogil=True)
def _sphere_bounds(placements: Array, slot: IntArray, centres: Array, a: IntArray, b: IntArray, reach: Array,
                   out: Array) -> None:  # pragma: no cover - compiled
    """``out[r, k] = |c_a - c_b| - reach[k]`` for pair ``k`` = ``(a[k], b[k])`` at configuration ``r``: the sphere
    centres ``centres`` ``(G, 3)`` carried by the placements ``placements[r, slot[g]]`` ``(4, 4)``."""
    world = np.empty((len(slot), 3))
    for r in range(placements.shape[0]):
        for g in range(len(slot)):
            H = placements[r, slot[g]]
            for i in range(3):
                world[g, i] = H[i, 0] * centres[g, 0] + H[i, 1] * centres[g, 1] + H[i, 2] * centres[g, 2] + H[i, 3]
        for k in range(len(a)):
            dx = world[a[k], 0] - world[b[k], 0]
            dy = world[a[k], 1] - world[b[k], 1]
            dz = world[a[k], 2] - world[b[k], 2]
            out[r, k] = np.sqrt(dx * dx + dy * dy + dz * dz) - reach[k]


@numba.njit(cache=True, nogil=True)
def _dop_gaps(placements: Array, rows: IntArray, pairs: IntArray, dop_slot: IntArray, capsule_slot: IntArray,
              ends: Array, support: Array, directions: Array, out: Array) -> None:  # pragma: no cover - compiled
    """``out[c] = max_n (min(n . e0, n . e1) - h(n))`` for pair ``pairs[c]`` at configuration ``rows[c]``: how far its
    capsule axis ``ends[pair]`` ``(2, 3)`` (in the frame of the placement ``capsule_slot[pair]``) lies outside the DOP
    ``support[pair]`` ``(26,)`` over ``directions`` ``(26, 3)`` (in the frame of the placement ``dop_slot[pair]``)."""
    local = np.empty((2, 3))
    for c in range(len(rows)):
        k = pairs[c]
        held = placements[rows[c], dop_slot[k]]
        other = placements[rows[c], capsule_slot[k]]
        for e in range(2):
            x = ends[k, e]
            w0 = other[0, 0] * x[0] + other[0, 1] * x[1] + other[0, 2] * x[2] + other[0, 3] - held[0, 3]
            w1 = other[1, 0] * x[0] + other[1, 1] * x[1] + other[1, 2] * x[2] + other[1, 3] - held[1, 3]
            w2 = other[2, 0] * x[0] + other[2, 1] * x[1] + other[2, 2] * x[2] + other[2, 3] - held[2, 3]
            for i in range(3):  # into the held frame: R^T w
                local[e, i] = held[0, i] * w0 + held[1, i] * w1 + held[2, i] * w2
        best = -np.inf
        for n in range(directions.shape[0]):
            d = directions[n]
            along0 = local[0, 0] * d[0] + local[0, 1] * d[1] + local[0, 2] * d[2]
            along1 = local[1, 0] * d[0] + local[1, 1] * d[1] + local[1, 2] * d[2]
            best = max(best, min(along0, along1) - support[k, n])
        out[c] = best
