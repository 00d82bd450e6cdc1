"""Closed-loop kinematic simulation of a scenario, its log, and atomic saving/loading of runs.

The loop, with control period ``dt`` and camera frame period ``T_f`` (33 ms by default):

1. at ``t_k = k dt`` the state is checked exactly: AMSIP, per-link clearance and collision from an
   :class:`~previewctl.index.evaluator.Evaluator` on the robot loaded with ``geometry="mesh"`` (the exact URDF
   geometry; for planar4 the same cylinders);
2. a collision stops the run there (unless ``stop_on_collision=False``); the colliding step is the
   last row of the log, with ``q̇ = 0``;
3. the control cycle -- kinematics of ``q`` and the controller's ``command`` -- is timed with
   ``time.perf_counter``; ``frame_due`` is true when ``t_k`` enters a new camera frame
   (``floor(t_k / T_f)`` changes; true at ``k = 0``);
4. ``q ← pin.integrate(model, q, q̇ dt)``.

The last row is the state at ``duration`` (its command is computed and logged but not applied).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.control.base import ControlInfo, Controller, ControlState
from previewctl.control.factory import make_controller
from previewctl.control.params import ControllerSpec
from previewctl.control.tracking import effective_velocity_limits, task_target
from previewctl.errors import PreviewctlError
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import kinematics, kinematics_reader
from previewctl.sim.log import RunResult
from previewctl.sim.scenario import Scenario
from previewctl.types import Array

Progress = Callable[[float, float], None]
"""``progress(fraction, t)``: fraction of the run done in [0, 1] and simulated time [s]."""


def frame_index(t: float, frame: float) -> int:
    """Camera frame number of time ``t`` [s] for frame period ``frame`` [s] (robust to rounding)."""
    return math.floor(t / frame + 1e-9)


def simulate(
    scenario: Scenario,
    controller_name: str | None = None,
    *,
    progress: Progress | None = None,
    stop_on_collision: bool = True,
    seed: int | None = None,
    controller: Controller | None = None,
    exact_evaluator: Evaluator | None = None,
) -> RunResult:
    """Run a scenario in closed loop.

    Args:
        scenario: what to run.
        controller_name: override of the scenario's controller (``none``, ``gradient``, ``single``,
            ``multi``, ``reach``); its parameters stay those of the scenario.
        progress: called as ``progress(fraction, t)`` after every step.
        stop_on_collision: stop at the first exact collision (default) or log it and go on.
        seed: random seed of the controller (default: the scenario's).
        controller: a ready-made controller (overrides ``controller_name``; for tests and experiments).
        exact_evaluator: the evaluator of the exact check (default: one on the robot reloaded with
            ``geometry="mesh"``; pass one to share the mesh loading between runs).

    Returns:
        The log.

    Raises:
        PreviewctlError: unknown controller name, missing GA module, ...
    """
    robot, model = scenario.robot, scenario.robot.model
    timing = scenario.timing
    if controller is None:
        spec = ControllerSpec(controller_name or scenario.controller.name, scenario.controller.params)
        rng = np.random.default_rng(scenario.seed if seed is None else seed)
        evaluator = Evaluator(robot, scenario.scene, scenario.index, scenario.potential)
        controller = make_controller(spec, robot, evaluator, rng)
    if exact_evaluator is None:
        exact_evaluator = Evaluator(scenario.exact_robot(), scenario.scene, scenario.index, scenario.potential)
    if exact_evaluator.robot.nq != robot.nq:
        raise PreviewctlError(
            f"exact evaluator robot has nq={exact_evaluator.robot.nq}, the scenario robot nq={robot.nq}"
        )
    params = getattr(controller, "params", scenario.controller.params)
    steps = timing.steps
    nq, nv, L = robot.nq, robot.nv, len(exact_evaluator.robot.guarded_links)
    log: dict[str, Any] = {
        "t": np.zeros(steps + 1),
        "q": np.zeros((steps + 1, nq)),
        "qdot": np.zeros((steps + 1, nv)),
        "qdot_requested": np.zeros((steps + 1, nv)),
        "hand": np.zeros((steps + 1, 3)),
        "desired": np.zeros((steps + 1, 3)),
        "hand_error": np.zeros(steps + 1),
        "S": np.zeros(steps + 1),
        "amsi": np.zeros(steps + 1),
        "link_distances": np.zeros((steps + 1, L)),
        "min_distance": np.zeros(steps + 1),
        "collision": np.zeros(steps + 1, dtype=bool),
        "cycle_time": np.zeros(steps + 1),
        "frame_due": np.zeros(steps + 1, dtype=bool),
        "velocity_scale": np.ones(steps + 1),
        "targets": None,  # (steps + 1, p, nq) once the controller reports its imaginary arms
        "target_S": None,
    }
    reader = kinematics_reader(robot)  # built once: the loop only reads through it
    q = np.array(scenario.q0, dtype=float)
    last_frame = -1
    rows = 2 if robot.task == "planar" else 3
    count = 0
    for k in range(steps + 1):
        t = k * timing.dt
        check = exact_evaluator(q[None, :], t)
        log["t"][k], log["q"][k] = t, q
        log["S"][k], log["amsi"][k] = check.S[0], check.amsi[0]
        log["link_distances"][k], log["min_distance"][k] = check.link_distances[0], check.min_distance[0]
        log["collision"][k] = check.collision[0]
        count = k + 1
        frame = frame_index(t, timing.frame)
        frame_due, last_frame = frame != last_frame, frame
        log["frame_due"][k] = frame_due
        if check.collision[0] and stop_on_collision:
            hand = check.tip_position[0].copy()
            desired, _ = task_target(robot, scenario.path, t)
            log["hand"][k], log["desired"][k] = hand, desired
            log["hand_error"][k] = np.linalg.norm((desired - hand)[:rows])
            if progress is not None:
                progress(1.0, t)
            break
        start = time.perf_counter()
        kin = kinematics(robot, q[None, :], reader=reader)
        state = ControlState(kin, scenario.path, scenario.scene, timing.dt, frame_due)
        qdot, info = controller.command(t, q, state)
        log["cycle_time"][k] = time.perf_counter() - start
        _log_command(log, k, kin.tip_position[0], info, qdot, rows)
        if k < steps:
            q = np.asarray(pin.integrate(model, q, qdot * timing.dt), dtype=float)
        if progress is not None:
            progress(k / steps, t)
    if log["targets"] is None:  # a controller without imaginary arms: p = 0
        log["targets"], log["target_S"] = np.zeros((steps + 1, 0, nq)), np.zeros((steps + 1, 0))
    arrays = {name: value[:count] for name, value in log.items()}
    return RunResult(
        scenario=scenario.name,
        controller=getattr(controller, "name", type(controller).__name__),
        robot=robot.name,
        dt=timing.dt,
        joint_names=robot.joint_names,
        link_names=exact_evaluator.robot.guarded_links,
        velocity_limits=effective_velocity_limits(robot, params.velocity_scale),
        **arrays,
    )


def _log_command(log: dict[str, Any], k: int, hand: Array, info: ControlInfo, qdot: Array, rows: int) -> None:
    log["hand"][k], log["desired"][k] = hand, info.desired_position
    log["hand_error"][k] = np.linalg.norm((info.desired_position - hand)[:rows])
    log["qdot"][k], log["qdot_requested"][k] = qdot, info.qdot_requested
    log["velocity_scale"][k] = info.scale
    if info.targets is not None and info.target_amsip is not None:
        if log["targets"] is None:
            rows_total, (p, nq) = len(log["t"]), info.targets.shape
            log["targets"], log["target_S"] = np.full((rows_total, p, nq), np.nan), np.full((rows_total, p), np.nan)
        log["targets"][k], log["target_S"][k] = info.targets, info.target_amsip
