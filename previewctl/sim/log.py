"""The run log (:class:`RunResult`), its summary, and atomic saving and loading (``run.npz`` + ``summary.json``)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, get_type_hints

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import PreviewctlError
from previewctl.files import atomic_write, atomic_write_bytes
from previewctl.types import Array

NPZ_NAME = "run.npz"
SUMMARY_NAME = "summary.json"


@dataclass(frozen=True, eq=False)
class RunResult:
    """The log of one simulated run (``T`` logged steps).

    The fields are the run-log schema: :func:`save_run` writes each one under its name into ``run.npz``
    and :func:`load_run` reads them back by their declared types.

    Attributes:
        scenario: scenario name.
        controller: controller name.
        robot: robot name.
        dt: control period [s].
        joint_names: joint names, in ``q`` order.
        link_names: guarded link names, in ``link_distances`` column order.
        tolerance: largest hand error [m] of a successful run (see :meth:`summary`).
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
        loop_time: ``(T,)`` wall time of each whole cycle of the loop from its deadline [s]: the clock's wake-up
            latency (real time), the integration, the exact check, the control cycle and the logging; over ``dt``,
            the cycle missed the next deadline.
        plan_age: ``(T,)`` background planning: the age [s] of the searches' or the planner's result in use
            (NaN with none, and with inline planning).
        fallback: ``(T,)`` background planning: the cycle ran the ``qp`` law for want of a valid result.
        frame_due: ``(T,)`` whether a camera frame arrived at the step.
        velocity_scale: ``(T,)`` task scaling of the joint-limit saturation (1 = the whole task velocity).
        velocity_limits: ``(nv,)`` joint speed limits used [rad/s] (``inf`` = none).
        targets: ``(T, p, nq)`` the imaginary arms ``q~_i`` the controller steered toward (``p = 0``
            without previews; NaN where no command was computed, e.g. the colliding step).
        target_S: ``(T, p)`` their AMSIP values.
        execution: how the commands were executed: ``qp`` or ``pseudoinverse``.
        composition: what the controller was made of: its law, imaginary-arm policy, planner, execution and the
            settings it ignored (:class:`~previewctl.control.base.Composition`, as text).
        slack: ``(T,)`` the QP's largest collision-damper slack [m/s] (0 while every damper held).
        self_distance: ``(T,)`` smallest distance between the arm's self pairs [m] (exact geometry): exact below the
            potential's ``self_influence_distance``, else a lower bound at least that; 0 in contact; ``inf`` without
            self pairs.
        self_collision: ``(T,)`` exact self-collision flag (two of the arm's own links touch).
        self_pair: ``(T,)`` index in :attr:`self_pairs` of the nearest link pair at each step (``-1``: none).
        self_pairs: the link pairs ``(a, b)`` the exact check measured (``a`` nearer the base).
        observations: ``(T,)`` observed obstacles (a scenario's ``[sensing]``): the observations delivered to the
            controller before each step (:mod:`previewctl.sim.sensor`); 0 without sensing.
        observations_dropped: the observations due by the last step that the sensor dropped.
        real_time_class: a real-time run's loop in Linux's real-time class (``SCHED_FIFO``): ``"granted"`` or
            ``"refused"`` by the OS; ``""`` in simulated time (:func:`~previewctl.control.background.real_time_loop`).
        cores_awake: a real-time run's cores kept out of deep idle states: ``"granted"``, ``"refused"`` or ``""``,
            as ``real_time_class``.
    """

    scenario: str
    controller: str
    robot: str
    dt: float
    joint_names: tuple[str, ...]
    link_names: tuple[str, ...]
    tolerance: float
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
    loop_time: Array
    plan_age: Array
    fallback: NDArray[np.bool_]
    frame_due: NDArray[np.bool_]
    velocity_scale: Array
    velocity_limits: Array
    targets: Array
    target_S: Array  # noqa: N815 -- the paper's symbol S
    execution: str
    composition: str
    slack: Array
    self_distance: Array
    self_collision: NDArray[np.bool_]
    self_pair: NDArray[np.int64]
    self_pairs: tuple[tuple[str, str], ...]
    observations: NDArray[np.int64]
    observations_dropped: int
    real_time_class: str
    cores_awake: str

    @property
    def steps(self) -> int:
        """Number of logged steps ``T``."""
        return int(self.t.shape[0])

    @property
    def collision_index(self) -> int | None:
        """Index of the first colliding step, or ``None``."""
        hits = np.flatnonzero(self.collision)
        return int(hits[0]) if hits.size else None

    @property
    def self_collision_index(self) -> int | None:
        """Index of the first step where the arm touches itself, or ``None``."""
        hits = np.flatnonzero(self.self_collision)
        return int(hits[0]) if hits.size else None

    @property
    def error_index(self) -> int | None:
        """Index of the first step whose hand error exceeds :attr:`tolerance`, or ``None``."""
        over = np.flatnonzero(self.hand_error > self.tolerance)
        return int(over[0]) if over.size else None

    def summary(self) -> dict[str, Any]:
        """Key figures of the run (JSON-ready: floats, ints, bools, strings, ``None``).

        The verdict: ``success`` is true only when the run is free of collisions with obstacles *and* with
        itself, *and* its largest hand error is at most ``tolerance``; ``failure`` names what failed
        (``"collision"``, ``"self-collision"``, ``"hand error"``, joined by ``" and "``; ``None`` on success),
        ``collision_time``, ``self_collision_time`` and ``error_time`` [s] when each first failed.

        Keys: ``scenario``, ``controller``, ``robot``, ``steps``, ``duration`` [s], ``success``,
        ``failure``, ``tolerance`` [m], ``collided``, ``collision_time`` [s], ``collision_link``,
        ``self_collided``, ``self_collision_time`` [s], ``self_collision_links`` (``[a, b]``: the two links that
        touched first, ``a`` nearer the base), ``min_self_distance`` [m] (exact below the potential's
        ``self_influence_distance``, a lower bound at least that above it; ``None`` without self pairs),
        ``max_hand_error`` [m], ``error_time`` [s], ``min_clearance`` [m] (``None`` without obstacles),
        ``mean_S``, ``min_S``, ``max_abs_qdot`` [rad/s], ``max_qdot_ratio`` (largest ``|q̇_j| / q̇max_j``),
        ``cycle_time_median``, ``cycle_time_p99``, ``cycle_time_max`` [s] (the control cycles), ``execution``,
        ``composition``, ``max_slack`` [m/s]; and how the whole cycles fit their period ``dt`` (:attr:`loop_time`):
        ``cycle_p50``, ``cycle_p99``, ``cycle_max`` [s], ``deadline_misses`` (the cycles longer than ``dt``: each
        missed the next deadline), and of background planning ``plan_age_p95`` [s] (``None`` without a result in
        use, e.g. inline) and ``fallback_fraction`` (the fraction of cycles that ran the ``qp`` law instead; 0
        inline); ``observations`` and ``observations_dropped``: observations delivered to the controller and dropped
        by the simulator's sensor (0 without ``[sensing]``); ``real_time_class`` and ``cores_awake``: whether the OS
        granted a real-time run's loop the real-time class and kept its cores awake (``None`` in simulated time).
        """
        k, s, e = self.collision_index, self.self_collision_index, self.error_index
        failures = [part for part, index in (("collision", k), ("self-collision", s), ("hand error", e))
                    if index is not None]
        link = None
        if k is not None:
            link = self.link_names[int(np.argmin(self.link_distances[k]))] if self.link_names else None
        finite = np.isfinite(self.velocity_limits)
        ratio = np.abs(self.qdot[:, finite]) / self.velocity_limits[finite] if finite.any() else np.zeros((1, 1))
        clearance = float(self.min_distance.min()) if self.steps else math.inf
        self_clearance = float(self.self_distance.min()) if self.steps else math.inf
        pair = int(self.self_pair[s]) if s is not None else -1
        return {
            "scenario": self.scenario,
            "controller": self.controller,
            "robot": self.robot,
            "steps": self.steps,
            "duration": float(self.t[-1] - self.t[0]) if self.steps else 0.0,
            "success": not failures,
            "failure": " and ".join(failures) or None,
            "tolerance": self.tolerance,
            "collided": k is not None,
            "collision_time": float(self.t[k]) if k is not None else None,
            "collision_link": link,
            "self_collided": s is not None,
            "self_collision_time": float(self.t[s]) if s is not None else None,
            "self_collision_links": list(self.self_pairs[pair]) if pair >= 0 else None,
            "min_self_distance": self_clearance if math.isfinite(self_clearance) else None,
            "max_hand_error": float(self.hand_error.max()),
            "error_time": float(self.t[e]) if e is not None else None,
            "min_clearance": clearance if math.isfinite(clearance) else None,
            "mean_S": float(self.S.mean()),
            "min_S": float(self.S.min()),
            "max_abs_qdot": float(np.abs(self.qdot).max()),
            "max_qdot_ratio": float(ratio.max()) if ratio.size else 0.0,
            "cycle_time_median": float(np.median(self.cycle_time)),
            "cycle_time_p99": float(np.percentile(self.cycle_time, 99)),
            "cycle_time_max": float(self.cycle_time.max()),
            "execution": self.execution,
            "composition": self.composition,
            "max_slack": float(self.slack.max()) if self.steps else 0.0,
            "observations": int(self.observations.sum()),
            "observations_dropped": self.observations_dropped,
            "real_time_class": _granted(self.real_time_class),
            "cores_awake": _granted(self.cores_awake),
            **self._timing(),
        }

    def _timing(self) -> dict[str, Any]:
        """The summary's figures of how the cycles fit their period (:meth:`summary`)."""
        ages = self.plan_age[np.isfinite(self.plan_age)]
        return {
            "cycle_p50": float(np.median(self.loop_time)),
            "cycle_p99": float(np.percentile(self.loop_time, 99)),
            "cycle_max": float(self.loop_time.max()),
            "deadline_misses": int(np.count_nonzero(self.loop_time > self.dt)),
            "plan_age_p95": float(np.percentile(ages, 95)) if ages.size else None,
            "fallback_fraction": float(self.fallback.mean()) if self.steps else 0.0,
        }


def grant_record(granted: bool | None) -> str:
    """How the log records the OS's answer to a real-time request (:attr:`RunResult.real_time_class`): ``"granted"``,
    ``"refused"``, or ``""`` when it was not asked (``None``: simulated time); :meth:`RunResult.summary` reads it
    back."""
    return "" if granted is None else "granted" if granted else "refused"


def _granted(answer: str) -> bool | None:
    """A request's answer as :func:`grant_record` logged it, as the summary says it (``None``: not asked)."""
    return None if not answer else answer == "granted"


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
    arrays: dict[str, Any] = {f.name: _stored(getattr(result, f.name)) for f in fields(RunResult)}
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
    types = get_type_hints(RunResult)
    if "t" in stored and "cycle_time" in stored:
        stored = {**_added_later(stored["t"].shape[0], stored["cycle_time"]), **stored}
    missing = sorted(set(types) - set(stored))
    if missing:
        raise PreviewctlError(f"{str(npz_path)!r} lacks {', '.join(missing)}")
    return RunResult(**{name: _restored(stored[name], kind) for name, kind in types.items()})


def _added_later(steps: int, cycle_time: NDArray[Any]) -> dict[str, NDArray[Any]]:
    """The members a log written by an older previewctl lacks, as that run had them: no self pair measured, no
    composition recorded (an empty text), inline planning, no whole cycle timed (taken as its control cycle,
    ``cycle_time``, a lower bound), no observation, and nothing asked of the OS for a real-time loop."""
    return {"loop_time": cycle_time, "plan_age": np.full(steps, np.nan), "fallback": np.zeros(steps, dtype=bool),
            "self_distance": np.full(steps, np.inf), "self_collision": np.zeros(steps, dtype=bool),
            "self_pair": np.full(steps, -1, dtype=np.int64), "self_pairs": np.zeros((0, 2), dtype=str),
            "composition": np.array(""), "observations": np.zeros(steps, dtype=np.int64),
            "observations_dropped": np.array(0), "real_time_class": np.array(""), "cores_awake": np.array("")}


def _stored(value: object) -> NDArray[Any]:
    """A field as an npz member: names (and pairs of names, as rows) as a string array (also when empty), the rest
    as arrays."""
    return np.array(value, dtype=str) if isinstance(value, tuple) else np.asarray(value)


def _restored(stored: NDArray[Any], kind: object) -> Any:
    """An npz member back as a field of declared type ``kind`` (``str``, ``float``, names, name pairs or an array)."""
    if kind is str:
        return str(stored)
    if kind is float:
        return float(stored)
    if kind is int:
        return int(stored)
    if kind == tuple[str, ...]:
        return tuple(str(n) for n in stored)
    if kind == tuple[tuple[str, str], ...]:
        return tuple((str(a), str(b)) for a, b in stored.reshape(-1, 2))
    return stored


def load_summary(out_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``summary.json`` of a saved run."""
    path = Path(out_dir) / SUMMARY_NAME
    try:
        loaded: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PreviewctlError(f"cannot read {str(path)!r}: {exc}") from exc
    return loaded
