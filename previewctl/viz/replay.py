"""A run as a 3-D replay in the browser: one self-contained HTML file (viser's offline player).

:func:`write_replay` records the run into a viser scene and saves it as ``replay.html``: it opens from
disk with no server and no network, with play/pause, a time slider and an orbit camera. It shows

* the arm with the visual meshes of its URDF (:mod:`previewctl.viz.arm_meshes`);
* every obstacle with its motion, the desired hand path (grey) and the hand's trace as it is drawn;
* the imaginary arms the preview controllers steered toward, as translucent ghosts (from the log's
  ``targets``; hidden while the controller computed none), and the oracle's motion as a translucent
  green arm when its run is given;
* the first collision: from its time on, the colliding link and the obstacle turn red and a red
  ball marks the contact (the nearest points of the pair), with a label naming both.

Size: a replay holds every mesh once (viser stores identical buffers once, so ghosts cost no mesh
data) plus the poses of each frame. Frames are taken at ``fps`` (default 15 per second of the run).
"""

from __future__ import annotations

import contextlib
import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.errors import PreviewctlError
from previewctl.files import atomic_write_bytes
from previewctl.scene.clearance import Clearance
from previewctl.scene.shapes import Halfspace, Obstacle, Plane
from previewctl.sim.log import RunResult, load_run
from previewctl.sim.paper import shipped_scenarios_dir
from previewctl.sim.scenario import Scenario, load_scenario
from previewctl.types import Array
from previewctl.viz.arm_meshes import ArmMeshes
from previewctl.viz.drawing import COLLISION_COLOUR
from previewctl.viz.meshes import Part, shape_parts

REPLAY_NAME = "replay.html"
DEFAULT_FPS = 15.0
"""Replay frames per second of run time (the log has 100 per second at dt = 0.01 s)."""
GHOST_RGBA = ((1.0, 0.6, 0.1, 0.22), (0.6, 0.3, 0.9, 0.22), (0.1, 0.7, 0.7, 0.22))
"""Colours of the imaginary arms ``q~_1, q~_2, ...`` (repeated beyond three)."""
ORACLE_RGBA = (0.15, 0.7, 0.25, 0.3)
OBSTACLE_RGBA = (0.42, 0.48, 0.6, 0.9)
HOLD = 1.0
"""Time [s] the last frame stays on screen (the end of a colliding run is its collision)."""
PATH_RGB = (0.45, 0.45, 0.45)
TRACE_RGB = (0.1, 0.35, 0.9)


def _rgb(hex_colour: str) -> tuple[int, int, int]:
    """``"#rrggbb"`` as integers in [0, 255] (what viser's node updates take; mesh colours accept them too)."""
    return (int(hex_colour[1:3], 16), int(hex_colour[3:5], 16), int(hex_colour[5:7], 16))


@dataclass(frozen=True)
class Contact:
    """Where a run first collided.

    Attributes:
        step: index of the first colliding log step.
        link: the colliding guarded link.
        obstacle: index of the obstacle it hit in the scene.
        point: ``(3,)`` contact point [m] (midpoint of the pair's nearest points).
    """

    step: int
    link: str
    obstacle: int
    point: Array


def find_contact(result: RunResult, scenario: Scenario) -> Contact | None:
    """The first collision of ``result``: its link (from the log) and the obstacle nearest that link.

    Returns ``None`` for a collision-free run.
    """
    k, link = result.collision_index, result.summary()["collision_link"]
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
    return Contact(k, link, int(clearance.pair_obstacles[best]), point)


def frame_steps(t: Array, fps: float, extra: int | None = None) -> Array:
    """Log step indices of the replay frames: the step nearest each ``1/fps`` [s] of run time, the last step and
    ``extra``."""
    times = np.arange(t[0], t[-1], 1.0 / fps)
    after = np.clip(np.searchsorted(t, times), 1, max(t.size - 1, 1))
    nearest = np.where(times - t[after - 1] < t[np.minimum(after, t.size - 1)] - times, after - 1, after)
    steps = np.append(np.minimum(nearest, t.size - 1), t.size - 1)
    if extra is not None:
        steps = np.append(steps, extra)
    return np.unique(steps)


def _wxyz(rotation: Array) -> Array:
    x, y, z, w = pin.Quaternion(np.asarray(rotation, float)).coeffs()
    return np.array([w, x, y, z])


class _Arm:
    """One arm drawn in the scene (the run's, a ghost or the oracle's): a frame per visual object."""

    def __init__(self, scene: Any, meshes: ArmMeshes, root: str, rgba: tuple[float, float, float, float] | None):
        self.meshes = meshes
        self.frames: list[Any] = []
        self.parts: dict[str, list[Any]] = {}
        for link in meshes.links:
            frame = scene.add_frame(f"{root}/{link.name}", show_axes=False)
            handles = [_add_part(scene, f"{root}/{link.name}/{i}", part, rgba) for i, part in enumerate(link.parts)]
            self.parts.setdefault(link.body, []).extend(handles)
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


def _add_part(scene: Any, name: str, part: Part, rgba: tuple[float, float, float, float] | None) -> Any:
    """A mesh node; ``rgba`` (a ghost's colour) replaces the part's own colour."""
    r, g, b, a = rgba or part.rgba
    return scene.add_mesh_simple(
        name, part.vertices, part.faces, color=(r, g, b), opacity=None if a >= 1.0 else a,
        cast_shadow=rgba is None, receive_shadow=rgba is None,
    )


def _polyline(points: Array) -> Array:
    """``(N, 3)`` points as the ``(N-1, 2, 3)`` segments viser draws."""
    return np.stack([points[:-1], points[1:]], axis=1)


def _camera(points: Array, planar: bool) -> tuple[Array, Array, float]:
    """A camera position and look-at point [m] that frame ``points``, and the scene's radius [m].

    Planar arms are seen from above (slightly tilted), spatial ones from the front right.
    """
    low, high = points.min(axis=0), points.max(axis=0)
    centre, radius = 0.5 * (low + high), max(0.5 * float(np.linalg.norm(high - low)), 0.3)
    direction = np.array([0.0, -0.35, 1.0]) if planar else np.array([1.0, -0.9, 0.6])
    return centre + (1.5 if planar else 1.25) * radius * direction / np.linalg.norm(direction), centre, radius


def _framed_points(result: RunResult, scenario: Scenario, meshes: ArmMeshes, steps: Array) -> Array:
    """Points the camera must see [m]: the hand, the desired path, the arm at the start, the bounded obstacles."""
    arm = [m.translation for m in meshes.placements(result.q[0])]
    times = result.t[steps]
    bounded = [o for o in scenario.scene.obstacles if not isinstance(o.shape, (Halfspace, Plane))]
    obstacles = [o.motion.positions(times) for o in bounded]
    return np.vstack([result.hand, _waypoints(scenario), arm, *obstacles])


def _waypoints(scenario: Scenario) -> Array:
    """The desired path's waypoints in 3-D [m] (z = 0 for a planar path): the whole path, reached or not."""
    points = scenario.path.waypoints
    return np.pad(points, ((0, 0), (0, 3 - points.shape[1])))


def replay_html(
    result: RunResult, scenario: Scenario, *, oracle: RunResult | None = None, fps: float = DEFAULT_FPS
) -> str:
    """The replay of ``result`` (in ``scenario``) as one self-contained HTML document.

    Args:
        result: the run.
        scenario: its scenario (robot source, obstacles).
        oracle: the oracle's run of the same scenario, drawn as a translucent green arm.
        fps: replay frames per second of run time.

    Raises:
        PreviewctlError: ``fps`` is not positive, or the run's joints do not match the scenario's robot.
    """
    if not fps > 0:
        raise PreviewctlError(f"fps must be > 0, got {fps}")
    robot = scenario.robot
    if result.q.shape[1] != robot.model.nq:
        raise PreviewctlError(
            f"run {result.scenario!r} has {result.q.shape[1]} joints; scenario {scenario.name!r}'s robot "
            f"{robot.name!r} has {robot.model.nq}: pass the scenario the run was made with"
        )
    import viser

    meshes = ArmMeshes(robot, scenario.robot_spec)
    contact = find_contact(result, scenario)
    steps = frame_steps(result.t, fps, contact.step if contact else None)
    planar = robot.task == "planar"
    eye, centre, radius = _camera(_framed_points(result, scenario, meshes, steps), planar)
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints its server's start and stop
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        scene = server.scene
        scene.set_up_direction("+z")
        # no environment map: in software WebGL (headless browsers, remote desktops) it costs ~1 s a frame
        scene.configure_environment_map(None)
        scene.add_light_hemisphere("/light", sky_color=(255, 255, 255), ground_color=(120, 120, 120), intensity=2.5)
        server.initial_camera.position = eye
        server.initial_camera.look_at = centre
        cell = 0.1 if radius < 1.0 else 0.25
        scene.add_grid("/grid", width=3.0 * radius, height=3.0 * radius, cell_size=cell, section_size=5 * cell,
                       position=(centre[0], centre[1], -0.05 if planar else 0.0))
        scene.add_line_segments("/path/desired", _polyline(_waypoints(scenario)), PATH_RGB, thickness=0.004)
        obstacles = _add_obstacles(scene, scenario, 3.0 * radius)
        arm = _Arm(scene, meshes, "/arm", None)
        ghosts = [_Arm(scene, meshes, f"/ghost{i}", GHOST_RGBA[i % len(GHOST_RGBA)])
                  for i in range(result.targets.shape[1])]
        oracle_arm = _Arm(scene, meshes, "/oracle", ORACLE_RGBA) if oracle is not None else None
        marker = scene.add_icosphere("/collision/marker", radius=max(0.02, 0.02 * radius), color=_rgb(COLLISION_COLOUR),
                                     visible=False)
        serializer = server.get_scene_serializer()
        previous = int(steps[0])
        for frame, k in enumerate(steps):
            k = int(k)
            t = float(result.t[k])
            arm.show(result.q[k])
            for i, ghost in enumerate(ghosts):
                ghost.show(result.targets[k, i])
            if oracle_arm is not None and oracle is not None:
                oracle_arm.show(oracle.q[min(int(np.searchsorted(oracle.t, t)), oracle.steps - 1)])
            for node in obstacles:
                placement = node.obstacle.placement(t)
                node.frame.position = placement.translation
                node.frame.wxyz = _wxyz(placement.rotation)
            if k > previous:
                scene.add_line_segments(f"/path/trace/{frame}", _polyline(result.hand[previous:k + 1]), TRACE_RGB,
                                        thickness=0.006)
            previous = k
            if contact is not None and k == contact.step:
                _show_contact(scene, contact, arm, obstacles[contact.obstacle], marker, t)
            serializer.insert_sleep(float(result.t[steps[frame + 1]] - t) if frame + 1 < steps.size else HOLD)
        return serializer.as_html()
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


@dataclass(frozen=True, eq=False)
class _ObstacleNode:
    """An obstacle in the scene: its frame (moved each frame) and its mesh handles (recoloured at a collision)."""

    obstacle: Obstacle
    frame: Any
    parts: tuple[Any, ...]


def _add_obstacles(scene: Any, scenario: Scenario, plane_size: float) -> list[_ObstacleNode]:
    """A frame per obstacle with its mesh."""
    nodes = []
    for obstacle in scenario.scene.obstacles:
        root = f"/obstacles/{obstacle.name}"
        frame = scene.add_frame(root, show_axes=False)
        parts = shape_parts(obstacle.shape.geometry(), OBSTACLE_RGBA, plane_size)
        handles = tuple(_add_part(scene, f"{root}/{i}", part, None) for i, part in enumerate(parts))
        nodes.append(_ObstacleNode(obstacle, frame, handles))
    return nodes


def _show_contact(scene: Any, contact: Contact, arm: _Arm, obstacle: _ObstacleNode, marker: Any, t: float) -> None:
    """From the collision on: the link and the obstacle in red, the contact marked and labelled."""
    red = _rgb(COLLISION_COLOUR)
    for handle in (*arm.parts.get(contact.link, []), *obstacle.parts):
        handle.color = red
    marker.position = contact.point
    marker.visible = True
    scene.add_label("/collision/label", f"collision at t = {t:.2f} s: {contact.link} hits {obstacle.obstacle.name}",
                    position=contact.point)


def scenario_of(result: RunResult) -> Scenario:
    """The shipped scenario a run was made with (``scenarios/<name>.toml``).

    Raises:
        PreviewctlError: no shipped scenario has the run's name (the message says how to pass one).
    """
    path = shipped_scenarios_dir() / f"{result.scenario}.toml"
    if not path.is_file():
        shipped = sorted(p.stem for p in shipped_scenarios_dir().glob("*.toml"))
        raise PreviewctlError(
            f"run of scenario {result.scenario!r}: no shipped scenario has that name ({', '.join(shipped)}); "
            "pass its scenario file (--scenario FILE)"
        )
    return load_scenario(path)


def sibling_oracle(run_dir: Path, result: RunResult) -> RunResult | None:
    """The oracle's run beside ``run_dir`` (``../oracle``, as ``previewctl paper`` writes), if there is one."""
    folder = run_dir.parent / "oracle"
    if result.controller == "oracle" or not (folder / "run.npz").is_file():
        return None
    oracle = load_run(folder)
    return oracle if oracle.scenario == result.scenario else None


def write_replay(
    run: RunResult | str | os.PathLike[str],
    path: str | os.PathLike[str] | None = None,
    *,
    scenario: Scenario | None = None,
    oracle: RunResult | None = None,
    fps: float = DEFAULT_FPS,
) -> Path:
    """Write the 3-D replay of a run as one self-contained HTML file (atomically).

    Args:
        run: the run, or its folder (``run.npz``, as :func:`~previewctl.sim.log.save_run` writes).
        path: the HTML file; default ``<run folder>/replay.html`` (required when ``run`` is a result).
        scenario: the run's scenario; default: the shipped scenario of the run's name.
        oracle: the oracle's run to draw beside it; default for a folder: ``../oracle`` if it holds a run
            of the same scenario.
        fps: replay frames per second of run time.

    Returns:
        The path written.

    Raises:
        PreviewctlError: no run in the folder, no scenario for it, or a file that cannot be written.
    """
    if isinstance(run, RunResult):
        if path is None:
            raise PreviewctlError("write_replay(result, path): a RunResult needs the path of the HTML file")
        result = run
    else:
        folder = Path(run)
        result = load_run(folder)
        if oracle is None:
            oracle = sibling_oracle(folder, result)
        path = folder / REPLAY_NAME if path is None else path
    html = replay_html(result, scenario or scenario_of(result), oracle=oracle, fps=fps)
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(out, html.encode("utf-8"))
    except OSError as exc:
        raise PreviewctlError(f"cannot write the replay to {str(out)!r}: {exc}") from exc
    return out
