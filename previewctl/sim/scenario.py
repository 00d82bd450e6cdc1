"""Scenario files: one TOML file describes a whole run (robot, hand path, obstacles, controller, timing).

Example (every section but ``[robot]`` and ``[path]`` is optional)::

    name = "planar_free"          # default: the file name
    seed = 0                       # random seed of the GA-based controllers

    [robot]
    source = "planar4"             # URDF path, shipped robot or example-robot-data name
    q0 = [1.2, 1.8, -2.9, 1.5]     # initial configuration [rad] (or q0_deg = [...] [deg])
    # tip, lock, task, guarded_links, control_points, geometry, package_dirs: see load_robot

    [path]
    waypoints = [[0.6, 1.4], [0.9, 1.4]]   # [m]; 2 columns for planar arms, 3 otherwise
    duration = 5.0                          # [s]
    # start_time = 0.0 [s]; orientation_rpy = [r, p, y] [rad] (pose tasks only)

    [[obstacles]]                  # as previewctl.scene.scene_from_dict accepts
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

    [index]                        # AMSI: length_unit [m] (default 0.01), weights a_i
    [potential]                    # influence_distance [m], gain, collision_value
    [output]                       # figures = ["strobe", "S", "clearance", "error"], gif = true, strobe_poses = 12

Every error is a :class:`~previewctl.errors.ScenarioError` whose message starts with the file name,
names the bad key by its dotted path (``controller.weights``), shows the value, and for an unknown
key lists the valid ones (with a "did you mean" for near misses).
"""

from __future__ import annotations

import difflib
import math
import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib
from previewctl.control.params import CONTROLLER_NAMES, ControllerParams, ControllerSpec, check_preview_weights
from previewctl.errors import PreviewctlError, ScenarioError
from previewctl.index.amsi import IndexParams
from previewctl.index.potential import Potential
from previewctl.path import HandPath
from previewctl.robot.load import load_robot
from previewctl.robot.model import GEOMETRY_CHOICES, Robot
from previewctl.scene.file import scene_from_dict
from previewctl.scene.motion import rpy_to_matrix
from previewctl.scene.shapes import Scene
from previewctl.types import Array
from previewctl.validation import show

START_TOLERANCE = 0.01
"""Largest distance [m] allowed between the hand at ``q0`` and the path start."""
START_ANGLE_TOLERANCE = 0.05
"""Largest angle [rad] allowed between the hand orientation at ``q0`` and the path's (pose tasks)."""
FIGURES: tuple[str, ...] = ("strobe", "S", "clearance", "error")
"""Figures the ``[output]`` section may ask for."""

_TOP_KEYS = ("name", "description", "seed", "robot", "path", "obstacles", "controller", "timing", "index",
             "potential", "output")
_ROBOT_KEYS = ("source", "tip", "lock", "task", "guarded_links", "control_points", "geometry", "package_dirs",
               "q0", "q0_deg")
_PATH_KEYS = ("waypoints", "duration", "start_time", "orientation_rpy")
_CONTROLLER_KEYS = ("name", "gain", "gradient_gain", "feedback_gain", "damping", "singular_threshold",
                    "velocity_scale", "preview_time", "weights", "previews", "population", "elite", "top_k",
                    "fd_step", "ga", "with_gradient")
_TIMING_KEYS = ("dt", "frame", "duration")
_INDEX_KEYS = ("length_unit", "weights")
_POTENTIAL_KEYS = ("influence_distance", "gain", "collision_value")
_OUTPUT_KEYS = ("figures", "gif", "strobe_poses")


@dataclass(frozen=True)
class RobotSpec:
    """How the scenario's robot was loaded (to reload it, e.g. with exact meshes).

    Attributes mirror :func:`previewctl.robot.load.load_robot`'s arguments.
    """

    source: str
    tip: str | None = None
    lock: tuple[str, ...] | None = None
    task: str | None = None
    guarded_links: tuple[str, ...] | str = "intermediate"
    control_points: tuple[str, ...] | None = None
    geometry: str = "convex"
    package_dirs: tuple[str, ...] = ()

    def load(self, geometry: str | None = None) -> Robot:
        """Load the robot, optionally with another ``geometry`` (one of ``GEOMETRY_CHOICES``)."""
        return load_robot(
            self.source,
            tip=self.tip,
            lock=self.lock,
            task=self.task,  # type: ignore[arg-type]
            control_points=self.control_points,
            guarded_links=self.guarded_links,  # type: ignore[arg-type]
            geometry=(geometry or self.geometry),  # type: ignore[arg-type]
            package_dirs=self.package_dirs,
        )


@dataclass(frozen=True)
class Timing:
    """Time steps of a run.

    Attributes:
        dt: control period [s].
        frame: camera frame period [s]; GA controllers run one generation per frame.
        duration: simulated time [s].
    """

    dt: float = 0.01
    frame: float = 0.033
    duration: float = 1.0

    @property
    def steps(self) -> int:
        """Number of control periods in ``duration``."""
        return max(1, round(self.duration / self.dt))


@dataclass(frozen=True)
class OutputSpec:
    """What ``previewctl run`` writes besides the log.

    Attributes:
        figures: figure names among :data:`FIGURES`.
        gif: whether to write an animated GIF (planar arms).
        strobe_poses: number of arm poses drawn in the strobe plot.
    """

    figures: tuple[str, ...] = FIGURES
    gif: bool = True
    strobe_poses: int = 12


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
        outputs: figures and GIF.
        source: the file it was read from, or ``None``.
        description: free text.
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
    outputs: OutputSpec = field(default_factory=OutputSpec)
    source: Path | None = None
    description: str = ""

    def exact_robot(self) -> Robot:
        """The same robot with exact (mesh) collision geometry; ``self.robot`` if it already has it."""
        if self.robot_spec.geometry == "mesh":
            return self.robot
        return self.robot_spec.load("mesh")


# ------------------------------------------------------------------------------- validation


class _Reader:
    """Typed access to TOML values with messages that name the dotted key and the value."""

    def __init__(self, origin: str) -> None:
        self.origin = origin

    def error(self, message: str) -> ScenarioError:
        return ScenarioError(f"{self.origin}: {message}")

    def table(self, value: object, where: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.error(f"{where} must be a table ([{where}]), got {show(value)}")
        return value

    def keys(self, table: Mapping[str, Any], where: str, valid: Sequence[str]) -> None:
        for key in table:
            if key not in valid:
                dotted = f"{where}.{key}" if where else key
                close = difflib.get_close_matches(str(key), valid, n=1)
                hint = f" (did you mean {(where + '.' if where else '') + close[0]!r}?)" if close else ""
                section = f"[{where}]" if where else "the top level"
                raise self.error(f"unknown key {dotted!r}{hint}; valid keys in {section}: {', '.join(valid)}")

    def number(self, value: object, where: str, *, positive: bool = False, nonnegative: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(f"{where} must be a finite number, got {show(value)}")
        if positive and value <= 0:
            raise self.error(f"{where} must be > 0, got {show(value)}")
        if nonnegative and value < 0:
            raise self.error(f"{where} must be >= 0, got {show(value)}")
        return float(value)

    def integer(self, value: object, where: str, minimum: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(f"{where} must be an integer, got {show(value)}")
        if minimum is not None and value < minimum:
            raise self.error(f"{where} must be >= {minimum}, got {value}")
        return int(value)

    def string(self, value: object, where: str, choices: Sequence[str] | None = None) -> str:
        if not isinstance(value, str):
            raise self.error(f"{where} must be a string, got {show(value)}")
        if choices is not None and value not in choices:
            raise self.error(f"{where} = {value!r} is not valid; valid: {', '.join(choices)}")
        return value

    def boolean(self, value: object, where: str) -> bool:
        if not isinstance(value, bool):
            raise self.error(f"{where} must be true or false, got {show(value)}")
        return value

    def strings(self, value: object, where: str) -> tuple[str, ...]:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.error(f"{where} must be a list of strings, got {show(value)}")
        return tuple(value)

    def numbers(self, value: object, where: str, size: int | None = None) -> tuple[float, ...]:
        if (
            not isinstance(value, list)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            or not all(math.isfinite(v) for v in value)
        ):
            raise self.error(f"{where} must be a list of finite numbers, got {show(value)}")
        if size is not None and len(value) != size:
            raise self.error(f"{where} must have {size} entries, got {len(value)}: {show(value)}")
        return tuple(float(v) for v in value)

    def number_or_numbers(self, value: object, where: str) -> tuple[float, ...]:
        if isinstance(value, list):
            return self.numbers(value, where)
        return (self.number(value, where),)


def load_scenario(path: str | os.PathLike[str]) -> Scenario:
    """Read and validate a scenario TOML file.

    Args:
        path: the file.

    Returns:
        The scenario; relative paths inside (URDF, meshes) resolve against the file's folder.

    Raises:
        ScenarioError: missing file, TOML syntax error, or any bad key or value (named in the message).
    """
    file = Path(path)
    if not file.is_file():
        raise ScenarioError(f"scenario file {str(file)!r} does not exist")
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{file}: not valid TOML: {exc}") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{file}: cannot be read: {exc}") from exc
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
    base = Path(base_dir)
    origin = str(source) if source is not None else "scenario"
    rd = _Reader(origin)
    doc = rd.table(data, "scenario")
    rd.keys(doc, "", _TOP_KEYS)
    if "robot" not in doc:
        raise rd.error("missing section [robot] (with at least source = ... and q0 = [...])")
    if "path" not in doc:
        raise rd.error("missing section [path] (with waypoints = [[x, y(, z)], ...] and duration = ...)")
    default_name = Path(source).stem if source is not None else "scenario"
    name = rd.string(doc.get("name", default_name), "name")
    if not name:
        raise rd.error("name must be a non-empty string")
    description = rd.string(doc.get("description", ""), "description")
    seed = rd.integer(doc.get("seed", 0), "seed", minimum=0)

    robot_spec, q0_spec = _robot_spec(rd, rd.table(doc["robot"], "robot"), base)
    try:
        robot = robot_spec.load()
    except PreviewctlError as exc:
        raise rd.error(f"robot: {exc}") from exc
    path = _path(rd, rd.table(doc["path"], "path"), robot)
    q0 = _initial_configuration(rd, robot, q0_spec, path)
    try:
        scene = scene_from_dict(doc.get("obstacles", []), "obstacles", base)
    except PreviewctlError as exc:
        raise rd.error(str(exc)) from exc
    controller = _controller(rd, rd.table(doc.get("controller", {}), "controller"), robot)
    timing = _timing(rd, rd.table(doc.get("timing", {}), "timing"), path)
    index = _index(rd, rd.table(doc.get("index", {}), "index"), robot)
    potential = _potential(rd, rd.table(doc.get("potential", {}), "potential"))
    outputs = _outputs(rd, rd.table(doc.get("output", {}), "output"))
    return Scenario(
        name=name,
        robot=robot,
        robot_spec=robot_spec,
        q0=q0,
        path=path,
        scene=scene,
        controller=controller,
        timing=timing,
        index=index,
        potential=potential,
        seed=seed,
        outputs=outputs,
        source=Path(source) if source is not None else None,
        description=description,
    )


def _robot_spec(rd: _Reader, table: Mapping[str, Any], base: Path) -> tuple[RobotSpec, tuple[str, tuple[float, ...]]]:
    rd.keys(table, "robot", _ROBOT_KEYS)
    if "source" not in table:
        raise rd.error("robot.source is missing (a URDF path, 'planar4' or an example-robot-data name like 'panda')")
    source = rd.string(table["source"], "robot.source")
    if source.endswith(".urdf") and not Path(source).is_absolute():
        source = str(base / source)
    guarded: tuple[str, ...] | str = "intermediate"
    if "guarded_links" in table:
        value = table["guarded_links"]
        guarded = value if isinstance(value, str) else rd.strings(value, "robot.guarded_links")
    spec = RobotSpec(
        source=source,
        tip=rd.string(table["tip"], "robot.tip") if "tip" in table else None,
        lock=rd.strings(table["lock"], "robot.lock") if "lock" in table else None,
        task=rd.string(table["task"], "robot.task", ("planar", "position", "pose")) if "task" in table else None,
        guarded_links=guarded,
        control_points=rd.strings(table["control_points"], "robot.control_points")
        if "control_points" in table
        else None,
        geometry=rd.string(table.get("geometry", "convex"), "robot.geometry", GEOMETRY_CHOICES),
        package_dirs=tuple(
            str(base / d) if not Path(d).is_absolute() else d
            for d in rd.strings(table.get("package_dirs", []), "robot.package_dirs")
        ),
    )
    if ("q0" in table) == ("q0_deg" in table):
        raise rd.error("give the initial configuration as exactly one of robot.q0 [rad] or robot.q0_deg [deg]")
    key = "q0" if "q0" in table else "q0_deg"
    return spec, (key, rd.numbers(table[key], f"robot.{key}"))


def _path(rd: _Reader, table: Mapping[str, Any], robot: Robot) -> HandPath:
    rd.keys(table, "path", _PATH_KEYS)
    for key in ("waypoints", "duration"):
        if key not in table:
            raise rd.error(f"path.{key} is missing")
    raw = table["waypoints"]
    if not isinstance(raw, list) or len(raw) < 2:
        raise rd.error(f"path.waypoints must be a list of at least 2 points [[x, y(, z)], ...], got {show(raw)}")
    dim = 2 if robot.task == "planar" else 3
    points = [rd.numbers(p, f"path.waypoints[{i}]", dim) for i, p in enumerate(raw)]
    duration = rd.number(table["duration"], "path.duration", positive=True)
    start = rd.number(table.get("start_time", 0.0), "path.start_time")
    orientation = None
    if "orientation_rpy" in table:
        if robot.task != "pose":
            raise rd.error(f"path.orientation_rpy only applies to task = 'pose'; robot {robot.name!r} has task "
                           f"{robot.task!r}")
        orientation = rpy_to_matrix(np.array(rd.numbers(table["orientation_rpy"], "path.orientation_rpy", 3)))
    elif robot.task == "pose":
        raise rd.error("path.orientation_rpy = [roll, pitch, yaw] [rad] is required for task = 'pose'")
    try:
        return HandPath(np.array(points), duration, start, orientation)
    except PreviewctlError as exc:
        raise rd.error(f"path: {exc}") from exc


def _initial_configuration(rd: _Reader, robot: Robot, spec: tuple[str, tuple[float, ...]], path: HandPath) -> Array:
    key, values = spec
    where = f"robot.{key}"
    angles = np.radians(values) if key == "q0_deg" else np.array(values)
    if len(angles) == robot.nq:
        q0 = np.array(angles, dtype=float)
    elif len(angles) == robot.nv:
        q0 = robot.configuration_from_angles(angles)
    else:
        sizes = f"{robot.nv}" if robot.nq == robot.nv else f"{robot.nv} (angles) or {robot.nq} (configuration)"
        raise rd.error(
            f"{where} has {len(values)} entries; robot {robot.name!r} needs {sizes} for joints "
            f"{', '.join(robot.joint_names)}"
        )
    lo, hi = robot.lower_limits, robot.upper_limits
    outside = np.flatnonzero((q0 < lo - 1e-9) | (q0 > hi + 1e-9))
    if outside.size:
        j = int(outside[0])
        raise rd.error(
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
        raise rd.error(
            f"{where} puts the hand at {shown} m, {gap:.4f} m from the path start "
            f"{np.array2string(path.waypoints[0], precision=4, separator=', ')} m; it must be within "
            f"{START_TOLERANCE} m (move q0 or the first waypoint)"
        )
    if robot.task == "pose" and path.orientation is not None:
        angle = float(np.linalg.norm(pin.log3(path.orientation @ tip.rotation.T)))
        if angle > START_ANGLE_TOLERANCE:
            raise rd.error(f"{where} turns the hand {angle:.4f} rad away from path.orientation_rpy; it must be "
                           f"within {START_ANGLE_TOLERANCE} rad")
    return q0


def _controller(rd: _Reader, table: Mapping[str, Any], robot: Robot) -> ControllerSpec:
    rd.keys(table, "controller", _CONTROLLER_KEYS)
    name = rd.string(table.get("name", "none"), "controller.name", CONTROLLER_NAMES)
    kwargs: dict[str, Any] = {}
    for key in ("gain", "gradient_gain"):
        if key in table:
            gains = rd.number_or_numbers(table[key], f"controller.{key}")
            if len(gains) not in (1, robot.nv):
                raise rd.error(f"controller.{key} has {len(gains)} entries; give one number or {robot.nv} "
                               f"(one per joint velocity)")
            if not all(g > 0 for g in gains):
                raise rd.error(f"controller.{key} must be positive, got {show(table[key])}")
            kwargs[key] = gains
    for key in ("feedback_gain", "damping"):
        if key in table:
            kwargs[key] = rd.number(table[key], f"controller.{key}", nonnegative=True)
    for key in ("singular_threshold", "velocity_scale", "preview_time", "fd_step"):
        if key in table:
            kwargs[key] = rd.number(table[key], f"controller.{key}", positive=True)
    if "velocity_scale" in kwargs and kwargs["velocity_scale"] > 1:
        raise rd.error(f"controller.velocity_scale must lie in (0, 1], got {kwargs['velocity_scale']!r}")
    for key, minimum in (("previews", 1), ("population", 2), ("elite", 0), ("top_k", 1)):
        if key in table:
            kwargs[key] = rd.integer(table[key], f"controller.{key}", minimum)
    if "weights" in table:
        weights = rd.numbers(table["weights"], "controller.weights")
        try:
            kwargs["weights"] = check_preview_weights(list(weights), "controller.weights")
        except PreviewctlError as exc:
            raise rd.error(str(exc)) from exc
    if "ga" in table:
        kwargs["ga_options"] = tuple(rd.table(table["ga"], "controller.ga").items())
    if "with_gradient" in table:
        kwargs["with_gradient"] = rd.boolean(table["with_gradient"], "controller.with_gradient")
    try:
        params = ControllerParams(**kwargs)
    except PreviewctlError as exc:
        raise rd.error(f"controller.{exc}") from exc
    return ControllerSpec(name, params)


def _timing(rd: _Reader, table: Mapping[str, Any], path: HandPath) -> Timing:
    rd.keys(table, "timing", _TIMING_KEYS)
    dt = rd.number(table.get("dt", 0.01), "timing.dt", positive=True)
    frame = rd.number(table.get("frame", 0.033), "timing.frame", positive=True)
    duration = rd.number(table.get("duration", path.end_time), "timing.duration", positive=True)
    if dt > duration:
        raise rd.error(f"timing.dt = {dt} s is longer than timing.duration = {duration} s")
    return Timing(dt, frame, duration)


def _index(rd: _Reader, table: Mapping[str, Any], robot: Robot) -> IndexParams:
    rd.keys(table, "index", _INDEX_KEYS)
    length_unit = rd.number(table.get("length_unit", 0.01), "index.length_unit", positive=True)
    weights = None
    if "weights" in table:
        weights = rd.numbers(table["weights"], "index.weights")
        if len(weights) != len(robot.control_points):
            raise rd.error(
                f"index.weights has {len(weights)} entries; robot {robot.name!r} has {len(robot.control_points)} "
                f"control points ({', '.join(robot.control_points)})"
            )
        if not all(w >= 0 for w in weights):
            raise rd.error(f"index.weights must be >= 0, got {list(weights)}")
    try:
        return IndexParams(weights=weights, length_unit=length_unit)
    except PreviewctlError as exc:
        raise rd.error(f"index.{exc}") from exc


def _potential(rd: _Reader, table: Mapping[str, Any]) -> Potential:
    rd.keys(table, "potential", _POTENTIAL_KEYS)
    kwargs = {key: rd.number(table[key], f"potential.{key}") for key in _POTENTIAL_KEYS if key in table}
    try:
        return Potential(**kwargs)
    except PreviewctlError as exc:
        raise rd.error(f"potential.{exc}") from exc


def _outputs(rd: _Reader, table: Mapping[str, Any]) -> OutputSpec:
    rd.keys(table, "output", _OUTPUT_KEYS)
    figures = rd.strings(table.get("figures", list(FIGURES)), "output.figures")
    for figure in figures:
        if figure not in FIGURES:
            raise rd.error(f"output.figures: unknown figure {figure!r}; valid: {', '.join(FIGURES)}")
    gif = rd.boolean(table.get("gif", True), "output.gif")
    poses = rd.integer(table.get("strobe_poses", 12), "output.strobe_poses", minimum=2)
    return OutputSpec(figures, gif, poses)
