"""Executions: eq. 19's reference turned into the joint velocity applied, within the joint limits.

Every :class:`~previewctl.control.controller.Controller` has one (:class:`~previewctl.control.base.Execution`):

* :class:`PseudoInverseExecution` (the paper's eq. 19): the reference ``q̇_task + α N v`` (``α`` the
  task-priority budget) is applied unchanged when it is inside the box of one period
  (:func:`~previewctl.control.tracking.velocity_box`: ``q + q̇ dt`` within the position limits, ``|q̇_j|`` within
  the speed limits). Otherwise the task is re-solved by saturation in the null space
  (:mod:`previewctl.control.saturation`, Flacco et al. 2012): the joint that leaves the box first is fixed at its
  bound and the task is solved again with the other joints, repeatedly; if they cannot achieve it, the task
  velocity is scaled down along its direction (``scale`` < 1). The null-space term is then projected on the free
  joints and scaled into the box. Obstacles are not seen here: only the law's null-space input keeps the links
  clear.
* :class:`QPExecution`: eq. 19 as a constrained QP: hand task first, the law's null-space motion second, and
  constraints that keep every guarded link clear of the obstacles (the velocity dampers of Faverjon &
  Tournassoud, as in NEO) and every joint inside its limits. The rest of this docstring is about it.

With ``q̇_ref = J#(ṙ_d + K_p e) + N v`` the command of eq. 19 (the mode's null-space input ``v``: a
preview pull, a gradient or zero), the QP is

    minimise    W ‖J (q̇ − q̇_ref)‖² + ‖q̇ − q̇_ref‖²
    subject to  lb ≤ q̇ ≤ ub                                              (joint speed and position limits)
                n_kᵀ J_k q̇ ≤ ξ (d_k − d_s)/(d_i − d_s) + n_kᵀ v_obs,k      (one damper per pair with d_k < d_i)
                n_kᵀ (J_a,k − J_b,k) q̇ ≤ ξ (d_k − d_s')/(d_i' − d_s')      (one per self pair with d_k < d_i')

* Weights: the hand term has weight ``W = task_weight`` (10⁴ by default) and the joint term weight 1.
  Both terms vanish at ``q̇ = q̇_ref``, so when ``q̇_ref`` meets every constraint it is the QP's solution:
  it is returned as it is, without calling the solver (most cycles), and the paper's controller is the
  unconstrained case exactly. When a constraint binds, the joints give way first: a hand deviation costs
  ``W`` times more than the same joint-space deviation, so the hand keeps its priority while the
  null-space motion yields.
* Dampers: ``d_k`` [m] is the Coal distance of pair ``k`` (guarded geometry, obstacle), ``n_k`` the unit
  normal from the robot's nearest point ``p_k`` towards the obstacle's, ``J_k`` the Jacobian of ``p_k``
  (a point fixed on its link) and ``v_obs,k`` the obstacle's velocity [m/s] from its known motion (the
  motions translate the obstacles, so all their points share it). The row states
  ``ḋ_k ≥ −ξ (d_k − d_s)/(d_i − d_s)``: inside the influence distance ``d_i`` the approach speed falls
  linearly to zero at the safety distance ``d_s``.
* Self dampers: a self pair (:mod:`previewctl.robot.self_pairs`) joins two links that both move. With ``p_a``,
  ``p_b`` its nearest points (fixed on their links) and ``n_k`` the unit normal from ``a`` to ``b``, the distance
  changes at ``ḋ_k = n_kᵀ (J_b − J_a) q̇``; the row states ``ḋ_k ≥ −ξ (d_k − d_s')/(d_i' − d_s')`` with the self
  pairs' own ``d_i' = self_influence_distance`` and ``d_s' = self_safety_distance``.
* Joint limits: the speed limits ``±velocity_scale · q̇max``; within ``limit_margin`` (a fraction of the
  joint's range) of a position limit, the speed towards it shrinks linearly to zero at the limit (the joint
  brakes in time), and never exceeds ``(limit − q)/dt``. A joint held at a limit is *saturated*: the QP
  re-solves the hand task with the other joints, which is saturation in the null space (Flacco et al. 2012)
  done by the solver.
* Step correction: ``q̇_ref`` already carries eq. 19's correction for the period it is held over
  (:func:`~previewctl.control.tracking.step_correction`), computed for the law's own command. When a
  constraint binds, the QP executes another ``q̇``, so the hand term's target is corrected again for the
  QP's solution (the same two Gauss-Newton corrections, each a re-solve).
* Infeasible constraints (e.g. an obstacle faster than the arm): safety comes before the hand. A first QP
  finds the smallest damper violations the joint bounds allow (one slack ``s_k ≥ 0`` per row, cost
  ``slack_weight · s_k²`` plus the joint term, without the hand term), and the task QP is solved with each
  row loosened by its slack. The largest slack [m/s] is reported. (Penalising the slacks inside the task QP
  instead lets the hand term buy a deeper approach: docs/decisions.md#damper-slacks-in-a-qp-of-their-own.)

The solver is DAQP through ``qpsolvers``: a dense active-set method for small QPs, with wheels on PyPI for
every CI platform, about 30 µs per solve at these sizes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import pinocchio as pin
import qpsolvers

from previewctl.control.base import ControlState, Executed, Reference
from previewctl.control.params import ControllerParams
from previewctl.control.saturation import saturate
from previewctl.control.tracking import (
    STEP_ITERATIONS,
    damped_pseudo_inverse,
    desired_position,
    effective_velocity_limits,
    step_correction,
    velocity_box,
)
from previewctl.kinematics import support_mask
from previewctl.robot.model import Robot
from previewctl.scene.clearance import Clearance
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Scene
from previewctl.types import Array, IntArray

SOLVER = "daqp"
_CYCLE = np.array([1, 2, 0])
_CYCLE2 = np.array([2, 0, 1])
_OBSTACLE_DT = 1e-3  # [s] forward difference of the obstacles' placements
_ACTIVE_TOL = 1e-9  # [rad/s], [m/s]: a constraint within this of its bound counts as active


@dataclass(frozen=True)
class Dampers:
    """The collision rows ``G q̇ ≤ h`` of one cycle (pairs inside their influence distance only): the obstacle
    pairs' rows first, then the self pairs'.

    Attributes:
        G: ``(R, nv)`` rows ``n_kᵀ J_k`` (obstacle pairs), ``n_kᵀ (J_a,k − J_b,k)`` (self pairs).
        h: ``(R,)`` bounds [m/s].
        distance: ``(R,)`` the pairs' distances [m].
        pairs: indices of the obstacle rows' pairs in the :class:`~previewctl.scene.clearance.Clearance`.
        self_pairs: indices of the self rows' pairs in ``robot.self_pairs``.
    """

    G: Array
    h: Array
    distance: Array
    pairs: IntArray
    self_pairs: IntArray


def _cross(a: Array, b: Array) -> Array:
    """Row-wise cross products of ``(R, 3)`` arrays (``np.cross`` costs more than the rows for small ``R``)."""
    return a[:, _CYCLE] * b[:, _CYCLE2] - a[:, _CYCLE2] * b[:, _CYCLE]


class PseudoInverseExecution:
    """Executes eq. 19's reference with clamping and saturation in the null space (module docstring).

    Args:
        robot: the arm.
        params: ``velocity_scale``, ``damping`` and ``singular_threshold`` (the saturation's damped inverse).
    """

    name = "pseudoinverse"

    def __init__(self, robot: Robot, params: ControllerParams) -> None:
        self.robot, self.params = robot, params

    def _inverse(self, A: Array) -> Array:
        return damped_pseudo_inverse(A, self.params.damping, self.params.singular_threshold)[0]

    def __call__(self, state: ControlState, reference: Reference) -> Executed:
        """The applied ``q̇`` [rad/s]: the reference if it is inside the box, else its saturation."""
        requested = reference.qdot_task + reference.budget * reference.qdot_null
        low, high = velocity_box(self.robot, state.q, state.dt, self.params.velocity_scale)
        if np.all((requested >= low) & (requested <= high)):
            return Executed(requested, requested, reference.budget, 1.0, False, state.dt, self.name)
        sat = saturate(reference.J, reference.xdot, reference.v, low, high, self._inverse)
        return Executed(sat.qdot, requested, sat.null_scale, sat.task_scale, bool(sat.saturated.any()), state.dt,
                        self.name)


class QPExecution:
    """Executes eq. 19's reference as the constrained QP of the module docstring.

    Args:
        robot: the arm (its collision geometry: convex hulls or capsules).
        scene: the obstacles.
        params: the QP settings (``task_weight``, ``slack_weight``, ``damper_gain``, ``influence_distance``,
            ``safety_distance``, ``limit_margin``, ``velocity_scale``).
    """

    name = "qp"

    def __init__(self, robot: Robot, scene: Scene, params: ControllerParams) -> None:
        self.robot, self.scene, self.params = robot, scene, params
        self.clearance = Clearance(robot, scene)
        self.data = robot.model.createData()
        facts = robot.joints
        speed = effective_velocity_limits(robot, params.velocity_scale)
        self._speed = np.where(np.isfinite(speed), speed, 1e3)  # [rad/s] a finite box for the solver
        self._index, self._upper, self._lower = facts.q_index, facts.upper, facts.lower
        with np.errstate(invalid="ignore"):
            margin = params.limit_margin * (facts.upper - facts.lower)  # inf or nan for unlimited joints
        braking = np.isfinite(margin) & (margin > 0)
        self._brake_rate = np.where(braking, self._speed / np.where(braking, margin, 1.0), np.inf)  # [1/s]
        self._identity = np.eye(robot.nv)
        self._joint_J = self.data.J  # a view on the C++ buffer, refreshed by every computeJointJacobians
        self._pair_support = support_mask(robot.model, self.clearance.pair_joints)  # the columns that move each pair
        self_clearance = self.clearance.self_clearance
        self._self_support = (support_mask(robot.model, self_clearance.joint_a),
                              support_mask(robot.model, self_clearance.joint_b))
        self._no_rows = np.zeros((0, robot.nv))  # read only: the rows of a cycle without a pair within reach
        self._no_rows.flags.writeable = False
        self._no_pairs = np.zeros(0, dtype=int)
        self._no_pairs.flags.writeable = False
        self._velocities = np.zeros((len(scene.obstacles), 3))
        self._velocity_time = np.nan
        self._velocity_revisions = self.clearance.revisions()

    def dampers(self, q: Array, t: float, joint_data: pin.Data | None = None) -> Dampers:
        """The damper rows at configuration ``q`` ``(nq,)`` and time ``t`` [s]; ``joint_data``: a ``Data`` that holds
        the joint placements and Jacobians at ``q`` already (the cycle's ``ControlState.joint_data``), else they are
        computed."""
        p = self.params
        if joint_data is None:
            pin.computeJointJacobians(self.robot.model, self.data, q)
            data, J = self.data, self._joint_J
        else:
            data, J = joint_data, joint_data.J
        self.clearance.set_time(t)
        near, w = self.clearance.witnesses(data, within=p.influence_distance)
        if near.size:
            # data.J holds each joint's motion in the world frame, (v at the world origin; ω); a point p fixed on
            # a link moves at v + ω × p under the joints that support the link, so n·ṗ = n·v + (p × n)·ω
            G = (w.normal @ J[:3] + _cross(w.robot_point, w.normal) @ J[3:]) * self._pair_support[near]
            obstacle_velocity = self._obstacle_velocities(t)[self.clearance.pair_obstacles[near]]
            obstacle_speed = (w.normal * obstacle_velocity).sum(axis=1)
            approach = p.damper_gain * (w.distance - p.safety_distance) / (p.influence_distance - p.safety_distance)
            h = approach + obstacle_speed
        else:  # no pair within reach: no row (most cycles)
            G, h = self._no_rows, w.distance
        if not len(self.robot.self_pairs):
            return Dampers(G, h, w.distance, near, self._no_pairs)
        s = self.clearance.self_witnesses(data, within=p.self_influence_distance)
        if not s.pairs.size:
            return Dampers(G, h, w.distance, near, s.pairs)
        support_a, support_b = self._self_support[0][s.pairs], self._self_support[1][s.pairs]
        G_self = ((s.normal @ J[:3] + _cross(s.point_a, s.normal) @ J[3:]) * support_a
                  - (s.normal @ J[:3] + _cross(s.point_b, s.normal) @ J[3:]) * support_b)
        h_self = p.damper_gain * (s.distance - p.self_safety_distance) / (p.self_influence_distance
                                                                          - p.self_safety_distance)
        return Dampers(np.vstack([G, G_self]), np.concatenate([h, h_self]),
                       np.concatenate([w.distance, s.distance]), near, s.pairs)

    def _obstacle_velocities(self, t: float) -> Array:
        """Velocities [m/s] ``(O, 3)`` of the obstacles at time ``t`` [s]: the motions translate the obstacles (their
        rotation is fixed), so every point of an obstacle has its obstacle's; a predicted obstacle's are its
        prediction's, read again after each new observation."""
        revisions = self.clearance.revisions()
        if t != self._velocity_time or revisions != self._velocity_revisions:
            for k, obstacle in enumerate(self.scene.obstacles):
                if not isinstance(obstacle.motion, Static):
                    positions = obstacle.motion.positions(np.array([t, t + _OBSTACLE_DT]))
                    self._velocities[k] = (positions[1] - positions[0]) / _OBSTACLE_DT
            self._velocity_time, self._velocity_revisions = t, revisions
        return self._velocities

    def bounds(self, q: Array, dt: float) -> tuple[Array, Array]:
        """Joint velocity bounds [rad/s] ``(nv,)`` each: speed limits, braking near the position limits.

        Towards a limit at distance ``a ≥ 0`` the bound is ``min(q̇max, q̇max · a / margin, a / dt)``, i.e.
        ``min(q̇max, a · min(q̇max / margin, 1 / dt))``; a joint without limits (``a = ∞``) keeps ``q̇max``.
        """
        lower, upper = np.empty(self._index.size), np.empty(self._index.size)
        _braking_bounds(np.asarray(q, dtype=float), self._index, self._lower, self._upper, self._speed,
                        self._brake_rate, 1.0 / dt, lower, upper)
        return lower, upper

    def __call__(self, state: ControlState, reference: Reference) -> Executed:
        """The executed ``q̇`` [rad/s] for eq. 19's reference ``q̇_ref = q̇_task + N v``, and the QP's report."""
        t, q = state.t, state.q
        requested = reference.qdot_task + reference.qdot_null
        lower, upper = self.bounds(q, state.dt)
        rows = self.dampers(q, t, state.joint_data)
        slack = 0.0
        if _inside(requested, lower, upper) and (not rows.h.size or (rows.G @ requested <= rows.h).all()):
            qdot = requested.copy()  # the cost's minimum (0, at q̇_ref) is feasible: it is the QP's solution
        else:
            J, W = reference.J, self.params.task_weight
            P = W * (J.T @ J) + self._identity
            c = -P @ requested
            qdot, slack = self._solve(P, c, rows, lower, upper)
            # the reference corrected eq. 19's step for the q̇ it asked for; the QP runs another: correct for that
            iterations = STEP_ITERATIONS if self.params.step_correction else 0
            r_next = desired_position(state.path, t + state.dt) if iterations else None
            for _ in range(iterations):
                c = c - W * (J.T @ step_correction(self.robot, state, qdot, reference.task_error, self.params, r_next))
                qdot, slack = self._solve(P, c, rows, lower, upper)
        active = int(np.count_nonzero(rows.G @ qdot >= rows.h - _ACTIVE_TOL)) if rows.h.size else 0
        clamped = _clamped(qdot, lower, upper, _ACTIVE_TOL)
        return Executed(qdot, requested, 1.0, 1.0, clamped, state.dt, self.name, dampers=int(rows.h.size),
                        active_dampers=active, slack=slack)

    def _solve(self, P: Array, c: Array, rows: Dampers, lower: Array, upper: Array) -> tuple[Array, float]:
        """The QP ``min ½ q̇ᵀPq̇ + cᵀq̇`` under the bounds and the dampers, softened if infeasible: ``(q̇, max slack)``."""
        solved = qpsolvers.solve_qp(P, c, rows.G, rows.h, lb=lower, ub=upper, solver=SOLVER)
        slack = 0.0
        if solved is None:
            solved, slack = self._soft(P, c, rows, lower, upper)
        return np.clip(solved, lower, upper), slack  # the solver meets the box to ~1e-15; make it exact

    def _soft(self, P: Array, c: Array, rows: Dampers, lower: Array, upper: Array) -> tuple[Array, float]:
        """The dampers cannot all hold: the links' safety first, then the hand. ``(q̇, max s)``.

        1. The smallest damper violation the joint bounds allow: one slack ``s_k ≥ 0`` [m/s] per row, minimise
           ``slack_weight ‖s‖² + ‖q̇ − q̇_ref‖²`` (the hand task is left out, so it cannot buy a deeper approach).
        2. The task QP with each row loosened by its slack, ``G q̇ ≤ h + s``.
        """
        nv, R = c.size, rows.h.size
        P_soft = np.zeros((nv + R, nv + R))
        P_soft[:nv, :nv] = self._identity
        P_soft[nv:, nv:] = self.params.slack_weight * np.eye(R)
        reference = -np.linalg.solve(P, c)  # the task QP's unconstrained minimiser
        G = np.hstack([rows.G, -np.eye(R)])
        x = qpsolvers.solve_qp(P_soft, np.concatenate([-reference, np.zeros(R)]), G, rows.h,
                               lb=np.concatenate([lower, np.zeros(R)]), ub=np.concatenate([upper, np.full(R, 1e3)]),
                               solver=SOLVER)
        if x is None:  # not expected (q̇ = 0 with s = max(0, −h) is feasible); stop rather than guess
            return np.zeros(nv), float(np.max(-rows.h, initial=0.0))
        slack = x[nv:]
        solved = qpsolvers.solve_qp(P, c, rows.G, rows.h + slack + _ACTIVE_TOL, lb=lower, ub=upper, solver=SOLVER)
        return (x[:nv] if solved is None else solved), float(slack.max(initial=0.0))


@numba.njit(cache=True, nogil=True)
def _braking_bounds(q: Array, index: IntArray, low: Array, high: Array, speed: Array, brake_rate: Array,
                    inverse_dt: float, lower: Array, upper: Array) -> None:  # pragma: no cover - compiled
    """:meth:`QPExecution.bounds` into ``lower`` and ``upper``, one compiled loop (``np.minimum``/``np.maximum`` as
    numpy takes them, signed zeros included)."""
    for j in range(index.size):
        position = q[index[j]]
        rate = brake_rate[j] if brake_rate[j] <= inverse_dt else inverse_dt
        room = high[j] - position
        room = (room if room >= 0.0 else 0.0) * rate
        upper[j] = speed[j] if speed[j] <= room else room
        room = position - low[j]
        room = (room if room >= 0.0 else 0.0) * rate
        lower[j] = -(speed[j] if speed[j] <= room else room)


@numba.njit(cache=True, nogil=True)
def _inside(qdot: Array, lower: Array, upper: Array) -> bool:  # pragma: no cover - compiled
    """Whether ``lower <= q̇ <= upper`` for every joint (one compiled loop instead of five array operations)."""
    for j in range(qdot.size):  # noqa: SIM110 - numba compiles the loop, not a generator
        if not lower[j] <= qdot[j] <= upper[j]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _clamped(qdot: Array, lower: Array, upper: Array, tolerance: float) -> bool:  # pragma: no cover - compiled
    """Whether a joint's ``q̇`` is within ``tolerance`` of its bound (one compiled loop instead of five array
    operations)."""
    for j in range(qdot.size):  # noqa: SIM110 - numba compiles the loop, not a generator
        if qdot[j] >= upper[j] - tolerance or qdot[j] <= lower[j] + tolerance:
            return True
    return False
