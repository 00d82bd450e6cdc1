"""Eq. 19 as built: damped resolved-rate tracking of the hand with a null-space input ``v``,

    q̇ = J#(ṙ_d + K_p (r_d − r)) + (I − J⁺J) v.

Details:

* Step correction (``step_correction``, on by default): the command is held for a period ``dt``, over which
  the hand also moves by second-order terms (the null-space motion is null for ``J`` at ``q`` only) and the
  path may turn. The task velocity is therefore corrected by ``(e⁺ − exp(−K_p dt) e) / dt``, ``e⁺`` the error
  predicted at ``t + dt`` by forward kinematics of ``q ⊕ q̇ dt`` (:func:`step_correction`, applied
  :data:`STEP_ITERATIONS` times): the step then leaves the error the continuous law would. Without it,
  ``K_p = 5/s`` and a 1 rad/s null-space motion at ``dt = 10 ms`` hold the planar arm's hand about a
  millimetre off its path.
* ``J`` is the task Jacobian (planar: 2 rows, position: 3, pose: 6 -- linear then angular, world
  aligned). For a pose task the error is ``[p_d − p; log3(R_d Rᵀ)]`` and ``ṙ_d = [ṗ_d; 0]``.
* ``J#`` is a damped least-squares inverse: with ``J = U Σ Vᵀ`` and ``σ_min`` its smallest singular
  value, ``J# = V diag(σ / (σ² + λ²)) Uᵀ`` where

      λ² = 0                                   if σ_min ≥ ε,
      λ² = (1 − (σ_min / ε)²) λ_max²           otherwise                (Maciejewski & Klein),

  ``ε = singular_threshold`` [m/rad] and ``λ_max = damping`` [m/rad]. Away from singularities this is
  the exact pseudo-inverse; near one the damping grows smoothly and keeps ``q̇`` bounded.
* The null-space projector ``N = I − J⁺J`` uses the *undamped* pseudo-inverse, so ``J N v = 0``
  exactly: the null-space term never moves the hand.
* Task priority: the null-space term is first scaled by the largest ``α`` in [0, 1] for which
  ``q̇_task + α N v`` respects the speed limits (``α = 0`` if ``q̇_task`` alone does not), so the
  avoidance motion never slows the hand down; ``α`` is reported as ``null_scale``.
* Limits: every ``q̇_j`` must lie in the box ``[max((lo_j − q_j)/dt, −q̇max_j), min((hi_j − q_j)/dt,
  q̇max_j)]`` (:func:`velocity_box`: ``q + q̇ dt`` stays within the position limits, ``|q̇_j|`` within
  ``velocity_scale · q̇max_j``; a non-finite or non-positive URDF speed limit counts as no limit).
  When the command above is inside the box it is applied unchanged. Otherwise the task is re-solved
  by saturation in the null space (:mod:`previewctl.control.saturation`, Flacco et al. 2012): the
  joint that leaves the box first is fixed at its bound and the task is solved again with the other
  joints, repeatedly; if they cannot achieve it, the task velocity is scaled down along its direction
  (``scale`` < 1). The null-space term is then projected on the free joints and scaled into the box.
* Limit avoidance: ``v`` gets the term of :func:`limit_avoidance`, which pushes a joint away from a
  position limit once it is within ``limit_margin`` of its range, before the box is ever reached.
* For the preview modes the configuration error is taken in the tangent space,
  ``v = K_v Σ_i k_i (q̃_i ⊖ q)`` (``pin.difference``), which equals eq. 21 for ordinary joints because
  ``Σ k_i = 1``; for revolute joints whose range spans a full turn or more, each difference is
  wrapped into ``(−π, π]`` (the same physical target, reached the short way).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from previewctl.control.base import ControlInfo, ControlState
from previewctl.control.params import ControllerParams
from previewctl.control.saturation import saturate
from previewctl.errors import ParameterError
from previewctl.index.amsi import null_space_projector
from previewctl.kinematics import hand_placement
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.types import Array

# ------------------------------------------------------------------------------------ eq. 19

STEP_ITERATIONS = 2
"""Corrections of eq. 19's step per cycle (Gauss-Newton on the predicted error). Measured on the Panda with
1.7 rad/s of null-space motion, the step misses by 0.7 mm without, 6 µm after one and 0.01 µm after two."""


def damped_pseudo_inverse(J: Array, damping: float, threshold: float) -> tuple[Array, float]:
    """Damped least-squares inverse ``J#`` of ``J`` ``(m, n)`` and the damping ``λ`` used.

    ``λ² = (1 − (σ_min/ε)²) λ_max²`` when ``σ_min < ε``, else 0 (see the module docstring).

    Args:
        J: the Jacobian.
        damping: ``λ_max`` [same unit as J's singular values].
        threshold: ``ε`` > 0.

    Returns:
        ``(J#, λ)``: ``J#`` of shape ``(n, m)``.
    """
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    smin = float(s[-1]) if s.size else 0.0
    lam2 = damping**2 * (1.0 - (smin / threshold) ** 2) if smin < threshold else 0.0
    denom = s**2 + lam2
    inv = np.divide(s, denom, out=np.zeros_like(s), where=denom > 0)
    return (Vt.T * inv) @ U.T, math.sqrt(lam2)


def joint_velocity_bounds(robot: Robot, q: Array, dt: float) -> tuple[Array, Array]:
    """Per-velocity-coordinate bounds that keep ``q + q̇ dt`` within the position limits.

    Coordinates without a finite limit (continuous joints among them) get ``−inf`` / ``inf`` on that side.

    Args:
        robot: the arm.
        q: configuration ``(nq,)``.
        dt: control period [s].

    Returns:
        ``(low, high)`` [rad/s], each ``(nv,)``.
    """
    facts = robot.joints
    position = np.asarray(q, dtype=float)[facts.q_index]  # continuous coordinates (index -1) are unused
    low = np.where(np.isfinite(facts.lower), (facts.lower - position) / dt, -np.inf)
    high = np.where(np.isfinite(facts.upper), (facts.upper - position) / dt, np.inf)
    return low, high


def effective_velocity_limits(robot: Robot, scale: float = 1.0) -> Array:
    """``scale`` × the URDF speed limits [rad/s], ``inf`` where the URDF gives none (≤ 0 or non-finite)."""
    limits = robot.joints.velocity
    return np.where(np.isfinite(limits) & (limits > 0), limits * scale, np.inf)


def velocity_box(robot: Robot, q: Array, dt: float, velocity_scale: float = 1.0) -> tuple[Array, Array]:
    """Bounds ``low <= q̇ <= high`` [rad/s] of one period: position limits over ``dt`` and speed limits.

    Each side is kept on its side of 0 (a joint found past a limit may stop, not be pushed further out).

    Args:
        robot: the arm.
        q: configuration ``(nq,)``.
        dt: control period [s].
        velocity_scale: fraction of the URDF speed limits allowed.

    Returns:
        ``(low, high)``, each ``(nv,)``.
    """
    low, high = joint_velocity_bounds(robot, q, dt)
    speed = effective_velocity_limits(robot, velocity_scale)
    return np.minimum(np.maximum(low, -speed), 0.0), np.maximum(np.minimum(high, speed), 0.0)


def limit_avoidance(robot: Robot, q: Array, params: ControllerParams) -> Array:
    """Null-space input [rad/s] ``(nv,)`` that steers away from position limits before they are hit.

    ``−K_l ∇H`` of ``H = ½ Σ_j max(0, ρ_j − d_j)²`` over both limits of each joint with finite limits,
    ``d_j`` the distance to the limit [rad] and ``ρ_j = limit_margin · (hi_j − lo_j)``: zero unless a
    joint is within ``ρ_j`` of a limit, then ``K_l`` [1/s] times how deep it is in that margin.
    """
    facts = robot.joints
    position = np.asarray(q, dtype=float)[facts.q_index]
    bounded = np.isfinite(facts.lower) & np.isfinite(facts.upper)
    margin = np.where(bounded, params.limit_margin * (facts.upper - facts.lower), 0.0)
    with np.errstate(invalid="ignore"):
        push_up = np.where(bounded, np.maximum(0.0, margin - (position - facts.lower)), 0.0)
        push_down = np.where(bounded, np.maximum(0.0, margin - (facts.upper - position)), 0.0)
    return np.asarray(params.limit_gain * (push_up - push_down), dtype=float)


def null_space_budget(qdot_task: Array, qdot_null: Array, limits: Array) -> float:
    """Largest ``α`` in [0, 1] with ``|q̇_task,j + α q̇_null,j| <= limit_j`` for every joint (task priority).

    0 when the task term alone already breaks a limit (the uniform scaling then handles it).

    Args:
        qdot_task: the tracking term [rad/s], ``(nv,)``.
        qdot_null: the null-space term [rad/s], ``(nv,)``.
        limits: joint speed limits [rad/s] (``inf`` = none), ``(nv,)``.
    """
    if np.any(np.abs(qdot_task) > limits):
        return 0.0
    alpha = 1.0
    for a, b, lim in zip(qdot_task, qdot_null, limits, strict=True):
        if np.isfinite(lim) and abs(a + b) > lim and b != 0.0:
            alpha = min(alpha, (math.copysign(lim, b) - a) / b)
    return max(0.0, alpha)


def task_target(robot: Robot, path: HandPath, t: float) -> tuple[Array, Array]:
    """Desired hand position and velocity at ``t`` [s], padded to 3-D: ``((3,) [m], (3,) [m/s])``."""
    p, v = np.zeros(3), np.zeros(3)
    d = path.dim
    p[:d], v[:d] = path.position(t), path.velocity(t)
    return p, v


def task_error(robot: Robot, path: HandPath, r_d: Array, tip: Array, rotation: Array) -> Array:
    """The task error ``e`` of eq. 19: ``r_d − r`` [m] over the task's rows, and for a pose task also the
    orientation error ``log3(R_d Rᵀ)`` [rad] (``R_d`` = the path's orientation, or the hand's own if it has none)."""
    if robot.task == "pose":
        R_d = path.orientation if path.orientation is not None else rotation
        return np.concatenate([r_d - tip, pin.log3(R_d @ rotation.T)])
    return (r_d - tip)[robot.task_rows]


def step_correction(
    robot: Robot, t: float, q: Array, state: ControlState, qdot: Array, error: Array, params: ControllerParams
) -> Array:
    """What to add to eq. 19's task velocity [m/s, rad/s] so that ``qdot`` held for ``dt`` leaves the error the
    continuous law would: ``(e(t + dt) − exp(−K_p dt) e(t)) / dt``, with ``e(t + dt)`` predicted by forward
    kinematics at ``q ⊕ q̇ dt``.

    Holding eq. 19's command over a period misses the path by the hand's second-order motion (the null-space
    motion is null for ``J`` at ``q`` only) and by the path's own turns within the period; both are removed to
    first order, at the cost of one forward kinematics per call.
    """
    dt = state.dt
    data = state.data if state.data is not None else robot.model.createData()
    tip, rotation = hand_placement(robot, pin.integrate(robot.model, q, qdot * dt), data)
    r_d = task_target(robot, state.path, t + dt)[0]
    predicted = task_error(robot, state.path, r_d, tip, rotation)
    return np.asarray((predicted - math.exp(-params.feedback_gain * dt) * error) / dt, dtype=float)


def track(
    robot: Robot,
    t: float,
    q: Array,
    state: ControlState,
    v: Array,
    params: ControllerParams,
    targets: Array | None = None,
    target_amsip: Array | None = None,
) -> tuple[Array, ControlInfo]:
    """Eq. 19 with feedback, damping and limits for a given null-space input ``v`` ``(nv,)``.

    Args:
        robot: the arm.
        t: time [s].
        q: configuration ``(nq,)``.
        state: kinematics of ``q`` and the path.
        v: null-space input [rad/s].
        params: gains, damping, limits.
        targets: imaginary arms to report (preview modes).
        target_amsip: their AMSIP values.

    Returns:
        ``(q̇, info)``.
    """
    kin = state.kin
    J = kin.J_task[0]
    r_d, rdot_d = task_target(robot, state.path, t)
    tip = kin.tip_position[0]
    error = task_error(robot, state.path, r_d, tip, kin.tip_rotation[0])
    feedforward = np.concatenate([rdot_d, np.zeros(3)]) if robot.task == "pose" else rdot_d[robot.task_rows]
    xdot = feedforward + params.feedback_gain * error
    J_sharp, lam = damped_pseudo_inverse(J, params.damping, params.singular_threshold)
    v_total = np.asarray(v, dtype=float) + limit_avoidance(robot, q, params)
    qdot_null = null_space_projector(J) @ v_total
    limits = effective_velocity_limits(robot, params.velocity_scale)
    qdot_task = J_sharp @ xdot
    null_scale = null_space_budget(qdot_task, qdot_null, limits)
    for _ in range(STEP_ITERATIONS if params.step_correction else 0):
        xdot = xdot + step_correction(robot, t, q, state, qdot_task + null_scale * qdot_null, error, params)
        qdot_task = J_sharp @ xdot
        null_scale = null_space_budget(qdot_task, qdot_null, limits)
    requested = qdot_task + null_scale * qdot_null
    low, high = velocity_box(robot, q, state.dt, params.velocity_scale)
    qdot, scale, clamped = requested, 1.0, False
    if not np.all((requested >= low) & (requested <= high)):
        sat = saturate(J, xdot, v_total, low, high,
                       lambda A: damped_pseudo_inverse(A, params.damping, params.singular_threshold)[0])
        qdot, scale, null_scale, clamped = sat.qdot, sat.task_scale, sat.null_scale, bool(sat.saturated.any())
    info = ControlInfo(
        desired_position=r_d,
        desired_velocity=rdot_d,
        hand_position=tip,
        task_error=error,
        v=v_total,
        qdot_task=qdot_task,
        qdot_null=qdot_null,
        qdot_requested=requested,
        null_scale=null_scale,
        scale=scale,
        clamped=clamped,
        damping=lam,
        dt=state.dt,
        frame_due=state.frame_due,
        targets=targets,
        target_amsip=target_amsip,
    )
    return qdot, info


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


# ------------------------------------------------------------------------------- controllers


class TrackingController:
    """``none``: eq. 19 with ``v = 0`` (minimum-norm hand tracking); ``qp``: the same law, always executed by
    the constrained QP (the controller built by :func:`~previewctl.control.factory.make_controller` sees to it)."""

    def __init__(self, robot: Robot, params: ControllerParams | None = None, name: str = "none") -> None:
        self.robot, self.params, self.name = robot, params or ControllerParams(), name

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]; see :func:`track`."""
        return track(self.robot, t, q, state, np.zeros(self.robot.nv), self.params)
