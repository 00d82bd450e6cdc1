"""Per-link clearance of a batch of configurations against a scene (Coal through Pinocchio's geometry layer), and
the arm's clearance from itself (:mod:`previewctl.scene.self_clearance`, reached through :class:`Clearance`).

A batch may be screened first (:meth:`Clearance.screened`): each obstacle is enclosed in a sphere ``(c_o, r_o)`` moved
with it, and each robot geometry in a sphere ``(c_g, r_g)`` and a capsule ``[a_g, b_g] + ρ_g`` carried by its joint
(:func:`~previewctl.robot.geometry.enclosing_capsule` of its cover), so every pair is bounded from below in numpy, by
``|c_g - c_o| - r_g - r_o`` for all pairs, then, for the pairs that bound leaves, by the larger of it and
``dist(c_o, [a_g, b_g]) - ρ_g - r_o``. Coal computes only the pairs still bounded below the distance that matters; the
others keep their bounds. An obstacle without a finite cover (a half-space, a plane) is never screened out.

An obstacle whose motion is a prediction (:class:`~previewctl.scene.motion.Uncertain`, an observed obstacle of
:mod:`previewctl.sensing`) is inflated by its margin ``m(t)`` [m] at the scene's time: every distance of its pairs is
the distance to its shape minus ``m(t)`` (its bounds too, so the screen stays exact below ``within``), and its nearest
points lie on the inflated surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from previewctl.errors import SceneError
from previewctl.robot.geometry import enclosing_capsule
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static, Uncertain, margin_at, planar_fields
from previewctl.scene.self_clearance import BOUND_SLACK, SelfClearance, SelfWitnesses, cover_points, geometry_data
from previewctl.scene.shapes import Scene
from previewctl.scene.solid import SolidMesh
from previewctl.types import Array, IntArray
from previewctl.validation import show


def check_dimensions(robot: Robot, scene: Scene) -> None:
    """Refuse an obstacle placed by 2-D vectors (padded with ``z = 0``) around a spatial arm.

    2 entries are for a planar arm (``task = "planar"`` or a planar chain), which moves in the plane ``z = 0``;
    around any other arm such an obstacle would silently sit at ``z = 0``. Every path that pairs a robot with a
    scene comes through here (:class:`Clearance`, and scenario files when they are read).

    Raises:
        SceneError: naming the obstacle, the field, the value given and the robot.
    """
    if robot.task == "planar" or robot.planar is not None:
        return
    for obstacle in scene.obstacles:
        for name in planar_fields(obstacle.motion):
            given = np.asarray(getattr(obstacle.motion, name))[..., :2]
            raise SceneError(
                f"obstacle {obstacle.name!r}: {name} {show(given.tolist())} is 2-D, but robot {robot.name!r} is "
                f"spatial (task {robot.task!r}): give 3-D positions [x, y, z] [m] (2-D ones are for planar arms)"
            )


@dataclass(frozen=True)
class Witnesses:
    """The nearest points of every (guarded geometry, obstacle) pair of a :class:`Clearance` (``P`` pairs).

    Attributes:
        distance: ``(P,)`` signed distance [m] (negative: penetration depth).
        robot_point: ``(P, 3)`` nearest point on the robot geometry [m], world frame.
        obstacle_point: ``(P, 3)`` nearest point on the obstacle [m], world frame.
        normal: ``(P, 3)`` unit vector from the robot towards the obstacle: the distance grows when the robot
            point moves along ``−normal``.
    """

    distance: Array
    robot_point: Array
    obstacle_point: Array
    normal: Array


class Clearance:
    """Distances between a robot's guarded geometry and a scene, through one Pinocchio geometry model.

    Every guarded link is paired with every obstacle, except the hand's links with a work surface
    (:class:`~previewctl.scene.shapes.Obstacle`). The robot's self pairs are measured by :attr:`self_clearance`
    (their own geometry model: every link with geometry, the base and fingers included); :meth:`self_witnesses`
    gives their nearest points.

    Raises:
        SceneError: an obstacle placed in 2-D around a spatial arm (:func:`check_dimensions`).

    Attributes:
        pair_links: ``(P,)`` guarded-link index of each (robot geometry, obstacle) pair.
        pair_obstacles: ``(P,)`` obstacle index of each pair.
        pair_joints: ``(P,)`` Pinocchio joint that carries the robot geometry of each pair.
        joints: the joints that carry guarded geometry, in the order of the placements :meth:`screened` reads.
        self_clearance: the distances between the robot's own links (``robot.self_pairs``).
    """

    def __init__(self, robot: Robot, scene: Scene) -> None:
        check_dimensions(robot, scene)
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
        solids = [SolidMesh.of(g.geometry) if isinstance(g.geometry, coal.BVHModelBase) else None
                  for g in robot.collision_model.geometryObjects]
        pair_links: list[int] = []
        pair_obstacles: list[int] = []
        pair_joints: list[int] = []
        self._solid_pairs: list[tuple[int, SolidMesh, int, int]] = []  # (pair, solid, robot geometry, obstacle)
        hand = [robot.guarded_links.index(link) for link in robot.hand_links]
        for g in range(n_robot):
            for k, o in enumerate(self._obstacle_ids):
                if scene.obstacles[k].work_surface and self._link_of_geom[g] in hand:
                    continue  # the hand may touch the object it works on
                self.geometry.addCollisionPair(pin.CollisionPair(g, o))
                solid = solids[g]
                if solid is not None:
                    self._solid_pairs.append((len(pair_links), solid, g, o))
                pair_links.append(self._link_of_geom[g])
                pair_obstacles.append(k)
                pair_joints.append(int(self.geometry.geometryObjects[g].parentJoint))
        self.pair_links = np.array(pair_links, dtype=int)
        self.pair_obstacles = np.array(pair_obstacles, dtype=int)
        self.pair_joints = np.array(pair_joints, dtype=int)
        # pairs grouped by link, for one minimum.reduceat per batch
        self._by_link = np.argsort(self.pair_links, kind="stable")
        self._links_present, self._link_starts = np.unique(self.pair_links[self._by_link], return_index=True)
        self.joints: tuple[int, ...] = tuple(sorted(set(pair_joints)))
        self._pair_geometry = np.array([p.first for p in self.geometry.collisionPairs], dtype=int)
        self._pair_slot = np.array([self.joints.index(j) for j in pair_joints], dtype=int)
        robot_covers = [_covers(g.geometry, g.placement) for g in robot.collision_model.geometryObjects]
        self._geometry_centres = np.array([np.append(c[0], 1.0) for c in robot_covers]).reshape(-1, 4)
        self._obstacle_covers = [_covers(o.shape.geometry(), pin.SE3.Identity())[:2] for o in scene.obstacles]
        obstacle_radius = np.array([r for _, r in self._obstacle_covers])[self.pair_obstacles] + BOUND_SLACK
        self._pair_reach = np.array([c[1] for c in robot_covers])[self._pair_geometry] + obstacle_radius
        self._pair_ends = np.array([c[2] for c in robot_covers]).reshape(-1, 2, 3)[self._pair_geometry]
        self._pair_capsule_reach = np.array([c[3] for c in robot_covers])[self._pair_geometry] + obstacle_radius
        self._uncertain = [k for k, o in enumerate(scene.obstacles) if isinstance(o.motion, Uncertain)]
        self._pair_margin = np.zeros(len(pair_links))  # [m] each pair's obstacle inflation at the scene's time
        self._margins = True  # whether predicted obstacles are inflated (use_margins(), margins)
        self._revisions = self.revisions()
        self._moving = [k for k, o in enumerate(scene.obstacles) if not isinstance(o.motion, Static)]
        self._obstacle_centres = np.array([self._centre(k, o.placement(0.0)) for k, o in enumerate(scene.obstacles)
                                           ]).reshape(-1, 3)  # (O, 3): the moving obstacles' rows follow set_time
        self._margins_at(0.0)
        self._own = model.createData()  # for screened batches, placed from q
        self.data = geometry_data(self.geometry)
        self._results = list(self.data.distanceResults)  # element references: no lookup per read
        self._solid_of = {pair: (solid, g, o) for pair, solid, g, o in self._solid_pairs}
        self._time = 0.0
        self._no_points = np.zeros((0, 3))  # read only: the witnesses of no pair
        self._no_points.flags.writeable = False
        self.self_clearance = SelfClearance(robot)

    def revisions(self) -> tuple[int, ...]:
        """The revisions of the predicted obstacles' motions (:class:`~previewctl.scene.motion.Uncertain`): a
        placement read before one of them changed is stale."""
        obstacles = self.scene.obstacles
        return tuple(obstacles[k].motion.revision for k in self._uncertain)  # type: ignore[attr-defined]

    def set_time(self, t: float) -> None:
        """Move the obstacles to their placements at time ``t`` [s] and inflate the predicted ones by their margins
        (static ones never move; nothing to do if already there and no prediction changed since)."""
        revisions = self.revisions()
        if float(t) == self._time and revisions == self._revisions:
            return
        self._time, self._revisions = float(t), revisions
        objects = self.geometry.geometryObjects
        for k in self._moving:
            placement = self.scene.obstacles[k].placement(t)
            objects[self._obstacle_ids[k]].placement = placement
            self._obstacle_centres[k] = self._centre(k, placement)
        self._margins_at(t)

    @property
    def predicts(self) -> bool:
        """Whether some obstacle of the scene is a prediction (:class:`~previewctl.scene.motion.Uncertain`)."""
        return bool(self._uncertain)

    @property
    def margins(self) -> bool:
        """Whether the predicted obstacles are inflated by their margins (:meth:`use_margins`)."""
        return self._margins

    def use_margins(self, on: bool) -> None:
        """Inflate the predicted obstacles by their margins (``on``, the default) or take them at their predicted
        size, from the next :meth:`set_time` on."""
        if on != self._margins:
            self._margins, self._time = on, math.nan  # the placements and margins are read again

    def _margins_at(self, t: float) -> None:
        """Each pair's inflation [m] at time ``t`` [s]: its obstacle's margin (0 but for predicted obstacles, and with
        the margins off)."""
        if self._uncertain:
            margins = np.array([margin_at(o.motion, t) if self._margins else 0.0 for o in self.scene.obstacles])
            self._pair_margin = margins.reshape(-1)[self.pair_obstacles]

    def _centre(self, k: int, placement: pin.SE3) -> Array:
        """Obstacle ``k``'s cover centre [m] in the world ``(3,)`` when it is at ``placement``."""
        return np.asarray(placement.act(self._obstacle_covers[k][0]))

    def pair_distances(self, data: pin.Data) -> list[float]:
        """Distance [m] per (guarded geometry, obstacle) pair for the joint placements in ``data``.

        Mesh geometry counts as solid: an obstacle inside a link mesh gets a negative distance
        (:mod:`previewctl.scene.solid`). A plain list: a batch collects one per configuration and
        converts them to an array once.
        """
        pin.updateGeometryPlacements(self.robot.model, data, self.geometry, self.data)
        pin.computeDistances(self.geometry, self.data)
        distances = [result.min_distance for result in self._results]
        for pair, _, _, _ in self._solid_pairs:
            distances[pair] = self._solid(pair, distances[pair])
        if self._uncertain:
            return [d - m for d, m in zip(distances, self._pair_margin.tolist(), strict=True)]
        return distances

    def _solid(self, pair: int, distance: float) -> float:
        """The distance [m] of ``pair`` with its mesh counted as solid (:mod:`previewctl.scene.solid`), from its
        Coal distance once computed for the geometry placements in :attr:`data` (unchanged for another pair)."""
        solid = self._solid_of.get(pair)
        if solid is None or distance <= 0.0:
            return distance
        mesh, g, o = solid
        placements = self.data.oMg
        return mesh.solid_distance(distance, placements[g], self._results[pair].getNearestPoint2(),
                                   self.geometry.geometryObjects[o].geometry, placements[o])

    def screened(self, Q: Array, placements: Array, within: float) -> Array:
        """Distances ``(B, P)`` [m] per pair at the scene's time: exact (as :meth:`pair_distances`) for the pairs
        bounded below ``within`` [m], else the lower bounds of the module docstring (each at least ``within``).

        Args:
            Q: ``(B, nq)`` validated configurations.
            placements: ``(B, J, 4, 4)`` the world placements of :attr:`joints` at each configuration.
            within: the distance [m] below which distances are exact.
        """
        held = placements[:, self._pair_slot]  # (B, P, 4, 4)
        centres = (held @ self._geometry_centres[self._pair_geometry, :, None])[..., :3, 0]
        gap = centres - self._obstacle_centres[self.pair_obstacles]
        distances = np.sqrt(np.einsum("bpk,bpk->bp", gap, gap)) - self._pair_reach
        limit = within + self._pair_margin  # (P,) [m]: below it the distance to the shape is exact
        rows, pairs = np.nonzero(distances < limit)
        if rows.size:
            frames = held[rows, pairs]
            ends = self._pair_ends[pairs] @ frames[:, :3, :3].transpose(0, 2, 1) + frames[:, None, :3, 3]
            capsule = _segment_distance(ends, self._obstacle_centres[self.pair_obstacles[pairs]])
            distances[rows, pairs] = np.maximum(distances[rows, pairs], capsule - self._pair_capsule_reach[pairs])
            keep = distances[rows, pairs] < limit[pairs]
            rows, pairs = rows[keep], pairs[keep]
        model, own, geometry, data, solids = self.robot.model, self._own, self.geometry, self.data, self._solid_of
        found, placed = [], -1
        for b, k in zip(rows.tolist(), pairs.tolist(), strict=True):
            if b != placed:
                pin.updateGeometryPlacements(model, own, geometry, data, Q[b])
                placed = b
            distance = pin.computeDistance(geometry, data, k).min_distance
            found.append(self._solid(k, distance) if k in solids else distance)
        distances[rows, pairs] = found
        return distances - self._pair_margin if self._uncertain else distances

    def witnesses(self, data: pin.Data, within: float = np.inf) -> tuple[IntArray, Witnesses]:
        """The pairs closer than ``within`` [m] for the joint placements in ``data``: their indices ``(R,)``
        and their distances, nearest points and normals."""
        distance = np.array(self.pair_distances(data))
        near = np.flatnonzero(distance < within)
        if not near.size:  # most cycles
            return near, Witnesses(distance[near], self._no_points, self._no_points, self._no_points)
        results = [self._results[k] for k in near]
        points = np.array([(r.getNearestPoint1(), r.getNearestPoint2(), r.normal) for r in results]).reshape(-1, 3, 3)
        obstacle_point = points[:, 1]
        if self._uncertain:  # on the inflated surface
            obstacle_point = obstacle_point - self._pair_margin[near, None] * points[:, 2]
        return near, Witnesses(distance[near], points[:, 0], obstacle_point, points[:, 2])

    def self_witnesses(self, data: pin.Data, within: float = np.inf) -> SelfWitnesses:
        """The self pairs closer than ``within`` [m] for the joint placements in ``data`` (``data.oMi``, e.g. after
        ``pin.computeJointJacobians``): pair indices, distances, nearest points ``point_a``, ``point_b`` and the
        normal from ``a`` to ``b`` (world frame), and the joints ``joint_a``, ``joint_b`` that carry the two
        geometries (see :class:`~previewctl.scene.self_clearance.SelfWitnesses`)."""
        return self.self_clearance.witnesses(data, within)

    def per_link(self, pair_distances: Array) -> Array:
        """Reduce pair distances ``(B, P)`` to the minimum per guarded link ``(B, L)`` (``inf`` if none)."""
        out = np.full((pair_distances.shape[0], len(self.robot.guarded_links)), np.inf)
        if self._links_present.size:
            grouped = pair_distances[:, self._by_link]
            out[:, self._links_present] = np.minimum.reduceat(grouped, self._link_starts, axis=1)
        return out


def _covers(shape: coal.CollisionGeometry, placement: pin.SE3) -> tuple[Array, float, Array, float]:
    """A sphere's centre ``(3,)`` [m] and radius [m], and a capsule's axis ends ``(2, 3)`` [m] and radius [m], each
    enclosing a Coal shape placed by ``placement`` (in the frame ``placement`` is given in); radii ``inf`` for a shape
    without a finite cover (a half-space, a plane)."""
    if not isinstance(shape, (coal.Halfspace, coal.Plane)):
        points, rho = cover_points(shape)
        points = points.reshape(-1, 3) @ placement.rotation.T + placement.translation
        centre = (points.min(axis=0) + points.max(axis=0)) / 2
        radius = float(np.linalg.norm(points - centre, axis=1).max()) + rho
        if np.isfinite(radius) and np.isfinite(centre).all():
            capsule, half_length, axis = enclosing_capsule(points)
            half = np.array([0.0, 0.0, half_length])
            return centre, radius, np.array([axis.act(-half), axis.act(half)]), capsule + rho
    return np.zeros(3), np.inf, np.zeros((2, 3)), np.inf


def _segment_distance(ends: Array, points: Array) -> Array:
    """Distances ``(C,)`` [m] from points ``(C, 3)`` to segments ``ends`` ``(C, 2, 3)``."""
    axis = ends[:, 1] - ends[:, 0]
    offset = points - ends[:, 0]
    length2 = np.einsum("ck,ck->c", axis, axis)
    along = np.clip(np.einsum("ck,ck->c", offset, axis) / np.maximum(length2, 1e-300), 0.0, 1.0)
    gap = offset - along[:, None] * axis
    return np.sqrt(np.einsum("ck,ck->c", gap, gap))
