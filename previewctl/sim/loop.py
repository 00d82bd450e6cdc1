"""Closed-loop kinematic simulation of a scenario.

Before the first step, a start ``q0`` in collision is refused as bad input
(:func:`~previewctl.sim.start.check_start`: nothing runs, nothing is logged). The loop, with control period ``dt``,
at each tick ``t_k`` of its clock (:mod:`previewctl.sim.clock`: ``t_k = k dt`` in simulated time, the default; the
wall time since the start with ``rate``, real time):

1. ``q ← q ⊕ q̇ (t_k − t_{k−1})``, the previous command applied for the time elapsed
   (:func:`~previewctl.kinematics.integrate`);
2. the state is checked exactly: AMSIP, per-link clearance and collision, the smallest distance
   between the arm's self pairs and self-collision, from an :class:`~previewctl.index.evaluator.Evaluator` on the
   robot loaded with ``geometry="mesh"`` (the exact URDF geometry, and its own self pairs; for planar4 the same
   cylinders, and no self pairs);
3. a collision, with an obstacle or with itself, stops the run there (unless ``stop_on_collision=False``); the
   colliding step is the last row of the log, with ``q̇ = 0``;
4. with a ``[sensing]`` table, the observations due by ``t_k`` are delivered (``controller.observe``, the sensor of
   :mod:`previewctl.sim.sensor`); then the control cycle, ``q̇ = controller.step(q, t_k, dt)``, is timed with
   ``time.perf_counter`` (``cycle_time``), and so is the whole cycle from its deadline: the clock's wake-up
   latency, steps 1-4 and the logging (``loop_time``: longer than ``dt``, the cycle missed the next deadline);
   the controller runs a GA generation when ``t_k`` enters a new camera frame
   (:class:`~previewctl.control.controller.Controller`).

The last row is the state at ``duration`` (its command is computed and logged but not applied).
The simulator is one user of :meth:`Controller.step <previewctl.control.controller.Controller.step>`:
your own loop gets the same numbers from the same calls.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from previewctl.control.background import real_time_loop
from previewctl.control.base import ControlInfo
from previewctl.control.controller import Controller, frame_index
from previewctl.control.factory import BACKGROUND_CONTROLLERS, make_controller
from previewctl.control.tracking import effective_velocity_limits, task_target
from previewctl.errors import ParameterError, PreviewctlError
from previewctl.index.evaluator import Evaluation, Evaluator
from previewctl.kinematics import integrate
from previewctl.robot.model import Robot
from previewctl.sim.clock import Tick, simulated_ticks, wall_ticks
from previewctl.sim.log import RunResult, grant_record
from previewctl.sim.scenario import Scenario, Verdict
from previewctl.sim.sensor import Sensor
from previewctl.sim.start import check_start
from previewctl.sim.start import exact_evaluator as exact_evaluator_of
from previewctl.types import Array, IntArray
from previewctl.validation import real_scalar

_log = logging.getLogger(__name__)

__all__ = ["Progress", "frame_index", "simulate"]  # frame_index lives in control.controller now

Progress = Callable[[float, float], None]
"""``progress(fraction, t)``: fraction of the run done in [0, 1] and simulated time [s]."""


def simulate(
    scenario: Scenario,
    controller_name: str | None = None,
    *,
    progress: Progress | None = None,
    stop_on_collision: bool = True,
    seed: int | None = None,
    controller: Controller | None = None,
    exact_evaluator: Evaluator | None = None,
    tolerance: float | None = None,
    rate: float | None = None,
) -> RunResult:
    """Run a scenario in closed loop.

    Args:
        scenario: what to run.
        controller_name: override of the scenario's controller (one of
            :data:`~previewctl.control.params.CONTROLLER_NAMES`); its parameters stay those of the scenario.
        progress: called as ``progress(fraction, t)`` after every step.
        stop_on_collision: stop at the first exact collision, with an obstacle or with itself (default), or log it
            and go on.
        seed: random seed of the controller (default: the scenario's).
        controller: a ready-made, fresh controller (overrides ``controller_name`` and ``seed``; for
            tests and experiments), e.g. from :func:`~previewctl.control.factory.make_controller`.
            A controller keeps its searches and frame clock between steps: do not reuse one.
        exact_evaluator: the evaluator of the exact check (default: one on the robot reloaded with
            ``geometry="mesh"``, :func:`~previewctl.sim.start.exact_evaluator`; pass one to share the mesh
            loading between runs).
        tolerance: largest hand error [m] of a successful run (default: the scenario's ``[verdict]``).
        rate: run in real time at this loop rate [Hz] (the control period is ``1 / rate``, the scenario's ``dt``
            is not used): the arm advances in wall-clock time (:func:`~previewctl.sim.clock.wall_ticks`), and the
            controller made here plans in the background if it can (``single``, ``multi``, ``reach``, ``horizon``,
            ``oracle``; the others have nothing to plan and run inline); it is closed when the run ends, also on
            Ctrl-C. The clock starts once the controller has stepped at the start state (its first step loads the
            compiled kernels) and its planning worker, if any, has answered it (a robot holds still until its
            planner is ready), or failed. The loop runs on the core the workers leave free, in the
            real-time class and with the cores kept awake if the OS grants them
            (:func:`~previewctl.control.background.real_time_loop`; a warning is logged for each refusal, and the log
            records both answers), until the run ends; over the last half of each period the loop rehearses the step
            instead of sleeping, to start each cycle with warm caches
            (:meth:`~previewctl.control.controller.Controller.rehearse`, :func:`~previewctl.sim.clock.wait_until`).
            Default: simulated time, the scenario's ``dt``, inline planning (deterministic).

    Returns:
        The log.

    Raises:
        StartCollisionError: ``scenario.q0`` collides at ``t = 0`` on the exact check
            (:func:`~previewctl.sim.start.check_start`), before anything runs.
        PreviewctlError: unknown controller name, an exact evaluator for another robot, a tolerance or a rate
            that is not a positive number, ...
    """
    verdict = scenario.verdict if tolerance is None else Verdict(tolerance)
    if exact_evaluator is None:
        exact_evaluator = exact_evaluator_of(scenario)
    if exact_evaluator.robot.nq != scenario.robot.nq:
        raise PreviewctlError(
            f"exact evaluator robot has nq={exact_evaluator.robot.nq}, the scenario robot nq={scenario.robot.nq}"
        )
    check_start(scenario, exact_evaluator)  # a start in collision is bad input, refused before the first step
    dt, steps = scenario.timing.dt, scenario.timing.steps
    if rate is not None:
        dt = 1.0 / positive_rate(rate)
        steps = max(1, round(scenario.timing.duration / dt))
    owned = controller is None
    if controller is None:
        name = controller_name or scenario.controller.name
        planning = "background" if rate is not None and name in BACKGROUND_CONTROLLERS else "inline"
        controller = make_controller(scenario, name=name, seed=seed, dt=dt, planning=planning)
    robot, links = scenario.robot, exact_evaluator.robot.guarded_links
    log = _Log(steps + 1, dt, robot, links, exact_evaluator.robot.self_pairs.pair_links)
    sensor = None if scenario.sensing is None else Sensor(scenario.scene, scenario.sensing, steps * dt,
                                                          robot.task == "planar")
    try:
        if rate is not None:
            _get_ready(controller, scenario.q0, dt)
        ticks = simulated_ticks(dt, steps) if rate is None else wall_ticks(dt, steps, controller.rehearse)
        with contextlib.nullcontext(None) if rate is None else real_time_loop() as granted:
            for refusal in () if granted is None else granted.refusals:
                _log.warning(refusal)
            count = _run(scenario, controller, exact_evaluator, log, ticks, progress, stop_on_collision, sensor)
    finally:
        if owned:  # ends a background worker, also on Ctrl-C
            controller.close()
    _log.info("run %r with %s: %d of %d steps", scenario.name, controller.name, count, steps)
    return RunResult(
        scenario=scenario.name,
        controller=controller.name,
        robot=robot.name,
        dt=dt,
        joint_names=robot.joint_names,
        link_names=links,
        tolerance=verdict.tolerance,
        velocity_limits=effective_velocity_limits(robot, controller.params.velocity_scale),
        execution=controller.execution.name,
        composition=str(controller.describe()),
        self_pairs=exact_evaluator.robot.self_pairs.links,
        observations_dropped=0 if sensor is None else sensor.dropped_by(float(log.columns["t"][count - 1])),
        real_time_class=grant_record(None if granted is None else granted.fifo),
        cores_awake=grant_record(None if granted is None else granted.awake),
        **log.arrays(count),
    )


def _get_ready(controller: Controller, q0: Array, dt: float) -> None:
    """Before a real-time run, as a robot holds still until its controller is ready: step ``controller`` at the start
    (``q0``, ``t = 0``, not logged) once, and with background planning every ``dt`` [s] until its worker's first
    result arrives or the worker fails (its start counts against its timeout). The first step loads the compiled
    kernels and, inline, runs the first search and plan; no cycle on the clock should pay for them (the ROS node
    does the same)."""
    start = time.perf_counter()
    controller.step(q0, 0.0, dt)
    while controller.planning is not None and controller.last_info.plan_age is None \
            and controller.last_info.worker_error is None:
        time.sleep(dt)
        controller.step(q0, 0.0, dt)
    _log.info("controller ready after %.2f s", time.perf_counter() - start)


def positive_rate(rate: object) -> float:
    """``rate`` as a finite loop rate > 0 [Hz]; :class:`ParameterError` naming it otherwise."""
    value = real_scalar(rate, "rate", ParameterError)
    if value <= 0.0:
        raise ParameterError(f"rate must be a loop rate > 0 [Hz], got {value!r}")
    return value


def _run(
    scenario: Scenario,
    controller: Controller,
    exact: Evaluator,
    log: _Log,
    ticks: Iterable[Tick],
    progress: Progress | None,
    stop_on_collision: bool,
    sensor: Sensor | None,
) -> int:
    """Step the loop over the clock's ``ticks``, filling ``log``, the ``sensor``'s observations (if any) delivered
    before each step; the number of rows logged."""
    dt, steps = log.period, log.rows - 1
    q = np.array(scenario.q0, dtype=float)
    qdot: Array | None = None
    for row, (k, t, elapsed, late) in enumerate(ticks):
        start = time.perf_counter() - late  # the cycle's deadline
        if qdot is not None:
            q = integrate(scenario.robot, q, qdot, elapsed)
        check = exact(q[None, :], t)
        log.record_check(row, t, q, check)
        if (check.collision[0] or check.self_collision[0]) and stop_on_collision:
            _record_collision(log, row, t, scenario, controller, check)
            if progress is not None:
                progress(1.0, t)
            return row + 1
        if sensor is not None:
            log.columns["observations"][row] = sensor.deliver(controller, t)
        step_start = time.perf_counter()
        qdot = controller.step(q, t, dt)
        log.columns["cycle_time"][row] = time.perf_counter() - step_start
        log.record_command(row, controller.last_info, qdot)
        log.columns["loop_time"][row] = time.perf_counter() - start
        if progress is not None:
            progress(k / steps, t)
    return row + 1


def _record_collision(
    log: _Log, k: int, t: float, scenario: Scenario, controller: Controller, check: Evaluation
) -> None:
    """The colliding last row: the hand and its target, no command (``q̇ = 0``)."""
    desired, _ = task_target(scenario.robot, scenario.path, t)
    log.record_hand(k, check.tip_position[0].copy(), desired)
    log.columns["frame_due"][k] = controller.frame_due(t)


class _Log:
    """The log of a run being simulated: one row per step, allocated for the whole run.

    Args:
        rows: the number of rows (steps + 1; a real-time run may log fewer).
        period: the control period [s].
        robot: the arm (its ``nq``, ``nv`` and task).
        links: the guarded links of the exact check.
        pair_links: for each self pair (geometry pair) of the exact check, its link pair's index.
    """

    def __init__(self, rows: int, period: float, robot: Robot, links: tuple[str, ...], pair_links: IntArray) -> None:
        nq, nv = robot.nq, robot.nv
        self.rows, self.period, self.nq = rows, period, nq
        self.pair_links = pair_links
        self.position_rows = 2 if robot.task == "planar" else 3
        self.columns: dict[str, Any] = {
            "t": np.zeros(rows),
            "q": np.zeros((rows, nq)),
            "qdot": np.zeros((rows, nv)),
            "qdot_requested": np.zeros((rows, nv)),
            "hand": np.zeros((rows, 3)),
            "desired": np.zeros((rows, 3)),
            "hand_error": np.zeros(rows),
            "S": np.zeros(rows),
            "amsi": np.zeros(rows),
            "link_distances": np.zeros((rows, len(links))),
            "min_distance": np.zeros(rows),
            "collision": np.zeros(rows, dtype=bool),
            "cycle_time": np.zeros(rows),
            "loop_time": np.zeros(rows),
            "plan_age": np.full(rows, np.nan),
            "fallback": np.zeros(rows, dtype=bool),
            "frame_due": np.zeros(rows, dtype=bool),
            "velocity_scale": np.ones(rows),
            "slack": np.zeros(rows),
            "self_distance": np.full(rows, np.inf),
            "self_collision": np.zeros(rows, dtype=bool),
            "self_pair": np.full(rows, -1, dtype=np.int64),
            "observations": np.zeros(rows, dtype=np.int64),
        }
        self.targets: Array | None = None  # (rows, p, nq) once the controller reports its imaginary arms
        self.target_S: Array | None = None

    def record_check(self, k: int, t: float, q: Array, check: Evaluation) -> None:
        """Row ``k``: the time, the configuration and its exact check."""
        c = self.columns
        c["t"][k], c["q"][k] = t, q
        c["S"][k], c["amsi"][k] = check.S[0], check.amsi[0]
        c["link_distances"][k], c["min_distance"][k] = check.link_distances[0], check.min_distance[0]
        c["collision"][k] = check.collision[0]
        pair = int(check.self_pair[0])
        c["self_distance"][k], c["self_collision"][k] = check.self_distance[0], check.self_collision[0]
        c["self_pair"][k] = self.pair_links[pair] if pair >= 0 else -1

    def record_hand(self, k: int, hand: Array, desired: Array) -> None:
        """Row ``k``: the hand, its target and the error over the task's position rows."""
        c = self.columns
        c["hand"][k], c["desired"][k] = hand, desired
        c["hand_error"][k] = np.linalg.norm((desired - hand)[: self.position_rows])

    def record_command(self, k: int, info: ControlInfo, qdot: Array) -> None:
        """Row ``k``: what the controller computed."""
        c = self.columns
        ref, executed = info.reference, info.executed
        self.record_hand(k, ref.hand_position, ref.desired_position)
        c["qdot"][k], c["qdot_requested"][k] = qdot, executed.requested
        c["velocity_scale"][k], c["frame_due"][k], c["slack"][k] = executed.scale, info.frame_due, executed.slack
        c["plan_age"][k] = np.nan if info.plan_age is None else info.plan_age
        c["fallback"][k] = info.fallback
        if info.targets is not None and info.target_amsip is not None:
            if self.targets is None or self.target_S is None:
                p = info.targets.shape[0]
                self.targets, self.target_S = np.full((self.rows, p, self.nq), np.nan), np.full((self.rows, p), np.nan)
            self.targets[k], self.target_S[k] = info.targets, info.target_amsip

    def arrays(self, count: int) -> dict[str, Any]:
        """The first ``count`` rows of every column (``p = 0`` imaginary arms if none was reported)."""
        targets, target_S = self.targets, self.target_S
        if targets is None or target_S is None:
            targets, target_S = np.zeros((self.rows, 0, self.nq)), np.zeros((self.rows, 0))
        columns = {**self.columns, "targets": targets, "target_S": target_S}
        return {name: value[:count] for name, value in columns.items()}
