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
    frame_due: NDArray[np.bool_]
    velocity_scale: Array
    velocity_limits: Array
    targets: Array
    target_S: Array  # noqa: N815 -- the paper's symbol S
    execution: str
    composition: str
    slack: Array

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
    def error_index(self) -> int | None:
        """Index of the first step whose hand error exceeds :attr:`tolerance`, or ``None``."""
        over = np.flatnonzero(self.hand_error > self.tolerance)
        return int(over[0]) if over.size else None

    def summary(self) -> dict[str, Any]:
        """Key figures of the run (JSON-ready: floats, ints, bools, strings, ``None``).

        The verdict: ``success`` is true only when the run is collision-free *and* its largest hand
        error is at most ``tolerance``; ``failure`` names what failed (``"collision"``,
        ``"hand error"``, or both joined by ``" and "``; ``None`` on success), ``collision_time`` [s]
        and ``error_time`` [s] when each first failed.

        Keys: ``scenario``, ``controller``, ``robot``, ``steps``, ``duration`` [s], ``success``,
        ``failure``, ``tolerance`` [m], ``collided``, ``collision_time`` [s], ``collision_link``,
        ``max_hand_error`` [m], ``error_time`` [s], ``min_clearance`` [m] (``None`` without obstacles),
        ``mean_S``, ``min_S``, ``max_abs_qdot`` [rad/s], ``max_qdot_ratio`` (largest ``|q̇_j| / q̇max_j``),
        ``cycle_time_median`` [s], ``cycle_time_max`` [s], ``execution``, ``composition``, ``max_slack`` [m/s].
        """
        k, e = self.collision_index, self.error_index
        failures = [part for part, index in (("collision", k), ("hand error", e)) if index is not None]
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
            "success": not failures,
            "failure": " and ".join(failures) or None,
            "tolerance": self.tolerance,
            "collided": k is not None,
            "collision_time": float(self.t[k]) if k is not None else None,
            "collision_link": link,
            "max_hand_error": float(self.hand_error.max()),
            "error_time": float(self.t[e]) if e is not None else None,
            "min_clearance": clearance if math.isfinite(clearance) else None,
            "mean_S": float(self.S.mean()),
            "min_S": float(self.S.min()),
            "max_abs_qdot": float(np.abs(self.qdot).max()),
            "max_qdot_ratio": float(ratio.max()) if ratio.size else 0.0,
            "cycle_time_median": float(np.median(self.cycle_time)),
            "cycle_time_max": float(self.cycle_time.max()),
            "execution": self.execution,
            "composition": self.composition,
            "max_slack": float(self.slack.max()) if self.steps else 0.0,
        }


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
    missing = sorted(set(types) - set(stored))
    if missing:
        raise PreviewctlError(f"{str(npz_path)!r} lacks {', '.join(missing)}")
    return RunResult(**{name: _restored(stored[name], kind) for name, kind in types.items()})


def _stored(value: object) -> NDArray[Any]:
    """A field as an npz member: names as a string array (also when empty), the rest as arrays."""
    return np.array(value, dtype=str) if isinstance(value, tuple) else np.asarray(value)


def _restored(stored: NDArray[Any], kind: object) -> Any:
    """An npz member back as a field of declared type ``kind`` (``str``, ``float``, names or an array)."""
    if kind is str:
        return str(stored)
    if kind is float:
        return float(stored)
    if kind == tuple[str, ...]:
        return tuple(str(n) for n in stored)
    return stored


def load_summary(out_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``summary.json`` of a saved run."""
    path = Path(out_dir) / SUMMARY_NAME
    try:
        loaded: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PreviewctlError(f"cannot read {str(path)!r}: {exc}") from exc
    return loaded
