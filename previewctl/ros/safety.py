"""When the node stops the arm, and how a command is kept within the limits.

The node publishes zero velocity, and says why on ``~/status``, when (:func:`stop_reason`):

* no joint state has come yet, or the last one is older than ``stale_periods`` control periods;
* the hand error exceeds ``max_hand_error``;
* the planning worker failed (crashed, raised or stopped answering);
* the cycle raised (the node catches every exception of a cycle, reports it and goes on);
* the command is not finite.

A finite command is scaled down as a whole, keeping its direction, until every joint is within its speed limit
(:func:`within_limits`): the controller already respects the limits, this is the last guard before the robot.
"""

from __future__ import annotations

import numpy as np

from previewctl.errors import PlanningWorkerError
from previewctl.types import Array


def stop_reason(joint_state_age: float | None, period: float, stale_periods: float, hand_error: float,
                max_hand_error: float, worker_error: PlanningWorkerError | None) -> str | None:
    """Why the arm must stop this cycle, or ``None``.

    Args:
        joint_state_age: time since the last joint state [s]; ``None``: none yet.
        period: the control period [s].
        stale_periods: joint states older than this many periods are stale.
        hand_error: the hand error of this cycle [m].
        max_hand_error: the largest hand error allowed [m].
        worker_error: the planning worker's failure, if any.
    """
    if joint_state_age is None:
        return "no joint state yet"
    if joint_state_age > stale_periods * period:
        return (f"joint states stale: the last is {joint_state_age:.3f} s old, more than {stale_periods:g} periods "
                f"({stale_periods * period:.3f} s)")
    if not hand_error <= max_hand_error:  # NaN included
        return f"hand error {hand_error:.4f} m exceeds max_hand_error {max_hand_error:g} m"
    if worker_error is not None:
        return f"planning worker failed: {worker_error}"
    return None


def within_limits(qdot: Array, limits: Array) -> tuple[Array, str | None]:
    """``qdot`` [rad/s] scaled down as a whole to within ``limits`` [rad/s] (``inf``: none), and why it was
    changed; zero, with the reason, when it is not finite."""
    qdot = np.asarray(qdot, dtype=float)
    if not np.all(np.isfinite(qdot)):
        return np.zeros_like(qdot), f"command not finite: {qdot.tolist()}"
    ratio = float(np.max(np.abs(qdot) / limits, initial=0.0))
    if ratio <= 1.0:
        return qdot, None
    return qdot / ratio, f"command scaled by 1/{ratio:.3g} to the speed limits"
