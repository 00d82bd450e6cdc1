"""Closed-loop kinematic simulation of a scenario, its log, and atomic saving/loading of runs.

The loop, with control period ``dt`` and camera frame period ``T_f`` (33 ms by default):

1. at ``t_k = k dt`` the state is checked exactly: AMSIP, per-link clearance and collision from an
   :class:`~previewctl.amsip.Evaluator` on the robot loaded with ``geometry="mesh"`` (the exact URDF
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

import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.amsip import Evaluator
from previewctl.avoidance import kinematics, kinematics_reader
from previewctl.control import (
    ControlInfo,
    Controller,
    ControllerSpec,
    ControlState,
    effective_velocity_limits,
    make_controller,
    task_target,
)
from previewctl.errors import PreviewctlError
from previewctl.files import atomic_write, atomic_write_bytes
from previewctl.scenario import Scenario

Array = NDArray[np.float64]
Progress = Callable[[float, float], None]
"""``progress(fraction, t)``: fraction of the run done in [0, 1] and simulated time [s]."""

NPZ_NAME = "run.npz"
SUMMARY_NAME = "summary.json"

_ARRAYS = ("t", "q", "qdot", "qdot_requested", "hand", "desired", "hand_error", "S", "amsi", "link_distances",
           "min_distance", "collision", "cycle_time", "frame_due", "velocity_scale", "velocity_limits",
           "targets", "target_S")


@dataclass(frozen=True, eq=False)
class RunResult:
    """The log of one simulated run (``T`` logged steps).

    Attributes:
        scenario: scenario name.
        controller: controller name.
        robot: robot name.
        dt: control period [s].
        joint_names: joint names, in ``q`` order.
        link_names: guarded link names, in ``link_distances`` column order.
        t: ``(T,)`` times [s].
        q: ``(T, nq)`` configurations [rad].
        qdot: ``(T, nv)`` applied joint velocities [rad/s] (0 on a colliding last step).
        qdot_requested: ``(T, nv)`` joint velocities before the limits [rad/s].
        hand: ``(T, 3)`` hand position [m].
        desired: ``(T, 3)`` desired hand position [m] (z = 0 for planar paths).
        hand_error: ``(T,)`` hand position error ``|r_d − r|`` [m] (over the task's position rows).
        S: ``(T,)`` AMSIP (exact geometry).
        amsi: ``(T,)`` AMSI ``E``.
        link_distances: ``(T, L)`` clearance per guarded link [m] (``inf`` without obstacles).
        min_distance: ``(T,)`` smallest clearance [m].
        collision: ``(T,)`` exact collision flag.
        cycle_time: ``(T,)`` wall time of each control cycle (kinematics + command) [s].
        frame_due: ``(T,)`` whether a camera frame arrived at the step.
        velocity_scale: ``(T,)`` uniform velocity-limit scaling applied (1 = unlimited).
        velocity_limits: ``(nv,)`` joint speed limits used [rad/s] (``inf`` = none).
        targets: ``(T, p, nq)`` the imaginary arms ``q~_i`` the controller steered toward (``p = 0``
            without previews; NaN where no command was computed, e.g. the colliding step).
        target_S: ``(T, p)`` their AMSIP values.
    """

    scenario: str
    controller: str
    robot: str
    dt: float
    joint_names: tuple[str, ...]
    link_names: tuple[str, ...]
    t: Array
    q: Array
    qdot: Array
    qdot_requested: Array
    hand: Array
    desired: Array
    hand_error: Array
    S: Array
    amsi: Array
    link_distances: Array
    min_distance: Array
    collision: NDArray[np.bool_]
    cycle_time: Array
    frame_due: NDArray[np.bool_]
    velocity_scale: Array
    velocity_limits: Array
    targets: Array
    target_S: Array  # noqa: N815 -- the paper's symbol S

    @property
    def steps(self) -> int:
        """Number of logged steps ``T``."""
        return int(self.t.shape[0])

    @property
    def collision_index(self) -> int | None:
        """Index of the first colliding step, or ``None``."""
        hits = np.flatnonzero(self.collision)
        return int(hits[0]) if hits.size else None

    def summary(self) -> dict[str, Any]:
        """Key figures of the run (JSON-ready: floats, ints, bools, strings, ``None``).

        Keys: ``scenario``, ``controller``, ``robot``, ``steps``, ``duration`` [s], ``collided``,
        ``collision_time`` [s], ``collision_link``, ``max_hand_error`` [m], ``min_clearance`` [m]
        (``None`` without obstacles), ``mean_S``, ``min_S``, ``max_abs_qdot`` [rad/s],
        ``max_qdot_ratio`` (largest ``|q̇_j| / q̇max_j``), ``cycle_time_median`` [s], ``cycle_time_max`` [s].
        """
        k = self.collision_index
        link = None
        if k is not None:
            link = self.link_names[int(np.argmin(self.link_distances[k]))] if self.link_names else None
        finite = np.isfinite(self.velocity_limits)
        ratio = np.abs(self.qdot[:, finite]) / self.velocity_limits[finite] if finite.any() else np.zeros((1, 1))
        clearance = float(self.min_distance.min()) if self.steps else math.inf
        return {
            "scenario": self.scenario,
            "controller": self.controller,
            "robot": self.robot,
            "steps": self.steps,
            "duration": float(self.t[-1] - self.t[0]) if self.steps else 0.0,
            "collided": k is not None,
            "collision_time": float(self.t[k]) if k is not None else None,
            "collision_link": link,
            "max_hand_error": float(self.hand_error.max()),
            "min_clearance": clearance if math.isfinite(clearance) else None,
            "mean_S": float(self.S.mean()),
            "min_S": float(self.S.min()),
            "max_abs_qdot": float(np.abs(self.qdot).max()),
            "max_qdot_ratio": float(ratio.max()) if ratio.size else 0.0,
            "cycle_time_median": float(np.median(self.cycle_time)),
            "cycle_time_max": float(self.cycle_time.max()),
        }


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


# ------------------------------------------------------------------------------------ saving


def save_run(result: RunResult, out_dir: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write ``run.npz`` (every array and the names) and ``summary.json`` into ``out_dir``.

    Each file is written atomically: a reader sees either the old file or the complete new one.

    Returns:
        The two paths ``(npz, json)``.

    Raises:
        PreviewctlError: the folder cannot be created or written.
    """
    folder = Path(out_dir)
    npz_path, json_path = folder / NPZ_NAME, folder / SUMMARY_NAME
    arrays: dict[str, Any] = {name: getattr(result, name) for name in _ARRAYS}
    arrays.update(
        joint_names=np.array(result.joint_names, dtype=str),
        link_names=np.array(result.link_names, dtype=str),
        scenario=np.array(result.scenario),
        controller=np.array(result.controller),
        robot=np.array(result.robot),
        dt=np.array(result.dt),
    )
    text = json.dumps(result.summary(), indent=2) + "\n"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(npz_path, lambda handle: np.savez_compressed(handle, **arrays))
        atomic_write_bytes(json_path, text.encode("utf-8"))
    except OSError as exc:
        raise PreviewctlError(f"cannot write the run to {str(folder)!r}: {exc}") from exc
    return npz_path, json_path


def load_run(out_dir: str | os.PathLike[str]) -> RunResult:
    """Reload a run written by :func:`save_run`.

    Raises:
        PreviewctlError: missing or unreadable files.
    """
    folder = Path(out_dir)
    npz_path = folder / NPZ_NAME
    if not npz_path.is_file():
        raise PreviewctlError(f"no run in {str(folder)!r}: {NPZ_NAME} is missing")
    try:
        with np.load(npz_path, allow_pickle=False) as npz:
            stored = {name: npz[name] for name in npz.files}
    except (OSError, ValueError) as exc:
        raise PreviewctlError(f"cannot read {str(npz_path)!r}: {exc}") from exc
    names = {f.name for f in fields(RunResult)}
    missing = sorted(names - set(stored))
    if missing:
        raise PreviewctlError(f"{str(npz_path)!r} lacks {', '.join(missing)}")
    return RunResult(
        scenario=str(stored["scenario"]),
        controller=str(stored["controller"]),
        robot=str(stored["robot"]),
        dt=float(stored["dt"]),
        joint_names=tuple(str(n) for n in stored["joint_names"]),
        link_names=tuple(str(n) for n in stored["link_names"]),
        **{name: stored[name] for name in _ARRAYS},
    )


def load_summary(out_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``summary.json`` of a saved run."""
    path = Path(out_dir) / SUMMARY_NAME
    try:
        loaded: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PreviewctlError(f"cannot read {str(path)!r}: {exc}") from exc
    return loaded


__all__ = ["NPZ_NAME", "SUMMARY_NAME", "RunResult", "frame_index", "load_run", "load_summary", "save_run", "simulate"]
