"""Scenario files: one TOML file describes a whole run (robot, hand path, obstacles, controller, timing).

Example (every section but ``[robot]`` and ``[path]`` is optional)::

    name = "planar_free"          # default: the file name
    seed = 0                       # random seed of the GA-based controllers

    [robot]
    source = "planar4"             # URDF path, shipped robot or example-robot-data name
    q0 = [1.2, 1.8, -2.9, 1.5]     # initial configuration [rad] (or q0_deg = [...] [deg], or "auto":
                                   # the best collision-free one with the hand at the first waypoint)
    # tip, lock, task, guarded_links, control_points, geometry, package_dirs, srdf: see load_robot

    [path]
    waypoints = [[0.6, 1.4], [0.9, 1.4]]   # [m]; 2 columns for planar arms, 3 otherwise
    duration = 5.0                          # [s]
    # start_time = 0.0 [s]; orientation_rpy = [r, p, y] [rad] (pose tasks only)

    [[obstacles]]                  # as previewctl.scene.file.scene_from_dict accepts
    name = "ball"
    shape = "sphere"
    radius = 0.1
    position = [1.5, -1.0]

    [controller]
    name = "multi"                 # none | gradient | single | multi | reach
    gain = 1.0                     # K_v [1/s]; see previewctl.control.params.ControllerParams for every key
    preview_time = 5.0             # t~ [s]
    weights = [0.3, 0.65, 0.05]    # k_i: 0 < k_i < 1, sum 1

    [timing]
    dt = 0.01                      # control period [s]
    frame = 0.033                  # camera frame [s] (one GA generation per frame)
    duration = 5.0                 # simulated time [s] (default: path end)

    [verdict]
    tolerance = 0.005              # largest hand error [m] of a successful run (and collision-free)

    [index]                        # AMSI: length_unit [m] (default 0.01), weights a_i
    [potential]                    # influence_distance [m], gain, collision_value
    [output]                       # figures = ["strobe", "S", "clearance", "error"], gif = true, strobe_poses = 12

The document is first checked against the schema (:mod:`previewctl.sim.schema`, which says how to
add a key), then the robot, path, scene and controller are built. Every error is a
:class:`~previewctl.errors.ScenarioError` whose message starts with the file name, names the bad key
by its dotted path (``controller.weights``), shows the value, and for an unknown key or name lists
the valid ones (with a "did you mean" for near misses).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.control.nullspace import gain_vector
from previewctl.control.params import ControllerParams, ControllerSpec
from previewctl.errors import PreviewctlError, ScenarioError, UnreachableTargetError
from previewctl.index.amsi import IndexParams
from previewctl.index.evaluator import Evaluator
from previewctl.index.potential import Potential
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.robot.reach import reach_of
from previewctl.scene.clearance import check_dimensions
from previewctl.scene.file import scene_from_tables
from previewctl.scene.motion import rpy_to_matrix
from previewctl.scene.shapes import Scene
from previewctl.search.explore import explore
from previewctl.sensing.options import Sensing
from previewctl.sim.schema import FIGURES, OutputSpec, RobotSpec, ScenarioFile, Timing, Verdict
from previewctl.types import Array
from previewctl.validation import show, validate
from previewctl.validation.toml import read_toml

__all__ = ["FIGURES", "OutputSpec", "RobotSpec", "Scenario", "Timing", "Verdict", "load_scenario",
           "scenario_from_dict"]

START_TOLERANCE = 0.01
"""Largest distance [m] allowed between the hand at ``q0`` and the path start."""
REACH_SLACK = 1e-9
"""Round-off allowed [m] when a path point sits exactly on the reach shell."""
START_ANGLE_TOLERANCE = 0.05
"""Largest angle [rad] allowed between the hand orientation at ``q0`` and the path's (pose tasks)."""


@dataclass(frozen=True, eq=False)
class Scenario:
    """A complete run description. Build it with :func:`load_scenario` or :func:`scenario_from_dict`.

    Attributes:
        name: scenario name (default: the file stem).
        robot: the arm (search geometry, usually convex).
        robot_spec: how to reload it (e.g. with exact meshes for the collision check).
        q0: initial configuration ``(nq,)`` [rad].
        path: the desired hand path.
        scene: the obstacles.
        controller: controller name and parameters.
        timing: control period, camera frame, duration.
        index: AMSI parameters.
        potential: obstacle potential parameters.
        seed: random seed for the controllers.
        verdict: when a run succeeds (collision-free and the hand error within a tolerance).
        outputs: figures and GIF.
        source: the file it was read from, or ``None``.
        description: free text.
        sensing: the observed obstacles (the ``[sensing]`` table), or ``None``: every motion is known.
    """

    name: str
    robot: Robot
    robot_spec: RobotSpec
    q0: Array
    path: HandPath
    scene: Scene
    controller: ControllerSpec
    timing: Timing
    index: IndexParams
    potential: Potential
    seed: int = 0
    verdict: Verdict = field(default_factory=Verdict)
    outputs: OutputSpec = field(default_factory=OutputSpec)
    source: Path | None = None
    description: str = ""
    sensing: Sensing | None = None

    def exact_robot(self) -> Robot:
        """The same robot with exact (mesh) collision geometry; ``self.robot`` if it already has it."""
        if self.robot_spec.geometry == "mesh":
            return self.robot
        return self.robot_spec.load("mesh")


def load_scenario(path: str | os.PathLike[str], *, auto_start: bool = False) -> Scenario:
    """Read and validate a scenario TOML file.

    Args:
        path: the file.
        auto_start: replace the file's ``q0`` by ``"auto"`` (the best collision-free configuration with
            the hand at the first waypoint).

    Returns:
        The scenario; relative paths inside (URDF, meshes) resolve against the file's folder.

    Raises:
        ScenarioError: missing file, TOML syntax error, or any bad key or value (named in the message).
    """
    file = Path(path)
    data = read_toml(file, ScenarioError, "scenario file")
    if auto_start and isinstance(data.get("robot"), dict):
        robot = {key: value for key, value in data["robot"].items() if key not in ("q0", "q0_deg")}
        data = {**data, "robot": {**robot, "q0": "auto"}}
    return scenario_from_dict(data, file.parent, source=file)


def scenario_from_dict(
    data: Mapping[str, Any], base_dir: str | os.PathLike[str] = ".", *, source: str | os.PathLike[str] | None = None
) -> Scenario:
    """Build a scenario from a parsed TOML document.

    Args:
        data: the document (a mapping of sections).
        base_dir: folder against which relative file paths resolve.
        source: the file the document came from (used in messages and as the default name).

    Raises:
        ScenarioError: a bad key or value (named by its dotted path in the message).
    """
    origin = str(source) if source is not None else "scenario"
    doc: ScenarioFile = validate(ScenarioFile, data, ScenarioError, prefix=f"{origin}: ", root="the scenario")
    try:
        return _build(doc, Path(base_dir), source)
    except PreviewctlError as exc:
        raise ScenarioError(f"{origin}: {exc}") from exc


@contextmanager
def _section(prefix: str) -> Iterator[None]:
    """Errors of the value objects built inside, prefixed with where they come from (``"path."``)."""
    try:
        yield
    except PreviewctlError as exc:
        raise ScenarioError(f"{prefix}{exc}") from exc


def _build(doc: ScenarioFile, base: Path, source: str | os.PathLike[str] | None) -> Scenario:
    """The runtime objects of a validated document; robot-dependent checks raise ``ScenarioError``."""
    robot_spec = _robot_spec(doc.robot, base)
    with _section("robot: "):
        robot = robot_spec.load()
    path = _path(doc.path, robot)
    _check_reach(robot, path)
    scene = scene_from_tables(doc.obstacles, base)
    check_dimensions(robot, scene)  # a 2-D obstacle around a spatial arm, refused when the file is read
    index_params, potential = IndexParams(**doc.index.model_dump()), Potential(**doc.potential.model_dump())
    if doc.robot.q0 == "auto":
        q0 = _best_start(robot, path, Evaluator(robot, scene, index_params, potential))
    else:
        q0 = _initial_configuration(doc.robot, robot, path)
    controller = _controller(doc.controller, robot)
    with _section("[timing] "):
        timing = Timing(doc.timing.dt, doc.timing.frame, doc.timing.duration or path.end_time)
    index = doc.index
    if index.weights is not None and len(index.weights) != len(robot.control_points):
        raise ScenarioError(
            f"index.weights has {len(index.weights)} entries; robot {robot.name!r} has {len(robot.control_points)} "
            f"control points ({', '.join(robot.control_points)})"
        )
    return Scenario(
        name=doc.name or (Path(source).stem if source is not None else "scenario"),
        robot=robot,
        robot_spec=robot_spec,
        q0=q0,
        path=path,
        scene=scene,
        controller=controller,
        timing=timing,
        index=index_params,
        potential=potential,
        seed=doc.seed,
        verdict=Verdict(**doc.verdict.model_dump()),
        outputs=OutputSpec(**doc.output.model_dump()),
        source=Path(source) if source is not None else None,
        description=doc.description,
        sensing=None if doc.sensing is None else _sensing(doc.sensing),
    )


def _sensing(table: Any) -> Sensing:
    """The ``[sensing]`` table's :class:`~previewctl.sensing.options.Sensing`."""
    with _section("[sensing] "):
        return Sensing(**table.model_dump())


def _robot_spec(table: Any, base: Path) -> RobotSpec:
    """The robot's spec, with relative URDF, SRDF and package paths resolved against ``base``."""
    values = table.model_dump(exclude={"q0", "q0_deg"})
    if values["source"].endswith(".urdf") and not Path(values["source"]).is_absolute():
        values["source"] = str(base / values["source"])
    if values["srdf"] is not None and not Path(values["srdf"]).is_absolute():
        values["srdf"] = str(base / values["srdf"])
    values["package_dirs"] = tuple(d if Path(d).is_absolute() else str(base / d) for d in values["package_dirs"])
    return RobotSpec(**values)


def _path(table: Any, robot: Robot) -> HandPath:
    """The hand path of ``[path]``: one waypoint entry per task coordinate, an orientation for pose tasks."""
    dim = 2 if robot.task == "planar" else 3
    for i, point in enumerate(table.waypoints):
        if len(point) != dim:
            raise ScenarioError(f"path.waypoints[{i}] must have {dim} entries (robot {robot.name!r} has task "
                                f"{robot.task!r}), got {len(point)}: {show(list(point))}")
    orientation = None
    if table.orientation_rpy is not None:
        if robot.task != "pose":
            raise ScenarioError(f"path.orientation_rpy only applies to task = 'pose'; robot {robot.name!r} has task "
                                f"{robot.task!r}")
        orientation = rpy_to_matrix(table.orientation_rpy)
    elif robot.task == "pose":
        raise ScenarioError("path.orientation_rpy = [roll, pitch, yaw] [rad] is required for task = 'pose'")
    with _section("path."):  # HandPath's messages start with the key, e.g. "duration must be > 0 [s]"
        return HandPath(np.array(table.waypoints), table.duration, table.start_time, orientation)


def _check_reach(robot: Robot, path: HandPath) -> None:
    """Every point of the path within the arm's reach shell (:mod:`previewctl.robot.reach`).

    Raises:
        ScenarioError: a waypoint beyond the outer radius, or a segment through the inner hole.
    """
    reach = reach_of(robot)
    centre = reach.centre[: path.dim]
    shown = show(np.round(centre, 4).tolist())
    for i, point in enumerate(path.waypoints):
        distance = float(np.linalg.norm(point - centre))
        if distance > reach.outer + REACH_SLACK:
            raise ScenarioError(
                f"path.waypoints[{i}] = {show(point.tolist())} m is {distance:.4f} m from the base of robot "
                f"{robot.name!r} (its first joint, at {shown} m), beyond its reach of {reach.outer:.4f} m"
            )
    for i, (a, b) in enumerate(zip(path.waypoints[:-1], path.waypoints[1:], strict=True)):
        d = b - a
        s = float(np.clip((centre - a) @ d / (d @ d), 0.0, 1.0)) if d @ d > 0 else 0.0
        closest = float(np.linalg.norm(a + s * d - centre))
        if closest < reach.inner - REACH_SLACK:
            raise ScenarioError(
                f"path segment {i}-{i + 1} passes {closest:.4f} m from the base of robot {robot.name!r} (at "
                f"{shown} m); the hand cannot come closer than {reach.inner:.4f} m"
            )


def _best_start(robot: Robot, path: HandPath, evaluator: Evaluator) -> Array:
    """``q0 = "auto"``: the global exploration's best configuration with the hand at the first waypoint.

    Raises:
        ScenarioError: no configuration reaches the first waypoint without collision.
    """
    target: Any = path.waypoints[0]
    if robot.task == "pose" and path.orientation is not None:
        target = (np.pad(path.waypoints[0], (0, 3 - path.dim)), path.orientation)
    try:
        best = explore(robot, evaluator, target, path.start_time).best
    except UnreachableTargetError as exc:
        raise ScenarioError(f"robot.q0 = 'auto': {exc}") from exc
    if best.S < 0:
        raise ScenarioError(f"robot.q0 = 'auto': every configuration with the hand at path.waypoints[0] = "
                            f"{show(path.waypoints[0].tolist())} m collides")
    return np.array(best.q, dtype=float)


def _initial_configuration(table: Any, robot: Robot, path: HandPath) -> Array:
    """``q0`` [rad] of ``[robot]``: one entry per joint, within the limits, the hand at the path start."""
    key = "q0" if table.q0 is not None else "q0_deg"
    values = getattr(table, key)
    where = f"robot.{key}"
    angles = np.radians(values) if key == "q0_deg" else np.array(values)
    if len(angles) == robot.nq:
        q0 = np.array(angles, dtype=float)
    elif len(angles) == robot.nv:
        q0 = robot.configuration_from_angles(angles)
    else:
        sizes = f"{robot.nv}" if robot.nq == robot.nv else f"{robot.nv} (angles) or {robot.nq} (configuration)"
        raise ScenarioError(
            f"{where} has {len(values)} entries; robot {robot.name!r} needs {sizes} for joints "
            f"{', '.join(robot.joint_names)}"
        )
    lo, hi = robot.lower_limits, robot.upper_limits
    outside = np.flatnonzero((q0 < lo - 1e-9) | (q0 > hi + 1e-9))
    if outside.size:
        j = int(outside[0])
        raise ScenarioError(
            f"{where}: joint {robot.joint_names_by_q()[j]!r} = {q0[j]:.6g} rad is outside its limits "
            f"[{lo[j]:.6g}, {hi[j]:.6g}] rad"
        )
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q0)
    tip = data.oMf[robot.tip_frame_id]
    start = np.zeros(3)
    start[: path.dim] = path.waypoints[0]
    hand = np.array(tip.translation)
    if robot.task == "planar":
        hand[2] = 0.0
    gap = float(np.linalg.norm(hand - start))
    if gap > START_TOLERANCE:
        shown = np.array2string(hand[: path.dim], precision=4, separator=", ")
        raise ScenarioError(
            f"{where} puts the hand at {shown} m, {gap:.4f} m from the path start "
            f"{np.array2string(path.waypoints[0], precision=4, separator=', ')} m; it must be within "
            f"{START_TOLERANCE} m (move q0 or the first waypoint, or set q0 = \"auto\" (previewctl run --q0 auto) "
            "to start from the best collision-free configuration at the first waypoint)"
        )
    if robot.task == "pose" and path.orientation is not None:
        angle = float(np.linalg.norm(pin.log3(path.orientation @ tip.rotation.T)))
        if angle > START_ANGLE_TOLERANCE:
            raise ScenarioError(f"{where} turns the hand {angle:.4f} rad away from path.orientation_rpy; it must be "
                                f"within {START_ANGLE_TOLERANCE} rad")
    return q0


def _controller(table: Any, robot: Robot) -> ControllerSpec:
    """The controller of ``[controller]``: the gains have one entry or one per joint velocity."""
    for key in ("gain", "gradient_gain"):
        gain_vector(getattr(table, key), robot.nv, f"controller.{key}")
    values = table.model_dump(exclude={"name", "ga"})
    ga_options = tuple(table.ga.model_dump(exclude_unset=True).items())
    with _section("[controller] "):
        return ControllerSpec(table.name, ControllerParams(**values, ga_options=ga_options))
