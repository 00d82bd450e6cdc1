"""Seeded benchmark scenes: a hand path within reach and obstacles that cross the intermediate links mid-run.

:func:`generate` draws scene ``index`` of a robot from ``np.random.default_rng((crc32(label), index, seed))``
(the robot's name, or a URDF file's stem and content hash: :func:`~previewctl.bench.robots.robot_label`):

1. ``q0`` uniformly in a box around the robot's nominal pose (its :class:`~previewctl.bench.profiles.Profile`,
   hand-written or derived from the arm), the hand there;
2. a hand path of straight segments from that hand, every sample inside the profile's workspace;
3. the arm's motion under plain tracking (controller ``none``, no obstacle) up to each crossing time
   ``t_c``, drawn in the middle of the run; there a point on the polyline of the joint origins (the
   intermediate links, never the hand's link) is chosen, and an obstacle (a disc for a planar arm, a
   ball otherwise) is sent through it at ``t_c`` at constant velocity, across the link (or, with
   ``motions = "surprise"``, on its way there it turns, stops, changes speed or wanders:
   :mod:`previewctl.bench.surprises`). The first obstacle crosses at ``0.35-0.65`` of the run; with
   probability 1/2 a second one crosses elsewhere.
   Each obstacle is redrawn until it starts :data:`START_CLEARANCE` clear of the arm at ``q0``;
4. the document goes through :func:`~previewctl.sim.scenario.scenario_from_dict` (the scenario files'
   validation path) and the solvability witness (:mod:`previewctl.bench.witness`); a draw it rejects
   is counted and the next draw taken.

The same ``(robot, index, seed, settings)`` always gives the same scene.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.bench.profiles import Profile
from previewctl.bench.robots import bench_source, cached_robot, profile, robot_label
from previewctl.bench.settings import SceneSettings
from previewctl.bench.surprises import surprise
from previewctl.bench.witness import witness
from previewctl.control.factory import make_controller
from previewctl.errors import ParameterError, ScenarioError
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import integrate
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.file import scene_from_dict
from previewctl.scene.shapes import Scene
from previewctl.sim.scenario import Scenario, scenario_from_dict
from previewctl.types import Array

GEOMETRY_DRAWS = 1000
"""Most draws of ``q0`` and path, or of an obstacle, per scene draw before giving up."""
START_CLEARANCE = 0.05
"""Least distance [m] between an obstacle and the guarded links at ``t = 0`` (a scene starts in the clear)."""


@dataclass(frozen=True, eq=False)
class BenchScene:
    """A generated scene.

    Attributes:
        robot: robot name.
        index: scene index.
        seed: the sweep's scene seed.
        document: the scenario document (plain JSON values; :meth:`scenario` builds it).
        rejected: draws the witness rejected before this one.
        witness: what the witness found, one sentence.
        oracle_run: the witness's ``oracle`` run (planar arms; see
            :class:`~previewctl.bench.witness.Witnessed`), which the sweep records instead of running it again.
        oracle_plan: the plan that run followed, which the scene's other ``oracle`` runs follow too.
        history: how long [s] before ``t = 0`` its obstacles already move and an observed run's sensor observes
            (:attr:`SceneSettings.history <previewctl.bench.settings.SceneSettings.history>`).
    """

    robot: str
    index: int
    seed: int
    document: dict[str, Any]
    rejected: int
    witness: str
    oracle_run: dict[str, Any] | None = None
    oracle_plan: dict[str, Any] | None = None
    history: float = 0.0

    def scenario(self) -> Scenario:
        """The scenario, through the scenario files' validation."""
        return scenario_from_dict(self.document, source=self.document["name"])

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> BenchScene:
        """The scene of a line of ``scenes.jsonl`` (its other keys ignored; a line from before ``oracle_run``
        was recorded has none)."""
        return cls(**{f.name: record[f.name] for f in dataclasses.fields(cls) if f.name in record})


def generate(robot: str, index: int, seed: int = 0, settings: SceneSettings | None = None) -> BenchScene:
    """Scene ``index`` of ``robot`` (a name or a URDF file, :mod:`previewctl.bench.robots`) for scene seed ``seed``:
    the first draw the witness accepts.

    Raises:
        UnknownNameError: an unknown robot.
        RobotLoadError: a robot that does not load as an arm.
        ParameterError: a negative index or seed, or an arm no profile can be derived for.
        ScenarioError: no draw accepted within ``settings.max_draws``.
    """
    robot = bench_source(robot)
    prof = profile(robot)
    for name, value in (("scene index", index), ("scene seed", seed)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ParameterError(f"{name} must be an integer >= 0, got {value!r}")
    settings = settings or SceneSettings()
    label = robot_label(robot)
    rng = np.random.default_rng((zlib.crc32(label.encode()), index, seed))
    arm = cached_robot(robot)
    for draw in range(settings.max_draws):
        document = draw_document(arm, robot, prof, rng, settings, name=f"{label}_{index:03d}_s{seed}")
        scenario = scenario_from_dict(document, source=document["name"])
        found = witness(scenario, settings)
        if found.holds:
            return BenchScene(robot, index, seed, document, draw, found.sentence, found.oracle_run,
                              found.oracle_plan, settings.history)
    raise ScenarioError(f"{label} scene {index} (seed {seed}): the witness rejected all {settings.max_draws} draws")


def draw_document(arm: Robot, robot: str, prof: Profile, rng: np.random.Generator, settings: SceneSettings,
                  name: str) -> dict[str, Any]:
    """One draw: the scenario document of ``q0``, the path and the crossing obstacles."""
    duration = settings.duration if settings.duration is not None else prof.duration
    q0, waypoints = _draw_start_and_path(arm, prof, rng)
    path = HandPath(waypoints, duration)
    crossings = [rng.uniform(0.35, 0.65)] + ([rng.uniform(0.2, 0.8)] if rng.random() < 0.5 else [])
    states = _nominal_states(arm, path, q0, [c * duration for c in crossings], settings.dt)
    obstacles = [_clear_crossing(arm, prof, rng, q0, q, c * duration, f"obstacle{i + 1}", settings)
                 for i, (c, q) in enumerate(zip(crossings, states, strict=True))]
    return {
        "name": name,
        "description": f"bench scene: {robot_label(robot)}, {len(waypoints) - 1}-segment hand path in {duration:g} s, "
                       f"{len(obstacles)} crossing obstacle(s)"
                       + ("" if settings.motions == "constant" else f" ({settings.motions})"),
        "robot": {"source": robot, "q0": [float(v) for v in q0]},
        "path": {"waypoints": [[float(v) for v in p] for p in waypoints], "duration": duration},
        "obstacles": obstacles,
        "controller": dict(prof.controller),
        "timing": {"dt": settings.dt, "duration": duration},
        "output": {"gif": False},
    }


def _hand(arm: Robot, q: Array) -> Array:
    """The hand position [m] (2 entries for a planar arm)."""
    data = arm.model.createData()
    pin.framesForwardKinematics(arm.model, data, q)
    hand = np.array(data.oMf[arm.tip_frame_id].translation)
    return hand[:2] if arm.task == "planar" else hand


def _in_workspace(prof: Profile, points: Array) -> bool:
    """Every point within the profile's reach (and height)."""
    radial = np.linalg.norm(points[:, :2], axis=1)
    ok = bool(np.all((radial >= prof.reach[0]) & (radial <= prof.reach[1])))
    if prof.height is not None:
        ok &= bool(np.all((points[:, 2] >= prof.height[0]) & (points[:, 2] <= prof.height[1])))
    return ok


def _draw_start_and_path(arm: Robot, prof: Profile, rng: np.random.Generator) -> tuple[Array, Array]:
    """``q0`` [rad] and the path waypoints [m], every path sample within the workspace."""
    center, spread = np.array(prof.q0_center), np.array(prof.q0_spread)
    lo, hi = np.maximum(center - spread, arm.joints.lower), np.minimum(center + spread, arm.joints.upper)
    for _ in range(GEOMETRY_DRAWS):
        q0 = arm.configurations_from_angles(rng.uniform(lo, hi)[None, :])[0]
        points = [_hand(arm, q0)]
        for _ in range(prof.segments):
            angle = rng.uniform(-math.pi, math.pi)
            direction = np.array([math.cos(angle), math.sin(angle)])
            if prof.height is not None:
                direction = np.append(direction, rng.uniform(-0.3, 0.3))
            points.append(points[-1] + rng.uniform(*prof.segment_length) * direction / np.linalg.norm(direction))
        waypoints = np.array(points)
        samples = np.concatenate([np.linspace(a, b, 20) for a, b in itertools.pairwise(waypoints)])
        if _in_workspace(prof, samples):
            return q0, waypoints
    raise ScenarioError(f"no start and path within the workspace of {arm.name!r} in {GEOMETRY_DRAWS} draws")


def _nominal_states(arm: Robot, path: HandPath, q0: Array, times: list[float], dt: float) -> list[Array]:
    """The arm's configurations at ``times`` [s] under plain tracking (``none``) with no obstacle."""
    ctrl = make_controller("none", robot=arm, path=path, scene=Scene(()), dt=dt)
    q, states = np.array(q0, dtype=float), {}
    last = max(times)
    for k in range(math.ceil(last / dt) + 1):
        t = k * dt
        for c in times:
            if c not in states and t >= c:
                states[c] = q.copy()
        if len(states) == len(times):
            break
        q = integrate(arm, q, ctrl.step(q, t, dt), dt)
    return [states.get(c, q) for c in times]


def _clear_crossing(arm: Robot, prof: Profile, rng: np.random.Generator, q0: Array, q: Array, t_c: float,
                    name: str, settings: SceneSettings) -> dict[str, Any]:
    """A :func:`_crossing` obstacle that starts at least :data:`START_CLEARANCE` away from the arm at ``q0``."""
    for _ in range(GEOMETRY_DRAWS):
        table = _crossing(arm, prof, rng, q, t_c, name, settings)
        if Evaluator(arm, scene_from_dict([table]))(q0[None, :], 0.0).min_distance[0] > START_CLEARANCE:
            return table
    raise ScenarioError(f"no obstacle crossing {arm.name!r} at t = {t_c:.3g} s starts clear of q0 in "
                        f"{GEOMETRY_DRAWS} draws (a longer duration gives it room)")


def _crossing(arm: Robot, prof: Profile, rng: np.random.Generator, q: Array, t_c: float, name: str,
              settings: SceneSettings) -> dict[str, Any]:
    """An obstacle table that passes a point of the intermediate links (arm at ``q``) at time ``t_c`` [s], or
    surprises on its way there (``settings.motions``)."""
    data = arm.model.createData()
    pin.forwardKinematics(arm.model, data, q)
    joints = np.array([data.oMi[j].translation for j in range(1, arm.model.njoints)])
    segments = np.diff(joints, axis=0)
    lengths = np.linalg.norm(segments, axis=1)
    s = rng.uniform(0.3, 0.9) * lengths.sum()
    i = int(np.searchsorted(np.cumsum(lengths), s))
    i = min(i, len(lengths) - 1)
    along = segments[i] / lengths[i]
    point = joints[i] + along * (s - (np.cumsum(lengths)[i] - lengths[i]))
    speed, radius = rng.uniform(*prof.speed), rng.uniform(*prof.radius)
    if arm.task == "planar":
        normal = np.array([-along[1], along[0], 0.0])
        angle = rng.uniform(-math.pi / 6, math.pi / 6) + (math.pi if rng.random() < 0.5 else 0.0)
        velocity = speed * (math.cos(angle) * normal + math.sin(angle) * along)
        shape: dict[str, Any] = {"shape": "cylinder", "radius": radius, "length": 0.4}
        point[2], velocity[2] = 0.0, 0.0
    else:
        across = rng.normal(size=3)
        across -= across.dot(along) * along
        velocity = speed * across / np.linalg.norm(across)
        shape = {"shape": "sphere", "radius": radius}
    start = point - velocity * t_c
    dims = 2 if arm.task == "planar" else 3
    if settings.motions == "surprise":
        duration = settings.duration if settings.duration is not None else prof.duration
        return {"name": name, **shape, "motion": surprise(rng, start, velocity, point, t_c, radius, duration, dims)}
    moving = {"start_time": -settings.history} if settings.history else {}  # already moving: the same from t = 0 on
    return {"name": name, **shape, "motion": {"type": "constant_velocity", "position": [float(v) for v in start[:dims]],
                                              "velocity": [float(v) for v in velocity[:dims]], **moving}}
