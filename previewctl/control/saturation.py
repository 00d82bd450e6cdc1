"""Saturation in the null space (SNS): joint limits that keep the hand on its path whenever they can.

Flacco, Khatib, De Luca, "Motion control of redundant robots under joint constraints: saturation in
the null space", ICRA 2012 (Algorithm 1, one task, velocity level). With box bounds
``low <= q̇ <= high`` (position limits over one period and speed limits, both containing 0):

1. ``q̇ = q̇_N + (J W)# (s ẋ − J q̇_N)`` with ``W`` the diagonal selection of the joints still free,
   ``q̇_N`` the saturated joints' fixed velocities (0 elsewhere) and ``s = 1``;
2. if ``q̇`` leaves the box, the task scaling factor ``s*`` that would bring it back with the current
   ``W`` is recorded (with ``W`` and ``q̇_N``) if it is the best so far; the most critical joint (the
   one that leaves the box first as ``s`` grows) is fixed at its bound and removed from ``W``;
3. when the free joints can no longer span the task (``rank(J W) < rank(J)``), the best recorded
   set is used with its ``s*``: the hand moves along ``ẋ``, slower, instead of leaving its direction.

A secondary null-space velocity ``n`` (the avoidance input) is then projected into the null space of
the free joints, ``(I − (J W)⁺ J W) W n``, and scaled by the largest ``β`` in [0, 1] that stays in
the box: it never moves the hand and never moves a saturated joint.

The functions here are pure linear algebra: the caller gives ``J`` and the damped inverse.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from previewctl.index.amsi import null_space_projector
from previewctl.types import Array

BOUND_SLACK = 1e-12
"""Relative slack [-] when testing ``low <= q̇ <= high`` (round-off of the bound itself)."""


@dataclass(frozen=True)
class Saturated:
    """The result of :func:`saturate`.

    Attributes:
        qdot: the joint velocity within the box [rad/s], ``(n,)``.
        task_scale: ``s`` in [0, 1], the fraction of the task velocity achieved (1 = all of it).
        null_scale: ``β`` in [0, 1] on the projected secondary velocity.
        saturated: which joints were fixed at a bound, ``(n,)`` bool.
    """

    qdot: Array
    task_scale: float
    null_scale: float
    saturated: Array


def within(qdot: Array, low: Array, high: Array) -> bool:
    """Whether ``low <= q̇ <= high`` to the relative slack :data:`BOUND_SLACK`."""
    slack = BOUND_SLACK * np.maximum(1.0, np.abs(qdot))
    return bool(np.all(qdot >= low - slack) and np.all(qdot <= high + slack))


def task_scaling(a: Array, b: Array, low: Array, high: Array) -> tuple[float, int]:
    """The largest ``s`` in [0, 1] with ``low <= s a + b <= high`` and the most critical joint.

    Args:
        a: the task part of ``q̇`` per unit of ``s`` [rad/s].
        b: the part that does not scale (saturated joints and their compensation) [rad/s].
        low: lower bounds [rad/s].
        high: upper bounds [rad/s].

    Returns:
        ``(s*, j)``: ``s* = 0`` when no ``s`` fits; ``j`` the joint whose bound caps ``s`` first (or
        one that is out of its box whatever ``s``).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        to_low, to_high = (low - b) / a, (high - b) / a
    upper = np.where(a > 0, to_high, np.where(a < 0, to_low, np.inf))
    lower = np.where(a > 0, to_low, np.where(a < 0, to_high, -np.inf))
    stuck = (a == 0) & ((b < low) | (b > high))
    if stuck.any():
        return 0.0, int(np.flatnonzero(stuck)[0])
    critical = int(np.argmin(upper))
    s_max, s_min = float(upper.min()), float(lower.max())
    if s_min > s_max or s_max < 0.0 or s_min > 1.0:
        return 0.0, critical
    return min(s_max, 1.0), critical


def saturate(
    J: Array,
    xdot: Array,
    secondary: Array,
    low: Array,
    high: Array,
    pseudo_inverse: Callable[[Array], Array],
) -> Saturated:
    """SNS (module docstring): the task ``ẋ`` with saturated joints, then the secondary velocity.

    Args:
        J: task Jacobian ``(m, n)``.
        xdot: task velocity ``(m,)`` (feed-forward plus feedback).
        secondary: null-space input ``(n,)`` [rad/s] (projected here).
        low: lower joint-velocity bounds ``(n,)`` [rad/s], ``<= 0``.
        high: upper joint-velocity bounds ``(n,)`` [rad/s], ``>= 0``.
        pseudo_inverse: ``J ↦ J#`` ``(n, m)``, e.g. the damped inverse of eq. 19.
    """
    n = J.shape[1]
    free, fixed = np.ones(n, dtype=bool), np.zeros(n)
    full_rank = np.linalg.matrix_rank(J) if J.size else 0
    best: tuple[float, Array, Array] = (0.0, free.copy(), fixed.copy())
    scale = 1.0
    while True:
        a, b = _parts(J, xdot, free, fixed, pseudo_inverse)
        if within(a + b, low, high):
            break
        s_star, j = task_scaling(a, b, low, high)
        if s_star > best[0]:
            best = (s_star, free.copy(), fixed.copy())
        free[j], fixed[j] = False, high[j] if a[j] > 0 or (a[j] == 0 and b[j] > high[j]) else low[j]
        if not free.any() or np.linalg.matrix_rank(J[:, free]) < full_rank:
            scale, free, fixed = best[0], best[1].copy(), best[2].copy()
            a, b = _parts(J, xdot, free, fixed, pseudo_inverse)
            break
    qdot = np.clip(scale * a + b, low, high)  # removes round-off only: s* keeps every joint in the box
    projected = np.where(free, null_space_projector(J * free) @ (secondary * free), 0.0)
    beta = _box_budget(qdot, projected, low, high)
    return Saturated(qdot + beta * projected, scale, beta, ~free)


def _parts(
    J: Array, xdot: Array, free: Array, fixed: Array, pseudo_inverse: Callable[[Array], Array]
) -> tuple[Array, Array]:
    """``(a, b)`` of ``q̇ = s a + b``: ``a = (J W)# ẋ``, ``b = q̇_N − (J W)# J q̇_N``."""
    inverse = pseudo_inverse(J * free) * free[:, None]  # exact zero rows for the saturated joints
    return inverse @ xdot, fixed - inverse @ (J @ fixed)


def _box_budget(qdot: Array, step: Array, low: Array, high: Array) -> float:
    """Largest ``β`` in [0, 1] with ``low <= q̇ + β step <= high`` (``q̇`` inside the box)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(step > 0, (high - qdot) / step, np.where(step < 0, (low - qdot) / step, np.inf))
    return float(np.clip(room.min(), 0.0, 1.0)) if room.size else 1.0
