"""Robots from URDF: a reduced Pinocchio model, its collision geometry, the task and control points.

``load_robot(source)`` accepts a URDF file path, a robot shipped in ``robots/`` (``"planar4"``) or an
example-robot-data name (``"panda"``, ``"ur5"``, ...). Defaults:

* chain: from the root, follow the deepest subtree; stop where the remaining children are all leaf
  joints (a gripper's fingers). Every joint off that chain is locked at its neutral value.
* tip frame: on the last chain joint, a tool-like frame (``*tcp*``, ``tool0``, ``*end_effector*``,
  ``ee_link``) if there is one, else the frame furthest from the joint in the frame tree.
* task: ``planar`` (x, y) when every chain joint turns about the world z axis in one plane,
  otherwise ``position``; ``pose`` (6 rows) on request.
* control points: the distinct joint origins along the chain that move (for planar4 the tips of
  links 1-3, as in the paper).
* guarded links: every moving link's clearance enters the potential and the collision check
  (``guarded_links="intermediate"`` leaves out the hand's link, the paper's "intermediate links").
  The hand's links may touch an obstacle marked as the work surface, and nothing else.
* self pairs: the pairs of the arm's own links checked against each other (:mod:`previewctl.robot.self_pairs`),
  from ``srdf=`` or the robot's shipped SRDF (``robots/<name>.srdf``, or example-robot-data's next to its URDF),
  else sampled as MoveIt's setup assistant does. The self geometry is every link with collision geometry, the base
  and the fingers included, in the same geometry choice.
* geometry: ``"convex"`` replaces meshes by their convex hulls and cylinders by capsules (a
  conservative cover, 20-40x cheaper distances); ``"capsules"`` replaces every mesh and cylinder by
  its smallest enclosing capsule along the mesh's principal axis (coarser but still conservative:
  distances are lower bounds, computed about 2.5x faster than against hulls); ``"mesh"`` keeps the
  URDF geometry exactly.

The loader sits in the index, not in :mod:`previewctl.robot`: a loaded :class:`~previewctl.robot.model.Robot`
carries the structural rank of each control point's avoidance matrix, computed here with
:func:`~previewctl.index.amsi.avoidance` (which also refuses a task the hand cannot follow).
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
from collections import Counter
from collections.abc import Callable, Sequence
from importlib import resources
from pathlib import Path
from typing import Literal, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from previewctl.errors import RobotLoadError, UnknownNameError
from previewctl.extras import require
from previewctl.index.amsi import avoidance
from previewctl.robot.chain import HandFrames, hand_frames, split_joints
from previewctl.robot.geometry import body_name, keep_links, mesh_exists, prepare_geometry, select_guarded_links
from previewctl.robot.model import GEOMETRY_CHOICES, TASK_ROWS, Geometry, Robot, Task
from previewctl.robot.planar import PlanarChain
from previewctl.robot.self_pairs import SelfPairs, find_self_pairs
from previewctl.robot.xml import robot_root

_TOOL_NAME_HINTS = ("tcp", "tool0", "end_effector", "ee_link")
_log = logging.getLogger(__name__)


def shipped_robots_dir() -> Path:
    """The folder of URDFs shipped with previewctl (inside the wheel, or the repo's ``robots/``)."""
    packaged = resources.files("previewctl").joinpath("robots")
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[2] / "robots"


def shipped_robot_names() -> tuple[str, ...]:
    """Names of the robots shipped in ``robots/``."""
    return tuple(sorted(p.stem for p in shipped_robots_dir().glob("*.urdf")))


def example_robot_names() -> tuple[str, ...]:
    """Names that example-robot-data's loader knows (empty if it is not installed)."""
    try:
        import example_robot_data
    except ImportError:
        return ()
    return tuple(sorted(example_robot_data.ROBOTS))


def load_robot(
    source: str | os.PathLike[str],
    *,
    tip: str | None = None,
    lock: Sequence[str] | None = None,
    task: Task | None = None,
    control_points: Sequence[str] | None = None,
    guarded_links: Sequence[str] | Literal["all", "intermediate"] = "all",
    geometry: Geometry = "convex",
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    collision_from_visual: bool = False,
    srdf: str | os.PathLike[str] | None = None,
) -> Robot:
    """Load an arm and prepare it for avoidance-manipulability evaluation.

    Args:
        source: a URDF path, a shipped robot name (``"planar4"``) or an example-robot-data name.
        tip: hand frame; default: see the module docstring.
        lock: joints to lock at their neutral value; default: every joint off the base-tip chain.
        task: ``"planar"``, ``"position"`` or ``"pose"``; default: planar if the arm is planar.
        control_points: joint names whose origins are control points; default: distinct moving
            joint origins along the chain.
        guarded_links: body names whose geometry counts for clearance, or ``"all"`` (every moving
            link, the default) or ``"intermediate"`` (every moving link but the hand's, the paper's).
        geometry: ``"convex"`` (convex hulls, capsules for cylinders), ``"capsules"`` (an enclosing
            capsule per mesh or cylinder) or ``"mesh"`` (exact URDF).
        package_dirs: folders to resolve ``package://`` mesh paths (URDF files only).
        collision_from_visual: use the ``<visual>`` geometry as collision geometry (an explicit
            opt-in for arms whose URDF has no ``<collision>`` elements).
        srdf: an SRDF file whose ``<disable_collisions>`` say which link pairs never need checking; default:
            the robot's shipped SRDF if it has one, else the pairs are sampled (see
            :mod:`previewctl.robot.self_pairs`).

    Raises:
        RobotLoadError: missing or malformed file (URDF or SRDF), no movable joint, missing mesh, no collision
            geometry on the moving links (without ``collision_from_visual``).
        UnknownNameError: unknown robot, frame, joint or link name.
    """
    if geometry not in GEOMETRY_CHOICES:
        raise UnknownNameError("geometry choice", geometry, GEOMETRY_CHOICES)
    if task is not None and task not in TASK_ROWS:
        raise UnknownNameError("task", task, TASK_ROWS)
    kind = pin.GeometryType.VISUAL if collision_from_visual else pin.GeometryType.COLLISION
    found = _load_source(source, package_dirs)
    name, build = found.name, found.build
    model, collision_model, hints, locked = _reduce(name, found.model, lambda full: build(full, kind), lock)
    _require_moving_geometry(name, collision_model, collision_from_visual)
    tip_frame = tip if tip is not None else _default_tip(model, hints)
    if not model.existFrame(tip_frame):
        raise UnknownNameError("frame", tip_frame, sorted(f.name for f in model.frames))
    try:
        collision_model = prepare_geometry(collision_model, geometry)
    except RuntimeError as exc:  # Coal: e.g. a degenerate mesh with no convex hull
        raise RobotLoadError(f"robot {name!r}: its collision geometry cannot be prepared as {geometry!r}: "
                             f"{' '.join(str(exc).split())[:200]}") from exc
    planar_ok = _is_planar(model)
    chosen_task: Task = task if task is not None else ("planar" if planar_ok else "position")
    rows = TASK_ROWS["planar"] if chosen_task == "planar" else TASK_ROWS["position"]
    points = _control_points(model, tip_frame, control_points, rows)
    if not points:
        raise RobotLoadError(f"robot {name!r} has no control point: no joint origin between the base and the hand "
                             f"{tip_frame!r} moves apart from it (the avoidance index needs one); name them with "
                             f"control_points=[...] or choose another tip")
    links = select_guarded_links(model, collision_model, tip_frame, guarded_links)
    every_link = collision_model
    collision_model = keep_links(collision_model, model, links)
    robot = Robot(name, model, collision_model, tip_frame, chosen_task, points, links, (), None)
    ranks = _structural_ranks(robot)
    planar = _planar_chain(robot) if chosen_task == "planar" and planar_ok else None
    pairs = _self_pairs(found, model, every_link, geometry, locked, srdf)
    _log.info("robot %r: %d joints, task %s, tip %r, control points %s, locked %s, geometry %s", name, model.nv,
              chosen_task, tip_frame, list(points), list(locked), geometry)
    return Robot(name, model, collision_model, tip_frame, chosen_task, points, links, ranks, planar, pairs)


# --------------------------------------------------------------------------------------- loading


GeometryBuilder = Callable[[pin.Model, pin.GeometryType], pin.GeometryModel]
"""Builds the full geometry model of a kind (collision or visual) for the full kinematic model (only once the
arm has been accepted)."""


class _Found(NamedTuple):
    """A robot source resolved: its name, full kinematic model, geometry builder, URDF file (if known) and default
    SRDF (the shipped one, if any)."""

    name: str
    model: pin.Model
    build: GeometryBuilder
    urdf: Path | None = None
    srdf: Path | None = None


def _self_pairs(found: _Found, model: pin.Model, geometry: pin.GeometryModel, kind: Geometry,
                locked: tuple[str, ...], srdf: str | os.PathLike[str] | None) -> SelfPairs:
    """The self pairs of the arm: from ``srdf`` (the user's), else the shipped SRDF, else sampled."""
    chosen = Path(os.fspath(srdf)) if srdf is not None else found.srdf
    fingerprint = None
    if found.urdf is not None:
        with contextlib.suppress(OSError):
            fingerprint = found.urdf.read_text(encoding="utf-8")
    return find_self_pairs(model, geometry, kind, srdf=chosen, fingerprint=fingerprint, locked=locked,
                           shipped_srdf=srdf is None)


def load_visual(
    source: str | os.PathLike[str], package_dirs: Sequence[str | os.PathLike[str]] = ()
) -> tuple[pin.Model, pin.GeometryModel]:
    """The full (unreduced) model of ``source`` and its visual geometry (meshes with their file paths).

    ``source`` and ``package_dirs`` are as in :func:`load_robot`; the model has every joint, locked or not.
    A URDF without ``<visual>`` elements gives its collision geometry instead, so the arm can still be drawn.
    """
    _, model, build, *_ = _load_source(source, package_dirs)
    visual = build(model, pin.GeometryType.VISUAL)
    if visual.ngeoms == 0:
        visual = build(model, pin.GeometryType.COLLISION)
    return model, visual


def _load_source(source: str | os.PathLike[str], package_dirs: Sequence[str | os.PathLike[str]]) -> _Found:
    """Resolve ``source`` to its name, full kinematic model, geometry-model builder, URDF and shipped SRDF."""
    if not isinstance(source, (str, os.PathLike)):
        raise RobotLoadError(f"robot source must be a URDF path or a robot name (a string), got {source!r}")
    text = os.fspath(source)
    shipped = shipped_robots_dir() / f"{text}.urdf"
    if shipped.is_file():
        srdf = shipped.with_suffix(".srdf")
        return _Found(text, *_load_urdf(shipped, package_dirs), shipped, srdf if srdf.is_file() else None)
    path = urdf_path(text)
    if path is not None:
        if not path.is_file():
            raise RobotLoadError(f"URDF file {text!r} does not exist")
        return _Found(path.stem, *_load_urdf(path, package_dirs), path)
    example_robots = require("example_robot_data", "robots",
                             f"robot {text!r} (not a shipped robot: {', '.join(shipped_robot_names())})")
    if text not in example_robots.ROBOTS:
        raise UnknownNameError("robot", text, (*shipped_robot_names(), *example_robot_names()))
    return _load_example_robot(text)


def urdf_path(source: str | os.PathLike[str]) -> Path | None:
    """The URDF file ``source`` names, or ``None`` when it is a robot name: anything but a shipped robot's name
    that ends in ``.urdf``, holds a path separator or has a suffix is a file (which may not exist)."""
    text = os.fspath(source)
    if (shipped_robots_dir() / f"{text}.urdf").is_file():
        return None
    return Path(text) if text.endswith(".urdf") or os.sep in text or Path(text).suffix else None


def _load_example_robot(name: str) -> _Found:
    """An example-robot-data robot: straight from its URDF when its loader does nothing else (no visual
    meshes, no SRDF: 2-20x faster), else through the loader. A floating base its loader adds is left out:
    it would be locked at the identity anyway. Its SRDF, if it ships one, sits next to its URDF
    (``<package>/<srdf_subpath>/<srdf_filename>``, e.g. ``panda_description/srdf/panda.srdf``)."""
    robots_loader = require("example_robot_data.robots_loader", "robots", f"robot {name!r}")
    loader = robots_loader.ROBOTS[name]
    direct = bool(loader.urdf_filename) and "__init__" not in vars(loader)
    relative = os.path.join(loader.path, loader.urdf_subpath, loader.urdf_filename)
    root = None
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            root = Path(robots_loader.getModelPath(relative)) if loader.urdf_filename else None
    except OSError as exc:
        if direct:
            raise RobotLoadError(f"example-robot-data could not find {name!r}: {exc}") from exc
    urdf = root / relative if root is not None else None
    srdf = root / loader.path / loader.srdf_subpath / loader.srdf_filename if root and loader.srdf_filename else None
    srdf = srdf if srdf is not None and srdf.is_file() else None
    if direct and urdf is not None and root is not None:
        model, collision = _load_urdf(urdf, [root.parent.parent])
        if loader.free_flyer and model.nv == 0:
            raise RobotLoadError(f"robot {name!r} is not an arm: its only joint is a floating base (a drone or a "
                                 "mobile base)")
        return _Found(name, model, collision, urdf, srdf)
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            wrapper = robots_loader.load(name)
    except (ImportError, ValueError, RuntimeError, OSError, AssertionError) as exc:
        raise RobotLoadError(f"example-robot-data could not load {name!r}: {exc}") from exc
    return _Found(name, wrapper.model, lambda model, kind: (
        wrapper.visual_model if kind == pin.GeometryType.VISUAL else wrapper.collision_model), urdf, srdf)


def _require_moving_geometry(name: str, collision: pin.GeometryModel, from_visual: bool) -> None:
    """Refuse an arm whose moving links carry no geometry: its clearance would read 'no obstacle near'.

    Raises:
        RobotLoadError: no geometry attached to a moving joint.
    """
    if any(g.parentJoint != 0 for g in collision.geometryObjects):
        return
    if from_visual:
        raise RobotLoadError(f"robot {name!r} has neither collision nor visual geometry on its moving links")
    raise RobotLoadError(
        f"robot {name!r} has no collision geometry on its moving links (no <collision> elements), so no "
        "collision could ever be detected; add <collision> elements to the URDF, or load it with "
        "collision_from_visual=True (scenario: robot.collision_from_visual = true) to use its visual geometry"
    )


def _load_urdf(path: Path, package_dirs: Sequence[str | os.PathLike[str]]) -> tuple[pin.Model, GeometryBuilder]:
    """Parse a URDF file with clear errors for malformed XML and missing meshes."""
    root = robot_root(path, "URDF")
    dirs = [str(d) for d in package_dirs] + [str(path.parent), str(path.parent.parent)]
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename", "")
        if not mesh_exists(filename, path.parent, dirs):
            raise RobotLoadError(f"URDF file {str(path)!r}: mesh file {filename!r} not found (searched {dirs})")
    try:
        model = pin.buildModelFromUrdf(str(path))
    except (ValueError, RuntimeError) as exc:
        raise RobotLoadError(f"URDF file {str(path)!r} could not be loaded: {exc}") from exc

    def geometry(full: pin.Model, kind: pin.GeometryType) -> pin.GeometryModel:
        try:
            return pin.buildGeomFromUrdf(full, str(path), kind, package_dirs=dirs)
        except (ValueError, RuntimeError) as exc:
            raise RobotLoadError(f"URDF file {str(path)!r}: its {str(kind).split('.')[-1].lower()} geometry could "
                                 f"not be loaded: {exc}") from exc

    return model, geometry


# --------------------------------------------------------------------------------- chain and tip


def _reduce(
    name: str, model: pin.Model, collision: Callable[[pin.Model], pin.GeometryModel], lock: Sequence[str] | None
) -> tuple[pin.Model, pin.GeometryModel, HandFrames, tuple[str, ...]]:
    """The arm: the model with its floating base and ``lock`` joints (default: the end-effector joints, see
    :mod:`previewctl.robot.chain`) locked at neutral, the frames that guide the default hand, and the names of
    the locked joints.

    Raises:
        RobotLoadError: no movable joint, not a serial arm, or a model Pinocchio cannot reduce.
        UnknownNameError: a ``lock`` name that is not a joint.
    """
    if model.nv == 0:
        raise RobotLoadError(f"robot {name!r} has no movable joint")
    _distinct_frame_names(model)
    for joint_name in lock or ():
        if not model.existJointName(joint_name):
            raise UnknownNameError("joint", joint_name, model.names[1:])
    split = split_joints(name, model, lock)
    frames = hand_frames(model, split)
    geometry = collision(model)
    locked = tuple(str(model.names[int(j)]) for j in split.locked)
    if split.locked:
        try:
            model, geometry = pin.buildReducedModel(model, geometry, list(split.locked), pin.neutral(model))
        except (ValueError, RuntimeError) as exc:
            raise RobotLoadError(f"robot {name!r}: locking joints {list(split.locked)} failed: {exc}") from exc
    return model, geometry, frames, locked


def _distinct_frame_names(model: pin.Model) -> None:
    """Rename (in place) a joint frame that shares its name with a link (URDF allows it; Pinocchio's lookups
    by name do not): ``gripper`` the joint becomes ``gripper_joint``, ``gripper`` the link stays."""
    counts = Counter(str(f.name) for f in model.frames)
    for i, frame in enumerate(model.frames):
        if counts[str(frame.name)] > 1 and frame.type != pin.FrameType.BODY:
            new = f"{frame.name}_{str(frame.type.name).lower()}"
            if frame.type == pin.FrameType.JOINT:
                model.names[int(frame.parentJoint)] = new
            frame.name = new
            model.frames[i] = frame


def _default_tip(model: pin.Model, hints: HandFrames) -> str:
    """On the last joint: a tool-like frame, else the base of a locked gripper, else the frame furthest from
    the joint in the frame tree; never a frame that moved with a locked gripper joint (a jaw)."""
    last = max(range(1, model.njoints), key=lambda j: (len(model.supports[j]), j))  # the deepest joint
    candidates = [i for i, f in enumerate(model.frames) if f.parentJoint == last and f.name not in hints.excluded]

    def hops(i: int) -> int:
        # A locked joint's frame can be its own parent after buildReducedModel: stop there too.
        count = 0
        while model.frames[i].parentJoint == last and model.frames[i].type != pin.FrameType.JOINT:
            parent = int(model.frames[i].parentFrame)
            if parent == i:
                break
            i, count = parent, count + 1
        return count

    tools = [i for i in candidates if any(h in model.frames[i].name.lower() for h in _TOOL_NAME_HINTS)]
    bases = [i for i in candidates if model.frames[i].name in hints.bases]
    best = max(tools or bases or candidates, key=lambda i: (hops(i), i))
    return str(model.frames[best].name)


def _structural_ranks(robot: Robot) -> tuple[int, ...]:
    """Generic rank of each ``M_i``: the largest numerical rank over random configurations.

    Raises:
        RobotLoadError: the hand cannot move along every task direction (e.g. ``"pose"`` for a planar arm).
    """
    rng = np.random.default_rng(12345)
    result = avoidance(robot, robot.random_configurations(rng, 24), use_structural_ranks=False)
    rows = result.J_task.shape[1]

    def rank(m: int) -> int:  # generic rank of the first m task rows
        return max(int(np.linalg.matrix_rank(J[:m], tol=1e-9 * max(1.0, float(np.linalg.norm(J, 2)))))
                   for J in result.J_task)

    task_rank = rank(rows)
    if task_rank < rows:
        valid = [t for t, s in TASK_ROWS.items() if s.stop < rows and rank(s.stop) == s.stop]
        raise RobotLoadError(f"robot {robot.name!r} cannot follow task {robot.task!r}: its hand moves along only "
                             f"{task_rank} of the task's {rows} directions; valid tasks for it: {valid or 'none'}")
    return tuple(int(r) for r in result.ranks.max(axis=0))


def _control_points(
    model: pin.Model, tip_frame: str, requested: Sequence[str] | None, rows: slice
) -> tuple[str, ...]:
    """Joint names whose origins serve as control points (validated or defaulted)."""
    # the joints from the root to the tip's joint (supports[j] starts with the universe, 0)
    chain = [int(j) for j in model.supports[model.frames[model.getFrameId(tip_frame)].parentJoint]][1:]
    if requested is not None:
        for joint_name in requested:
            if not model.existJointName(joint_name):
                raise UnknownNameError("control point joint", joint_name, model.names[1:])
        return tuple(requested)
    data = model.createData()
    rng = np.random.default_rng(7)
    samples = [pin.integrate(model, pin.neutral(model), rng.uniform(-np.pi, np.pi, model.nv)) for _ in range(4)]
    samples.append(pin.neutral(model))
    tracks = []
    for q in samples:
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        tip_position = data.oMf[model.getFrameId(tip_frame)].translation
        tracks.append([np.array(data.oMi[j].translation[rows]) for j in chain] + [np.array(tip_position[rows])])
    positions = np.array(tracks)  # (S, len(chain)+1, d)
    chosen: list[str] = []
    kept: list[int] = []
    for k, j in enumerate(chain):
        moves = np.ptp(positions[:, k], axis=0).max() > 1e-9
        duplicate = any(np.allclose(positions[:, k], positions[:, i], atol=1e-9) for i in kept)
        at_tip = np.allclose(positions[:, k], positions[:, -1], atol=1e-9)
        if moves and not duplicate and not at_tip:
            chosen.append(str(model.names[j]))
            kept.append(k)
    return tuple(chosen)


def _is_planar(model: pin.Model) -> bool:
    """Every joint revolute about z, placements in one plane without tilt."""
    for j in range(1, model.njoints):
        if model.joints[j].shortname() != "JointModelRZ":
            return False
        placement = model.jointPlacements[j]
        if not np.allclose(placement.rotation, np.eye(3), atol=1e-12) or abs(placement.translation[2]) > 1e-12:
            return False
    return True


def _planar_chain(robot: Robot) -> PlanarChain | None:
    """Closed-form chain data, or ``None`` if a guarded geometry is not an in-plane capsule."""
    model = robot.model
    offsets = np.array([model.jointPlacements[j].translation[:2] for j in range(1, model.njoints)])
    tip = model.frames[robot.tip_frame_id]
    tip_pose = tip.placement
    if not np.isclose(tip_pose.translation[2], 0.0) or tip.parentJoint != model.njoints - 1:
        return None
    segments, radii, joints, link_index = [], [], [], []
    for geom in robot.collision_model.geometryObjects:
        shape = geom.geometry
        if not isinstance(shape, coal.Capsule):
            return None
        axis = geom.placement.rotation[:, 2] * shape.halfLength
        centre = geom.placement.translation
        ends = np.array([centre - axis, centre + axis])
        if not np.allclose(ends[:, 2], 0.0, atol=1e-12):
            return None
        segments.append(ends[:, :2])
        radii.append(shape.radius)
        joints.append(int(geom.parentJoint) - 1)
        link_index.append(robot.guarded_links.index(body_name(model, geom)))
    control = tuple(int(model.getJointId(n)) - 1 for n in robot.control_points)
    return PlanarChain(
        offsets=offsets,
        tip_offset=np.array(tip_pose.translation[:2]),
        control_joints=control,
        link_joints=tuple(joints),
        link_segments=np.array(segments).reshape(-1, 2, 2),
        link_radii=np.array(radii),
        link_index=tuple(link_index),
    )
