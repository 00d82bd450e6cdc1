"""The figures of merit of one benchmark run, from its log."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from previewctl.sim.log import RunResult

TOLERANCES: dict[str, float] = {"success_1mm": 1e-3, "success_5mm": 5e-3}
"""Success at each hand-error tolerance [m]: collision-free AND max hand error below it."""


def run_metrics(result: RunResult) -> dict[str, Any]:
    """JSON-ready metrics of a run.

    Keys: ``success_1mm``, ``success_5mm`` (free of collisions, with obstacles and with itself, and max hand error
    < 1 mm / 5 mm), ``collision_free``, ``collision_time`` [s] (first exact collision with an obstacle, ``None``
    without one), ``self_collision_free``, ``self_collision_time`` [s] (first exact self-collision),
    ``min_clearance`` [m] (``None`` without obstacles), ``max_hand_error`` and ``rms_hand_error`` [m]
    (over the logged steps, up to a collision), ``mean_S``, ``cycle_time_median`` and ``cycle_time_p95`` [s]
    (the control cycles, without the colliding last step), ``steps``.
    """
    k, s = result.collision_index, result.self_collision_index
    error = np.asarray(result.hand_error)
    max_error = float(error.max())
    clearance = float(np.min(result.min_distance))
    end = min(i for i in (k, s, result.steps) if i is not None)  # the colliding last step has no control cycle
    cycles = np.asarray(result.cycle_time[:end])
    cycles = cycles if cycles.size else np.zeros(1)
    free = k is None and s is None
    return {
        **{name: free and max_error < tol for name, tol in TOLERANCES.items()},
        "collision_free": k is None,
        "collision_time": None if k is None else float(result.t[k]),
        "self_collision_free": s is None,
        "self_collision_time": None if s is None else float(result.t[s]),
        "min_clearance": clearance if math.isfinite(clearance) else None,
        "max_hand_error": max_error,
        "rms_hand_error": float(np.sqrt(np.mean(error**2))),
        "mean_S": float(np.mean(result.S)),
        "cycle_time_median": float(np.median(cycles)),
        "cycle_time_p95": float(np.percentile(cycles, 95)),
        "steps": result.steps,
    }
