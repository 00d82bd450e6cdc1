"""A run's 3-D scene in a viser server, which can be shown at any logged step.

:class:`ReplayScene` builds, once, what a person looks at:

* the arm with the visual meshes of its URDF (:mod:`previewctl.viz.arm_meshes`);
* every obstacle (moved to its place at the shown time), the desired hand path (grey, all of it) and
  the hand's trace (blue, drawn by the caller: :meth:`ReplayScene.add_trace`);
* the imaginary arms the preview controllers steered toward, as translucent ghosts (from the log's
  ``targets``; hidden where the controller computed none), and the oracle's motion as a translucent
  green arm when its run is given;
* the first collision: from its step on, the colliding link and the obstacle (or, when the arm hit itself, both
  of its links) are red, a red ball marks the contact (the midpoint of the pair's nearest points) and a label
  names both.

:meth:`ReplayScene.show` puts everything at one step and can go back in time (the live viewer's slider);
the recorded file (:mod:`previewctl.viz.replay`) calls it step after step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.errors import PreviewctlError
from previewctl.scene.clearance import Clearance
from previewctl.scene.shapes import Halfspace, Obstacle, Plane
from previewctl.sim.log import RunResult
from previewctl.sim.scenario import Scenario
from previewctl.types import Array
from previewctl.viz.arm_meshes import ArmMeshes
from previewctl.viz.drawing import COLLISION_COLOUR
from previewctl.viz.meshes import Part, shape_parts

Rgba = tuple[float, float, float, float]
GHOST_RGBA: tuple[Rgba, ...] = ((1.0, 0.6, 0.1, 0.22), (0.6, 0.3, 0.9, 0.22), (0.1, 0.7, 0.7, 0.22))
"""Colours of the imaginary arms ``q~_1, q~_2, ...`` (repeated beyond three)."""
ORACLE_RGBA: Rgba = (0.15, 0.7, 0.25, 0.3)
OBSTACLE_RGBA: Rgba = (0.42, 0.48, 0.6, 0.9)
PATH_RGB = (0.45, 0.45, 0.45)
TRACE_RGB = (0.1, 0.35, 0.9)


def _rgb255(colour: tuple[float, ...]) -> tuple[int, int, int]:
    """An RGB(A) colour in [0, 1] as integers in [0, 255] (what viser's node updates take)."""
    r, g, b = (round(255 * c) for c in colour[:3])
    return (r, g, b)


RED = tuple(int(COLLISION_COLOUR[i:i + 2], 16) for i in (1, 3, 5))
"""The collision colour, RGB in [0, 255]."""


@dataclass(frozen=True)
class Contact:
    """Where a run first collided, with an obstacle or with itself.

    Attributes:
        step: index of the first colliding log step.
        links: the arm's links that collided: one against an obstacle, two when the arm hit itself.
        obstacle: index of the obstacle hit in the scene, or ``None`` for a self-collision.
        point: ``(3,)`` contact point [m] (midpoint of the pair's nearest points).
        text: the label, e.g. ``collision at t = 1.20 s: link1 hits ball``.
    """

    step: int
    links: tuple[str, ...]
    obstacle: int | None
    point: Array
    text: str


def find_contact(result: RunResult, scenario: Scenario) -> Contact | None:
    """The first collision of ``result``: with an obstacle, its link (from the log) and the obstacle nearest that
    link; with itself, the logged self pair. ``None`` for a run free of both."""
    k, s = result.collision_index, result.self_collision_index
    if s is not None and (k is None or s < k):
        return _self_contact(result, scenario, s)
    link = result.summary()["collision_link"]
    if k is None or link is None or not scenario.scene.obstacles:
        return None
    robot = scenario.robot
    clearance = Clearance(robot, scenario.scene)
    clearance.set_time(float(result.t[k]))
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, result.q[k])
    distances = np.array(clearance.pair_distances(data))
    pairs = np.flatnonzero(clearance.pair_links == robot.guarded_links.index(link))
    best = int(pairs[np.argmin(distances[pairs])]) if pairs.size else int(np.argmin(distances))
    res = clearance.data.distanceResults[best]
    point = 0.5 * (np.asarray(res.getNearestPoint1()) + np.asarray(res.getNearestPoint2()))
    obstacle = int(clearance.pair_obstacles[best])
    text = f"collision at t = {result.t[k]:.2f} s: {link} hits {scenario.scene.obstacles[obstacle].name}"
    return Contact(k, (link,), obstacle, point, text)


def _self_contact(result: RunResult, scenario: Scenario, s: int) -> Contact:
    """The self-collision at log step ``s``: the logged pair of links, and the midpoint of their nearest points on
    the scenario robot's geometry."""
    a, b = result.self_pairs[int(result.self_pair[s])]
    robot = scenario.robot
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, result.q[s])
    found = Clearance(robot, scenario.scene).self_witnesses(data)
    mine = [i for i, pair in enumerate(found.pairs) if robot.self_pairs.pair_names(int(pair)) == (a, b)]
    if mine:
        nearest = min(mine, key=lambda i: found.distance[i])
        point = 0.5 * (found.point_a[nearest] + found.point_b[nearest])
    else:  # the search geometry does not check this pair: between the two links' origins
        frames = (robot.model.getFrameId(a), robot.model.getFrameId(b))
        point = 0.5 * (data.oMf[frames[0]].translation + data.oMf[frames[1]].translation)
    return Contact(s, (a, b), None, np.asarray(point, dtype=float), f"self-collision at t = {result.t[s]:.2f} s: "
                   f"{a} hits {b}")


def _wxyz(rotation: Array) -> Array:
    x, y, z, w = pin.Quaternion(np.asarray(rotation, float)).coeffs()
    return np.array([w, x, y, z])


def _add_part(scene: Any, name: str, part: Part, rgba: Rgba | None) -> Any:
    """A mesh node; ``rgba`` (a ghost's colour) replaces the part's own colour."""
    r, g, b, a = rgba or part.rgba
    return scene.add_mesh_simple(
        name, part.vertices, part.faces, color=(r, g, b), opacity=None if a >= 1.0 else a,
        cast_shadow=rgba is None, receive_shadow=rgba is None,
    )


def _polyline(points: Array) -> Array:
    """``(N, 3)`` points as the ``(N-1, 2, 3)`` segments viser draws."""
    return np.stack([points[:-1], points[1:]], axis=1)


class _Arm:
    """One arm drawn in the scene (the run's, a ghost or the oracle's): a frame per visual object."""

    def __init__(self, scene: Any, meshes: ArmMeshes, root: str, rgba: Rgba | None):
        self.meshes = meshes
        self.frames: list[Any] = []
        self.parts: dict[str, list[tuple[Any, Rgba]]] = {}
        for link in meshes.links:
            frame = scene.add_frame(f"{root}/{link.name}", show_axes=False)
            for i, part in enumerate(link.parts):
                handle = _add_part(scene, f"{root}/{link.name}/{i}", part, rgba)
                self.parts.setdefault(link.body, []).append((handle, rgba or part.rgba))
            self.frames.append(frame)

    def show(self, q: Array) -> None:
        """Place the arm at ``q`` (reduced model), or hide it where ``q`` is not finite (no target computed)."""
        visible = bool(np.all(np.isfinite(q)))
        for frame in self.frames:
            frame.visible = visible
        if visible:
            for frame, placement in zip(self.frames, self.meshes.placements(q), strict=True):
                frame.position = placement.translation
                frame.wxyz = _wxyz(placement.rotation)


@dataclass(frozen=True, eq=False)
class _ObstacleNode:
    """An obstacle in the scene: its frame (moved at each step) and its mesh handles (recoloured at a collision)."""

    obstacle: Obstacle
    frame: Any
    parts: tuple[tuple[Any, Rgba], ...]


class ReplayScene:
    """The scene of a run in ``server`` (a ``viser.ViserServer``), shown at one logged step at a time.

    Args:
        server: the viser server whose scene is filled.
        result: the run.
        scenario: its scenario (robot source, obstacles, path).
        oracle: the oracle's run of the same scenario, drawn as a translucent green arm.

    Raises:
        PreviewctlError: the run's joints do not match the scenario's robot.
    """

    def __init__(self, server: Any, result: RunResult, scenario: Scenario, oracle: RunResult | None = None) -> None:
        robot = scenario.robot
        if result.q.shape[1] != robot.model.nq:
            raise PreviewctlError(
                f"run {result.scenario!r} has {result.q.shape[1]} joints; scenario {scenario.name!r}'s robot "
                f"{robot.name!r} has {robot.model.nq}: pass the scenario the run was made with"
            )
        self.result, self.scenario, self.oracle = result, scenario, oracle
        self.scene = scene = server.scene
        meshes = ArmMeshes(robot, scenario.robot_spec)
        self.contact = find_contact(result, scenario)
        planar = robot.task == "planar"
        eye, centre, radius = self._camera(meshes, planar)
        scene.set_up_direction("+z")
        # no environment map: in software WebGL (headless browsers, remote desktops) it costs ~1 s a frame
        scene.configure_environment_map(None)
        scene.add_light_hemisphere("/light", sky_color=(255, 255, 255), ground_color=(120, 120, 120), intensity=2.5)
        server.initial_camera.position = eye
        server.initial_camera.look_at = centre
        cell = 0.1 if radius < 1.0 else 0.25
        scene.add_grid("/grid", width=3.0 * radius, height=3.0 * radius, cell_size=cell, section_size=5 * cell,
                       position=(centre[0], centre[1], -0.05 if planar else 0.0))
        scene.add_line_segments("/path/desired", _polyline(self._waypoints()), PATH_RGB, thickness=0.004)
        self.obstacles = [self._add_obstacle(o, 3.0 * radius) for o in scenario.scene.obstacles]
        self.arm = _Arm(scene, meshes, "/arm", None)
        self.ghosts = [_Arm(scene, meshes, f"/ghost{i}", GHOST_RGBA[i % len(GHOST_RGBA)])
                       for i in range(result.targets.shape[1])]
        self.oracle_arm = _Arm(scene, meshes, "/oracle", ORACLE_RGBA) if oracle is not None else None
        self._collided = False
        if self.contact is not None:
            self.marker = scene.add_icosphere("/collision/marker", radius=max(0.02, 0.02 * radius), color=RED,
                                              position=self.contact.point, visible=False)
            self.label = scene.add_label("/collision/label", self.contact.text, position=self.contact.point,
                                         visible=False)

    def _waypoints(self) -> Array:
        """The desired path's waypoints in 3-D [m] (z = 0 for a planar path): the whole path, reached or not."""
        points = self.scenario.path.waypoints
        return np.pad(points, ((0, 0), (0, 3 - points.shape[1])))

    def _camera(self, meshes: ArmMeshes, planar: bool) -> tuple[Array, Array, float]:
        """A camera position and look-at point [m] that frame the hand, the path, the arm at the start and the
        bounded obstacles, and the scene's radius [m]. Planar arms are seen from above (slightly tilted),
        spatial ones from the front right."""
        arm = [m.translation for m in meshes.placements(self.result.q[0])]
        times = self.result.t[:: max(1, self.result.steps // 50)]
        bounded = [o for o in self.scenario.scene.obstacles if not isinstance(o.shape, (Halfspace, Plane))]
        points = np.vstack([self.result.hand, self._waypoints(), arm, *(o.motion.positions(times) for o in bounded)])
        low, high = points.min(axis=0), points.max(axis=0)
        centre, radius = 0.5 * (low + high), max(0.5 * float(np.linalg.norm(high - low)), 0.3)
        direction = np.array([0.0, -0.35, 1.0]) if planar else np.array([1.0, -0.9, 0.6])
        return centre + (1.5 if planar else 1.25) * radius * direction / np.linalg.norm(direction), centre, radius

    def _add_obstacle(self, obstacle: Obstacle, plane_size: float) -> _ObstacleNode:
        root = f"/obstacles/{obstacle.name}"
        frame = self.scene.add_frame(root, show_axes=False)
        parts = shape_parts(obstacle.shape.geometry(), OBSTACLE_RGBA, plane_size)
        handles = tuple((_add_part(self.scene, f"{root}/{i}", part, None), part.rgba) for i, part in enumerate(parts))
        return _ObstacleNode(obstacle, frame, handles)

    def show(self, k: int) -> None:
        """Everything at log step ``k``: the arm, the ghosts, the oracle's arm, the obstacles, the collision."""
        result = self.result
        t = float(result.t[k])
        self.arm.show(result.q[k])
        for i, ghost in enumerate(self.ghosts):
            ghost.show(result.targets[k, i])
        if self.oracle_arm is not None and self.oracle is not None:
            self.oracle_arm.show(self.oracle.q[min(int(np.searchsorted(self.oracle.t, t)), self.oracle.steps - 1)])
        for node in self.obstacles:
            placement = node.obstacle.placement(t)
            node.frame.position = placement.translation
            node.frame.wxyz = _wxyz(placement.rotation)
        self._show_collision(self.contact is not None and k >= self.contact.step)

    def _show_collision(self, collided: bool) -> None:
        """The colliding links (and obstacle) red, the marker and the label shown (or all back to normal)."""
        if collided == self._collided or self.contact is None:
            return
        self._collided = collided
        obstacle = self.obstacles[self.contact.obstacle].parts if self.contact.obstacle is not None else ()
        parts = (*(part for link in self.contact.links for part in self.arm.parts.get(link, [])), *obstacle)
        for handle, rgba in parts:
            handle.color = RED if collided else _rgb255(rgba)
        self.marker.visible = collided
        self.label.visible = collided

    def add_trace(self, name: str, start: int, stop: int) -> None:
        """The hand's trace from log step ``start`` to ``stop`` (included) as the line node ``/path/trace/<name>``."""
        if stop > start:
            self.scene.add_line_segments(f"/path/trace/{name}", _polyline(self.result.hand[start:stop + 1]),
                                         TRACE_RGB, thickness=0.006)
