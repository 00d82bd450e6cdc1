"""pink as a baseline: its differential IK (``pink.solve_ik``), stepped by the same simulator as every controller.

`pink <https://github.com/stephane-caron/pink>`__ is what a user of Pinocchio arms would pick first: inverse
kinematics as a QP, with control-barrier functions for collisions. Each baseline here is pink used as its own
examples use it (``examples/barriers/kukas_self_collision.py``), with nothing tuned on the benchmark's scenes:

* a position-only ``FrameTask`` on the hand (``position_cost = 50``, ``orientation_cost = 0``, gain 1: the target
  is reached in one step), whose target is set at every cycle to ``r_d(t + dt)``, where the path puts the hand when
  the step ends: pink's tasks take no velocity feed-forward, and a target at ``r_d(t)`` (the examples' loop) would
  leave the hand a step behind;
* a ``PostureTask`` (``cost = 1e-3``) towards the start configuration;
* pink's default limits, configuration and velocity, on a copy of the arm's model whose speed limits are the ones
  every previewctl controller gets (``velocity_scale`` × the URDF's): pink attaches its limits to the model it is
  given, so the arm's own model is never handed to it;
* one ``SelfCollisionBarrier`` over every pair of one Pinocchio geometry model: the guarded link-obstacle pairs of
  :class:`~previewctl.scene.clearance.Clearance` (the obstacles placed where they are at the cycle's time) and the
  arm's self pairs (:mod:`previewctl.robot.self_pairs`), with ``d_min = safety_distance`` (the counterpart of the
  QP's ``d_s``; 0.02 m, pink's default, by default) and ``safe_displacement_gain = 1`` (the example's). Its rows are
  ``ḣ_k ≥ −γ h_k`` with ``h_k = d_k − d_min``: distances only, each obstacle still within a cycle (no velocity);
* DAQP through ``qpsolvers``, the solver pink's examples install and the one :mod:`previewctl.control.execution`
  uses, so cycle times compare the two formulations rather than two solvers.

The barrier gain ``γ`` has no counterpart in previewctl: each value pink's examples use is its own baseline,
:data:`BARRIER_GAINS`. A cycle where pink finds no solution (``NoSolutionFound``) commands ``q̇ = 0``, as a user's
loop would hold the arm, and is counted (:attr:`PinkExecution.no_solution`).

Adapting pink to the stepping interface: a :class:`~previewctl.control.controller.Controller` whose law asks for
nothing in the null space (:class:`PinkLaw`) and whose execution is pink (:class:`PinkExecution`). Eq. 19's
reference is still computed (the log's hand, target and error come from it) but not read by pink, so the time inside
pink's own calls is recorded apart (:meth:`PinkExecution.record`)."""

from __future__ import annotations

import time
from types import ModuleType
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.control.base import Composition, ControlState, Executed, NullInput, Reference
from previewctl.control.controller import Controller
from previewctl.control.execution import SOLVER
from previewctl.control.params import ControllerParams
from previewctl.control.tracking import task_target
from previewctl.errors import UnknownNameError
from previewctl.extras import require
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.clearance import Clearance
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Scene

BARRIER_GAINS: dict[str, float] = {"pink": 20.0, "pink-g100": 100.0}
"""The pink baselines by name, with their barrier gain ``γ`` [1/s]: 20, the ``SelfCollisionBarrier``'s in pink's
self-collision example (``examples/barriers/kukas_self_collision.py``), and 100, the gain of pink's other barrier
examples (``PositionBarrier`` in ``examples/barriers/arm_ur5.py``, ``BodySphericalBarrier`` in
``examples/barriers/yumi_self_collision.py``)."""
POSITION_COST = 50.0
"""The hand ``FrameTask``'s position cost [cost/m], as in pink's self-collision example."""
POSTURE_COST = 1e-3
"""The ``PostureTask``'s cost [cost/rad], as in every pink example."""
SAFE_DISPLACEMENT_GAIN = 1.0
"""The barrier's safe-displacement gain [-], as in pink's self-collision example."""
EXECUTION = "qp"
"""The execution mode a pink run is recorded under in a sweep: pink is a constrained QP, set beside ``qp``."""


def pink_module() -> ModuleType:
    """The ``pink`` package (``pin-pink`` on PyPI), from the ``bench`` extra.

    Raises:
        MissingExtraError: pink is not installed; one line naming the extra.
    """
    return require("pink", "bench", "the pink baseline")


def barrier_gain(name: str) -> float:
    """The barrier gain ``γ`` [1/s] of the pink baseline ``name``.

    Raises:
        UnknownNameError: not a name of :data:`BARRIER_GAINS` (they are listed).
    """
    if name not in BARRIER_GAINS:
        raise UnknownNameError("pink baseline", name, BARRIER_GAINS)
    return BARRIER_GAINS[name]


def barrier_geometry(robot: Robot, scene: Scene) -> tuple[pin.GeometryModel, list[int]]:
    """One geometry model holding the guarded link-obstacle pairs and the arm's self pairs, for pink's barrier; and
    the geometry ids of the scene's obstacles, in scene order (placed at ``t = 0``)."""
    geometry = Clearance(robot, scene).geometry.copy()
    obstacles = [int(geometry.getGeometryId(f"obstacle:{o.name}")) for o in scene.obstacles]
    own = robot.self_pairs.geometry
    offset = len(geometry.geometryObjects)
    for item in own.geometryObjects:
        copied = item.copy()
        copied.name = f"self:{item.name}"  # the guarded links' geometry is in the model once already
        geometry.addGeometryObject(copied)
    for pair in own.collisionPairs:
        geometry.addCollisionPair(pin.CollisionPair(pair.first + offset, pair.second + offset))
    return geometry, obstacles


class PinkLaw:
    """The law of a pink baseline: nothing in eq. 19's null space (pink solves the whole motion itself).

    Args:
        name: the baseline's name (:data:`BARRIER_GAINS`).
        nv: the arm's velocity dimension.
    """

    def __init__(self, name: str, nv: int) -> None:
        self.name = name
        self._zero = np.zeros(nv)

    def null_input(self, state: ControlState) -> NullInput:
        """``v = 0``."""
        return NullInput(self._zero.copy())


class PinkExecution:
    """One ``pink.solve_ik`` per cycle (module docstring): the hand at ``r_d(t + dt)``, a posture, pink's limits and
    its barrier over the guarded and self pairs, obstacles placed at ``t``.

    Args:
        robot: the arm (its collision geometry and self pairs).
        scene: the obstacles.
        params: ``velocity_scale`` (the speed limits) and ``safety_distance`` (the barrier's ``d_min``) [m].
        gain: the barrier gain ``γ`` [1/s].

    Raises:
        MissingExtraError: pink is not installed.

    Attributes:
        no_solution: the cycles where pink found no solution and ``q̇ = 0`` was commanded.
        times: the time [s] of each call (placing the obstacles, pink's kinematics and distances, ``solve_ik``):
            pink's own share of each control cycle.
    """

    name = "pink"

    def __init__(self, robot: Robot, scene: Scene, params: ControllerParams, gain: float) -> None:
        pink = pink_module()
        from pink.barriers import SelfCollisionBarrier
        from pink.tasks import FrameTask, PostureTask

        self._solve_ik, self._no_solution_error = pink.solve_ik, pink.exceptions.NoSolutionFound
        self.robot, self.scene = robot, scene
        model = robot.model.copy()  # pink attaches its limits to the model it is given
        model.velocityLimit = params.velocity_scale * model.velocityLimit
        self.geometry, self._obstacles = barrier_geometry(robot, scene)
        self.configuration = pink.Configuration(model, model.createData(), robot.neutral(),
                                                collision_model=self.geometry)
        self.hand = FrameTask(robot.tip_frame, position_cost=POSITION_COST, orientation_cost=0.0)
        self.posture = PostureTask(cost=POSTURE_COST)
        self.barrier = SelfCollisionBarrier(n_collision_pairs=len(self.geometry.collisionPairs), gain=gain,
                                            safe_displacement_gain=SAFE_DISPLACEMENT_GAIN,
                                            d_min=params.safety_distance)
        self.no_solution = 0
        self.times: list[float] = []
        self._started = False

    def place_obstacles(self, t: float) -> None:
        """Move the obstacles of the barrier's geometry to where they are at time ``t`` [s]."""
        for obstacle, gid in zip(self.scene.obstacles, self._obstacles, strict=True):
            if not isinstance(obstacle.motion, Static):
                self.geometry.geometryObjects[gid].placement = obstacle.placement(t)

    def __call__(self, state: ControlState, reference: Reference) -> Executed:
        """pink's ``q̇`` [rad/s] for ``state`` (eq. 19's ``reference`` is not read)."""
        start = time.perf_counter()
        self.place_obstacles(state.t)
        self.configuration.update(state.q)
        if not self._started:  # the posture is the start configuration, as in pink's examples
            self.posture.set_target_from_configuration(self.configuration)
            self._started = True
        desired, _ = task_target(self.robot, state.path, state.t + state.dt)
        self.hand.set_target(pin.SE3(np.eye(3), desired))
        try:
            qdot = self._solve_ik(self.configuration, [self.hand, self.posture], state.dt, solver=SOLVER,
                                  barriers=[self.barrier], safety_break=False)
        except self._no_solution_error:
            self.no_solution += 1
            qdot = np.zeros(self.robot.nv)
        self.times.append(time.perf_counter() - start)
        return Executed(qdot, qdot, 1.0, 1.0, False, state.dt, self.name, dampers=len(self.geometry.collisionPairs))


    def record(self) -> dict[str, Any]:
        """What a benchmark's result line adds for a pink run: ``pink_no_solution`` (cycles) and the median and p95
        of :attr:`times`, ``pink_time_median`` and ``pink_time_p95`` [s]."""
        times = np.asarray(self.times) if self.times else np.zeros(1)
        return {"pink_no_solution": self.no_solution, "pink_time_median": float(np.median(times)),
                "pink_time_p95": float(np.percentile(times, 95))}


def make_pink_controller(name: str, robot: Robot, path: HandPath, scene: Scene, params: ControllerParams,
                         dt: float) -> Controller:
    """The pink baseline ``name`` (:data:`BARRIER_GAINS`) as a controller any loop steps, ``ctrl.step(q, t)``.

    Args:
        name: the baseline.
        robot: the arm.
        path: the hand path.
        scene: the obstacles.
        params: the scenario's settings (``velocity_scale``, ``safety_distance``; eq. 19's for the log).
        dt: control period [s].

    Raises:
        UnknownNameError: ``name`` is not a pink baseline.
        MissingExtraError: pink is not installed.
    """
    gain = barrier_gain(name)
    execution = PinkExecution(robot, scene, params, gain)
    composition = Composition(controller=name, law=f"pink.solve_ik (barrier gain {gain:g} 1/s)",
                              execution=execution.name)
    return Controller(PinkLaw(name, robot.nv), execution, robot, path, params, composition, dt=dt)
