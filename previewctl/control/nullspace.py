"""Null-space inputs ``v`` of eq. 19: the preview pull of eqs. 20-21, the AMSIP gradient and limit avoidance.

* The preview pull (eq. 21, eq. 20 with one target) is taken in the tangent space,
  ``v = K_v Σ_i k_i (q̃_i ⊖ q)`` (``pin.difference``), which equals eq. 21 for ordinary joints because
  ``Σ k_i = 1``; for revolute joints whose range spans a full turn or more, each difference is wrapped into
  ``[−π, π)`` (the same physical target, reached the short way).
* The AMSIP gradient ``v = K_g ∇_q S`` (:class:`AmsipGradient`) is a local null-space ascent of eq. 18.
* Limit avoidance (:func:`limit_avoidance`) is added to every law's input by the tracking reference.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np
import pinocchio as pin

from previewctl.control.params import ControllerParams
from previewctl.errors import ParameterError
from previewctl.index.evaluator import POTENTIAL_ONLY, Evaluator
from previewctl.robot.joints import FULL_TURN
from previewctl.robot.model import Robot
from previewctl.types import Array, BoolArray, IntArray

LocalTerm = Callable[[Array, float], Array]
"""A local null-space term ``v(q, t)`` [rad/s] ``(nv,)`` that a law adds to its input (:class:`AmsipGradient`)."""


def gain_vector(gain: tuple[float, ...], nv: int, where: str) -> Array:
    """A gain (one number or one per joint velocity) as ``(nv,)`` [1/s]; ``where`` names it in messages.

    Raises:
        ParameterError: neither 1 nor ``nv`` entries.
    """
    if len(gain) == 1:
        return np.full(nv, gain[0])
    if len(gain) != nv:
        raise ParameterError(f"{where} has {len(gain)} entries; give one number or {nv} (one per joint velocity)")
    return np.array(gain)


def limit_avoidance(robot: Robot, q: Array, params: ControllerParams) -> Array:
    """Null-space input [rad/s] ``(nv,)`` that steers away from position limits before they are hit
    (:class:`LimitAvoidance`; keep one of those to step a loop)."""
    return LimitAvoidance(robot, params)(q)


class LimitAvoidance:
    """``−K_l ∇H`` of ``H = ½ Σ_j max(0, ρ_j − d_j)²`` over both limits of each joint with finite limits,
    ``d_j`` the distance to the limit [rad] and ``ρ_j = limit_margin · (hi_j − lo_j)``: zero unless a
    joint is within ``ρ_j`` of a limit, then ``K_l`` [1/s] times how deep it is in that margin.

    The margins are computed once for the arm and the settings (``limit_margin``, ``limit_gain`` [1/s]).
    """

    def __init__(self, robot: Robot, params: ControllerParams) -> None:
        facts = robot.joints
        self._index, self._gain = facts.q_index, params.limit_gain
        self._bounded = np.isfinite(facts.lower) & np.isfinite(facts.upper)
        self._margin = np.where(self._bounded, params.limit_margin * (facts.upper - facts.lower), 0.0)
        # an unbounded joint's limits read 0: its term is dropped anyway, and no infinity enters the arithmetic
        self._lower = np.where(self._bounded, facts.lower, 0.0)
        self._upper = np.where(self._bounded, facts.upper, 0.0)

    def __call__(self, q: Array) -> Array:
        """The input [rad/s] ``(nv,)`` at configuration ``q`` ``(nq,)``."""
        out = np.empty(self._index.size)
        _limit_push(np.asarray(q, dtype=float), self._index, self._bounded, self._margin, self._lower, self._upper,
                    self._gain, out)
        return out


@numba.njit(cache=True, nogil=True)
def _limit_push(q: Array, index: IntArray, bounded: BoolArray, margin: Array, lower: Array, upper: Array,
                gain: float, out: Array) -> None:  # pragma: no cover - compiled
    """``out[j] = K_l (max(0, ρ_j − (q_j − lo_j)) − max(0, ρ_j − (hi_j − q_j)))`` for the bounded joints, else 0
    (:class:`LimitAvoidance`; one compiled loop instead of a dozen small array operations per cycle)."""
    for j in range(index.size):
        up = down = 0.0
        if bounded[j]:
            position = q[index[j]]
            up = margin[j] - (position - lower[j])
            down = margin[j] - (upper[j] - position)
        out[j] = gain * ((up if up > 0.0 else 0.0) - (down if down > 0.0 else 0.0))  # np.maximum(0, x) exactly


def wrapped_difference(robot: Robot, q: Array, target: Array, *, keep: tuple[int, ...] = ()) -> Array:
    """``target ⊖ q`` ``(nv,)`` [rad or m], the full-turn angles wrapped into [−π, π), except the
    velocity indices in ``keep`` (their plain difference is kept).

    Continuous joints need no wrapping: ``pin.difference`` already returns their angle.
    """
    return _wrapped(robot, q, target, _wrapping(robot, keep))


def _wrapping(robot: Robot, keep: tuple[int, ...]) -> BoolArray:
    """The velocity indices that :func:`wrapped_difference` wraps ``(nv,)``."""
    wrap = robot.joints.full_turn & ~robot.joints.continuous
    wrap[list(keep)] = False
    return wrap


def _wrapped(robot: Robot, q: Array, target: Array, wrap: BoolArray) -> Array:
    """``target ⊖ q`` with the indices ``wrap`` wrapped into [−π, π)."""
    diff = np.asarray(pin.difference(robot.model, q, target), dtype=np.float64)
    if not wrap.any():  # nothing to wrap (e.g. a plan's targets, ``keep`` every index): the plain difference
        return diff
    return np.where(wrap, (diff + np.pi) % FULL_TURN - np.pi, diff)


def preview_pull(robot: Robot, q: Array, targets: Array, weights: Array, *, keep: tuple[int, ...] = ()) -> Array:
    """``Σ_i k_i (q̃_i ⊖ q)`` ``(nv,)`` [rad]: the blend of eq. 21 (eq. 20 with one target), each difference as
    :func:`wrapped_difference` takes it (``keep`` every index: plain differences, for targets unwrapped along a
    plan)."""
    pull = np.zeros(robot.nv)
    if robot.joints.vector_space and keep == tuple(range(robot.nv)):  # plain differences, target - q: compiled
        _plain_pull(np.asarray(q, dtype=float), np.asarray(targets, dtype=float), np.asarray(weights, dtype=float),
                    pull)
        return pull
    wrap = _wrapping(robot, keep)
    for k, target in zip(weights, targets, strict=True):
        pull += k * _wrapped(robot, q, target, wrap)
    return pull


@numba.njit(cache=True, nogil=True)
def _plain_pull(q: Array, targets: Array, weights: Array, pull: Array) -> None:  # pragma: no cover - compiled
    """``pull += Σ_i k_i (q̃_i − q)`` on zeros: :func:`preview_pull` on an arm whose joints are all 1-dof (there
    ``pin.difference`` is the plain difference) with no index wrapped, in numpy's order of operations (the same bits; a
    test checks them)."""
    for i in range(weights.size):
        for j in range(q.size):
            pull[j] += weights[i] * (targets[i, j] - q[j])


class AmsipGradient:
    """``v = K_g ∇_q S``: the local null-space ascent of the AMSIP (eq. 18).

    ``∇S`` is taken in the tangent space by central differences,
    ``∂S/∂q_j ≈ (S(q ⊕ h e_j) − S(q ⊖ h e_j)) / 2h``, all ``2 nv`` configurations evaluated in one batch
    with the scene at time ``t``.

    Args:
        robot: the arm.
        evaluator: the AMSIP evaluator of the scene.
        params: ``gradient_gain`` (``K_g``) and ``fd_step`` (``h`` [rad]).
    """

    def __init__(self, robot: Robot, evaluator: Evaluator, params: ControllerParams) -> None:
        self.robot, self.evaluator, self.step = robot, evaluator, params.fd_step
        self.gain = gain_vector(params.gradient_gain, robot.nv, "gradient_gain")
        """``K_g`` ``(nv,)`` [rad²/s per unit of S]."""

    def gradient(self, q: Array, t: float) -> Array:
        """``∇_q S`` at ``q`` ``(nq,)`` and time ``t`` [s], shape ``(nv,)`` [1/rad]."""
        h, nv, model = self.step, self.robot.nv, self.robot.model
        steps = np.concatenate([np.eye(nv), -np.eye(nv)]) * h
        batch = np.stack([pin.integrate(model, q, d) for d in steps])
        S = self.evaluator(batch, t, exact_below=POTENTIAL_ONLY).S
        return np.asarray((S[:nv] - S[nv:]) / (2.0 * h))

    def __call__(self, q: Array, t: float) -> Array:
        """``v = K_g ∇_q S`` ``(nv,)`` [rad/s] at ``q`` ``(nq,)`` and time ``t`` [s]."""
        return np.asarray(self.gain * self.gradient(q, t))
