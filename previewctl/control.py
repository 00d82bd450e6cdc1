"""Resolved-rate control of the hand with a null-space input (paper eq. 19) and its preview modes.

Every controller computes the joint velocity of eq. 19 with hand-position feedback,

    q̇ = J#(ṙ_d + K_p (r_d − r)) + (I − J⁺J) v,

and differs only in the null-space input ``v``:

* ``none``: ``v = 0`` (minimum-norm tracking);
* ``gradient``: ``v = K_g ∇_q S`` (local null-space ascent of the AMSIP; ``∇S`` by central finite
  differences of the :class:`~previewctl.amsip.Evaluator`, one batch of ``2 nv`` configurations);
* ``single`` (eq. 20): ``v = K_v (q̃(t + t̃) − q)``;
* ``multi`` (eq. 21): ``v = K_v (Σ_i k_i q̃(t + i t̃) − q)``, ``0 < k_i < 1``, ``Σ k_i = 1``;
* ``reach``: a route of peaks through the future (not built yet).

``with_gradient`` (off by default; not in the paper) adds the local ascent ``K_g ∇_q S`` of
``gradient`` to the null-space input of ``single`` and ``multi``. The preview pull heads for the
imaginary arms' optima, which on a spatial arm may lie radians away. The local term keeps the
current configuration clear of an obstacle meanwhile.

The preview modes get their imaginary arms ``q̃`` from a 1-step GA (:mod:`previewctl.search`), one per
preview time, which runs one generation per camera frame.

Details of eq. 19 as built:

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
* Limits, in this order: (1) position limits -- each ``q̇_j`` is clamped to
  ``[(lo_j − q_j)/dt, (hi_j − q_j)/dt]`` so that ``q + q̇ dt`` stays within the limits (joints with
  ``nq = nv`` and finite limits only); (2) velocity limits -- the whole ``q̇`` is scaled by
  ``s = min(1, min_j q̇max_j / |q̇_j|)``, which keeps its direction and never raises ``|q̇_j|`` above
  ``velocity_scale · q̇max_j``. A non-finite or non-positive URDF speed limit counts as no limit.
  Scaling after clamping keeps the position bounds (the interval contains 0).
* For the preview modes the configuration error is taken in the tangent space,
  ``v = K_v Σ_i k_i (q̃_i ⊖ q)`` (``pin.difference``), which equals eq. 21 for ordinary joints because
  ``Σ k_i = 1``; for revolute joints whose range spans a full turn or more, each difference is
  wrapped into ``(−π, π]`` (the same physical target, reached the short way).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.amsip import Evaluator
from previewctl.avoidance import Kinematics, null_space_projector
from previewctl.errors import ConfigurationError, PreviewctlError
from previewctl.redundancy import wrap_angle
from previewctl.robot import Robot
from previewctl.scene import Scene
from previewctl.trajectory import HandPath

Array = NDArray[np.float64]
ControllerName = Literal["none", "gradient", "single", "multi", "reach"]
CONTROLLER_NAMES: tuple[str, ...] = ("none", "gradient", "single", "multi", "reach")
PREVIEW_MODES: tuple[str, ...] = ("single", "multi", "reach")
PAPER_WEIGHTS: tuple[float, ...] = (0.3, 0.65, 0.05)
"""The paper's three-preview weights ``k_1, k_2, k_3`` (section 7.2)."""

_WEIGHT_SUM_TOL = 1e-9


def check_preview_weights(weights: object, where: str = "weights") -> tuple[float, ...]:
    """Validate the multi-preview weights ``k_i`` of eq. 21.

    Args:
        weights: a sequence of numbers.
        where: the name used in messages (e.g. ``"controller.weights"``).

    Returns:
        The weights as a tuple of floats.

    Raises:
        ConfigurationError: not a non-empty list of numbers, some ``k_i`` outside ``(0, 1)`` or
            ``Σ k_i ≠ 1`` (to 1e-9); the message names the value.
    """
    if (
        isinstance(weights, (str, bytes))
        or not isinstance(weights, Sequence)
        or not weights
        or not all(isinstance(k, (int, float)) and not isinstance(k, bool) for k in weights)
    ):
        raise ConfigurationError(f"{where} must be a non-empty list of numbers k_i, got {weights!r}")
    values = tuple(float(k) for k in weights)
    for i, k in enumerate(values, start=1):
        if not (math.isfinite(k) and 0.0 < k < 1.0):
            hint = "; for one preview use the 'single' controller" if len(values) == 1 else ""
            raise ConfigurationError(f"{where} = {list(values)}: k_{i} = {k!r} must satisfy 0 < k_i < 1{hint}")
    total = math.fsum(values)
    if abs(total - 1.0) > _WEIGHT_SUM_TOL:
        raise ConfigurationError(f"{where} = {list(values)}: the k_i must sum to 1, they sum to {total!r}")
    return values


def _gain_tuple(value: object, where: str) -> tuple[float, ...]:
    """A positive scalar gain as ``(g,)`` or a per-joint gain vector as a tuple."""
    items = (value,) if isinstance(value, (int, float)) and not isinstance(value, bool) else value
    if (
        isinstance(items, (str, bytes))
        or not isinstance(items, Sequence)
        or not items
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items)
    ):
        raise ConfigurationError(f"{where} must be a positive number or a list of positive numbers, got {value!r}")
    out = tuple(float(v) for v in items)
    if not all(math.isfinite(v) and v > 0 for v in out):
        raise ConfigurationError(f"{where} must be positive and finite, got {value!r}")
    return out


def _positive(value: object, where: str, *, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigurationError(f"{where} must be a finite number, got {value!r}")
    if value < 0 or (value == 0 and not allow_zero):
        raise ConfigurationError(f"{where} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return float(value)


def _count(value: object, where: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ConfigurationError(f"{where} must be an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class ControllerParams:
    """Parameters of every controller (each mode reads the ones it needs).

    Attributes:
        gain: ``K_v`` of eqs. 20/21 [1/s]: one number or one per velocity coordinate.
        gradient_gain: ``K_g`` of the ``gradient`` mode, ``v = K_g ∇S`` [rad²/s per unit of S]
            (S is in the index's length unit, ~10⁴ for the paper's arm in cm, hence the small default).
        feedback_gain: ``K_p`` on the hand error [1/s].
        damping: ``λ_max`` of the damped least-squares inverse [m/rad] (0 disables damping).
        singular_threshold: ``ε``: damping starts when ``σ_min(J) < ε`` [m/rad].
        velocity_scale: fraction of the URDF joint speed limits that the controller may use, in (0, 1].
        preview_time: ``t̃`` [s], the spacing of the preview times ``t + i t̃``.
        weights: ``k_i`` of eq. 21 (``multi``; ``single`` uses ``k_1 = 1``); ``0 < k_i < 1``, ``Σ = 1``.
        previews: number of future nodes of the ``reach`` mode.
        population: GA population per imaginary arm.
        elite: GA individuals copied unchanged to the next generation.
        top_k: distinct peaks the GA keeps.
        fd_step: finite-difference step of ``∇S`` [rad].
        ga_options: further keyword arguments for the GA, as ``(name, value)`` pairs.
        with_gradient: ``single``/``multi`` also add ``K_g ∇S`` (``gradient_gain``) to ``v``.
    """

    gain: tuple[float, ...] = (1.0,)
    gradient_gain: tuple[float, ...] = (1e-4,)
    feedback_gain: float = 5.0
    damping: float = 0.05
    singular_threshold: float = 0.05
    velocity_scale: float = 1.0
    preview_time: float = 1.0
    weights: tuple[float, ...] = PAPER_WEIGHTS
    previews: int = 3
    population: int = 64
    elite: int = 2
    top_k: int = 4
    fd_step: float = 1e-4
    ga_options: tuple[tuple[str, Any], ...] = field(default=())
    with_gradient: bool = False

    def __post_init__(self) -> None:
        """Validate every field.

        Raises:
            ConfigurationError: a bad value; the message names the field and the value.
        """
        object.__setattr__(self, "gain", _gain_tuple(self.gain, "gain"))
        object.__setattr__(self, "gradient_gain", _gain_tuple(self.gradient_gain, "gradient_gain"))
        _positive(self.feedback_gain, "feedback_gain", allow_zero=True)
        _positive(self.damping, "damping", allow_zero=True)
        _positive(self.singular_threshold, "singular_threshold")
        if not (_positive(self.velocity_scale, "velocity_scale") <= 1.0):
            raise ConfigurationError(f"velocity_scale must lie in (0, 1], got {self.velocity_scale!r}")
        _positive(self.preview_time, "preview_time")
        object.__setattr__(self, "weights", check_preview_weights(self.weights, "weights"))
        _count(self.previews, "previews", 1)
        _count(self.population, "population", 2)
        _count(self.elite, "elite", 0)
        _count(self.top_k, "top_k", 1)
        _positive(self.fd_step, "fd_step")
        if not isinstance(self.with_gradient, bool):
            raise ConfigurationError(f"with_gradient must be true or false, got {self.with_gradient!r}")
        if self.elite >= self.population:
            raise ConfigurationError(f"elite ({self.elite}) must be smaller than population ({self.population})")

    def preview_weights(self, mode: str) -> tuple[float, ...]:
        """The ``k_i`` used by a preview mode: ``(1,)`` for ``single`` (eq. 20), ``weights`` otherwise."""
        return (1.0,) if mode == "single" else self.weights


@dataclass(frozen=True)
class ControllerSpec:
    """A controller choice: its name (one of :data:`CONTROLLER_NAMES`) and parameters."""

    name: str = "none"
    params: ControllerParams = field(default_factory=ControllerParams)

    def __post_init__(self) -> None:
        """Check the name.

        Raises:
            ConfigurationError: unknown controller name (lists the valid ones).
        """
        if self.name not in CONTROLLER_NAMES:
            raise ConfigurationError(f"unknown controller {self.name!r}; valid: {', '.join(CONTROLLER_NAMES)}")


@dataclass(frozen=True)
class ControlState:
    """What a controller sees at one control cycle.

    Attributes:
        kin: kinematics of the current configuration (batch of one).
        path: the desired hand path.
        scene: the obstacles (query their placement at ``t`` or any future time).
        dt: control period [s].
        frame_due: whether a camera frame arrives at this cycle (GA controllers run a generation).
    """

    kin: Kinematics
    path: HandPath
    scene: Scene
    dt: float
    frame_due: bool


@dataclass(frozen=True)
class ControlInfo:
    """What a controller computed at one cycle.

    Attributes:
        desired_position: ``r_d(t)`` [m], shape ``(3,)`` (z = 0 for planar paths).
        desired_velocity: ``ṙ_d(t)`` [m/s], shape ``(3,)``.
        task_error: the task error fed back (``(m,)``: [m], and [rad] for the pose rows).
        v: the null-space input, shape ``(nv,)``.
        qdot_task: ``J#(ṙ_d + K_p e)`` [rad/s], shape ``(nv,)``.
        qdot_null: ``N v`` [rad/s], shape ``(nv,)``; ``J qdot_null = 0``.
        qdot_requested: ``qdot_task + null_scale · qdot_null``, before the limits [rad/s].
        null_scale: the factor ``α`` in [0, 1] on the null-space term (task priority, see the module docstring).
        scale: the uniform velocity-limit scaling ``s`` in (0, 1].
        clamped: whether a position limit clamped some joint velocity.
        damping: the damping ``λ`` used [m/rad].
        targets: the imaginary arms ``q̃_i``, ``(p, nq)`` (preview modes), else ``None``.
        target_amsip: their AMSIP values ``(p,)`` (preview modes), else ``None``.
    """

    desired_position: Array
    desired_velocity: Array
    task_error: Array
    v: Array
    qdot_task: Array
    qdot_null: Array
    qdot_requested: Array
    null_scale: float
    scale: float
    clamped: bool
    damping: float
    targets: Array | None = None
    target_amsip: Array | None = None


@runtime_checkable
class Controller(Protocol):
    """A joint-velocity controller."""

    name: str

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity ``q̇`` [rad/s] ``(nv,)`` for time ``t`` [s] and configuration ``q`` ``(nq,)``."""
        ...


# ------------------------------------------------------------------------------------ eq. 19


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

    Joints with ``nq ≠ nv`` (continuous) or infinite limits get ``(−inf, inf)``.

    Args:
        robot: the arm.
        q: configuration ``(nq,)``.
        dt: control period [s].

    Returns:
        ``(low, high)`` [rad/s], each ``(nv,)``.
    """
    low, high = np.full(robot.nv, -np.inf), np.full(robot.nv, np.inf)
    lo, hi = robot.lower_limits, robot.upper_limits
    model = robot.model
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.nq != joint.nv:
            continue
        for k in range(joint.nq):
            iq, iv = joint.idx_q + k, joint.idx_v + k
            if np.isfinite(lo[iq]):
                low[iv] = (lo[iq] - q[iq]) / dt
            if np.isfinite(hi[iq]):
                high[iv] = (hi[iq] - q[iq]) / dt
    return low, high


def effective_velocity_limits(robot: Robot, scale: float = 1.0) -> Array:
    """``scale`` × the URDF speed limits [rad/s], ``inf`` where the URDF gives none (≤ 0 or non-finite)."""
    limits = robot.velocity_limits
    return np.where(np.isfinite(limits) & (limits > 0), limits * scale, np.inf)


def apply_limits(
    robot: Robot, q: Array, qdot: Array, dt: float, velocity_scale: float = 1.0
) -> tuple[Array, float, bool]:
    """Enforce position limits (per-joint clamp) then velocity limits (uniform scaling).

    Args:
        robot: the arm.
        q: configuration ``(nq,)``.
        qdot: requested joint velocity ``(nv,)`` [rad/s] (not modified).
        dt: control period [s].
        velocity_scale: fraction of the URDF speed limits allowed.

    Returns:
        ``(q̇, s, clamped)``: the limited velocity, the scaling factor ``s`` in (0, 1] and whether a
        position bound was active.
    """
    low, high = joint_velocity_bounds(robot, q, dt)
    clamped_qdot = np.clip(qdot, low, high)
    clamped = bool(np.any(clamped_qdot != qdot))
    limits = effective_velocity_limits(robot, velocity_scale)
    speed = np.abs(clamped_qdot)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.where(speed > limits, limits / speed, 1.0)
    scale = float(ratios.min()) if ratios.size else 1.0
    return clamped_qdot * scale, scale, clamped


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
    m = J.shape[0]
    if robot.task == "pose":
        R_d = state.path.orientation if state.path.orientation is not None else kin.tip_rotation[0]
        error = np.concatenate([r_d - tip, pin.log3(R_d @ kin.tip_rotation[0].T)])
        feedforward = np.concatenate([rdot_d, np.zeros(3)])
    else:
        error = (r_d - tip)[:m]
        feedforward = rdot_d[:m]
    J_sharp, lam = damped_pseudo_inverse(J, params.damping, params.singular_threshold)
    qdot_task = J_sharp @ (feedforward + params.feedback_gain * error)
    qdot_null = null_space_projector(J) @ v
    null_scale = null_space_budget(qdot_task, qdot_null, effective_velocity_limits(robot, params.velocity_scale))
    requested = qdot_task + null_scale * qdot_null
    qdot, scale, clamped = apply_limits(robot, q, requested, state.dt, params.velocity_scale)
    info = ControlInfo(
        desired_position=r_d,
        desired_velocity=rdot_d,
        task_error=error,
        v=np.array(v, dtype=float),
        qdot_task=qdot_task,
        qdot_null=qdot_null,
        qdot_requested=requested,
        null_scale=null_scale,
        scale=scale,
        clamped=clamped,
        damping=lam,
        targets=targets,
        target_amsip=target_amsip,
    )
    return qdot, info


def _gain_vector(gain: tuple[float, ...], nv: int, where: str) -> Array:
    if len(gain) == 1:
        return np.full(nv, gain[0])
    if len(gain) != nv:
        raise ConfigurationError(f"{where} has {len(gain)} entries; the robot has {nv} joint velocities")
    return np.array(gain)


# ------------------------------------------------------------------------------- controllers


class TrackingController:
    """``none``: eq. 19 with ``v = 0`` (minimum-norm hand tracking)."""

    name = "none"

    def __init__(self, robot: Robot, params: ControllerParams | None = None) -> None:
        self.robot, self.params = robot, params or ControllerParams()

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]; see :func:`track`."""
        return track(self.robot, t, q, state, np.zeros(self.robot.nv), self.params)


class GradientController:
    """``gradient``: ``v = K_g ∇_q S`` -- local null-space ascent of the AMSIP.

    ``∇S`` is taken in the tangent space by central differences,
    ``∂S/∂q_j ≈ (S(q ⊕ h e_j) − S(q ⊖ h e_j)) / 2h``, all ``2 nv`` configurations evaluated in one batch
    with the scene at time ``t``.
    """

    name = "gradient"

    def __init__(self, robot: Robot, evaluator: Evaluator, params: ControllerParams | None = None) -> None:
        self.robot, self.evaluator = robot, evaluator
        self.params = params or ControllerParams()
        self._gain = _gain_vector(self.params.gradient_gain, robot.nv, "gradient_gain")

    def gradient(self, q: Array, t: float) -> Array:
        """``∇_q S`` at ``q`` ``(nq,)`` and time ``t`` [s], shape ``(nv,)`` [1/rad]."""
        h, nv, model = self.params.fd_step, self.robot.nv, self.robot.model
        steps = np.concatenate([np.eye(nv), -np.eye(nv)]) * h
        batch = np.stack([pin.integrate(model, q, d) for d in steps])
        S = self.evaluator(batch, t).S
        return np.asarray((S[:nv] - S[nv:]) / (2.0 * h))

    def null_space_input(self, q: Array, t: float) -> Array:
        """``v = K_g ∇_q S`` ``(nv,)`` [rad/s]."""
        return np.asarray(self._gain * self.gradient(q, t))

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]."""
        return track(self.robot, t, q, state, self.null_space_input(q, t), self.params)


@runtime_checkable
class CandidateLike(Protocol):
    """What a search returns: a configuration ``q`` ``(nq,)`` and its AMSIP ``S``."""

    q: Array
    S: float


@runtime_checkable
class SearchLike(Protocol):
    """The interface of :class:`previewctl.search.OneStepGA` that the preview controller uses."""

    def step(self, target: Array, t: float) -> Any:
        """Run one generation against hand target ``target`` at time ``t`` [s]; return the best candidate."""
        ...

    def peaks(self) -> tuple[Any, ...]:
        """The distinct peaks currently held."""
        ...

    def seed(self, q: Array) -> None:
        """Put configuration ``q`` into the population."""
        ...


def step_searches(searches: Sequence[SearchLike], path: HandPath, times: Sequence[float]) -> list[Any]:
    """One generation of ``searches[i]`` toward the hand target ``path.position(times[i])`` at
    ``times[i]`` [s]; their best candidates. 1-step GAs run through
    :func:`previewctl.search.step_together` (same result, one shared Newton projection)."""
    targets = [np.asarray(path.position(t_i), dtype=float) for t_i in times]
    from previewctl.search import OneStepGA, step_together  # lazy, as the default search factory

    if all(isinstance(search, OneStepGA) for search in searches):
        return step_together([s for s in searches if isinstance(s, OneStepGA)], targets, times)
    return [search.step(target, t_i) for search, target, t_i in zip(searches, targets, times, strict=True)]


def wrapped_difference(robot: Robot, q: Array, target: Array) -> Array:
    """``target ⊖ q`` ``(nv,)``, wrapped into (−π, π] for revolute joints spanning a full turn or more."""
    diff: Array = np.array(pin.difference(robot.model, q, target), dtype=np.float64)
    model = robot.model
    lo, hi = robot.lower_limits, robot.upper_limits
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.nq == 1 and joint.nv == 1 and joint.shortname().startswith(("JointModelR", "JointModelRevolute")):
            iq, iv = joint.idx_q, joint.idx_v
            if hi[iq] - lo[iq] >= 2 * np.pi - 1e-9:
                diff[iv] = (diff[iv] + np.pi) % (2 * np.pi) - np.pi
    return diff


class PreviewController:
    """``single`` (eq. 20) and ``multi`` (eq. 21) preview control.

    One search (an imaginary arm) per preview time ``t_i* = t + i t̃``, ``i = 1..p``. When a camera
    frame is due (and at the first call), each search runs one generation against the hand target
    ``r_d(t_i*)`` and the scene at ``t_i*``; its best candidate is the target ``q̃_i``. Between frames
    the last targets are kept. Then ``v = K_v Σ k_i (q̃_i ⊖ q)`` drives eq. 19.

    Args:
        robot: the arm.
        params: gains and weights.
        mode: ``"single"`` or ``"multi"`` (``"reach"`` is :class:`ReachController`).
        searches: one search per preview time (``p = 1`` for single, ``len(weights)`` for multi),
            each with ``step(target, t)``, ``peaks()`` and ``seed(q)``.
        evaluator: the AMSIP evaluator of the local term (needed with ``params.with_gradient``).

    Raises:
        ConfigurationError: wrong number of searches, unknown mode, ``with_gradient`` without evaluator.
    """

    def __init__(
        self,
        robot: Robot,
        params: ControllerParams,
        mode: str,
        searches: Sequence[SearchLike],
        evaluator: Evaluator | None = None,
    ) -> None:
        if mode not in ("single", "multi"):
            raise ConfigurationError(f"unknown preview mode {mode!r}; valid: single, multi, reach")
        self.name = mode
        self.robot, self.params, self.mode = robot, params, mode
        self.weights = np.array(params.preview_weights(mode))
        if len(searches) != len(self.weights):
            raise ConfigurationError(
                f"{mode} preview control needs {len(self.weights)} searches (one per preview time), got {len(searches)}"
            )
        self.searches = tuple(searches)
        self._gain = _gain_vector(params.gain, robot.nv, "gain")
        self._local: GradientController | None = None
        if params.with_gradient:
            if evaluator is None:
                raise ConfigurationError("with_gradient needs the AMSIP evaluator: pass evaluator=")
            self._local = GradientController(robot, evaluator, params)
        self._targets: Array | None = None
        self._target_amsip: Array | None = None

    @property
    def preview_times(self) -> Array:
        """Offsets ``i t̃`` [s] of the preview times, ``(p,)``."""
        return np.asarray(self.params.preview_time * np.arange(1, len(self.weights) + 1), dtype=np.float64)

    def _update_targets(self, t: float, q: Array, path: HandPath) -> tuple[Array, Array]:
        if self._targets is None:
            for search in self.searches:
                search.seed(np.array(q, dtype=float))
        targets, values = np.empty((len(self.searches), self.robot.nq)), np.empty(len(self.searches))
        times = [t + float(offset) for offset in self.preview_times]
        for i, best in enumerate(step_searches(self.searches, path, times)):
            targets[i], values[i] = np.asarray(best.q, dtype=float), float(best.S)
        self._targets, self._target_amsip = targets, values
        return targets, values

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]."""
        if state.frame_due or self._targets is None or self._target_amsip is None:
            targets, values = self._update_targets(t, q, state.path)
        else:
            targets, values = self._targets, self._target_amsip
        direction = np.zeros(self.robot.nv)
        for k, target in zip(self.weights, targets, strict=True):
            direction += k * wrapped_difference(self.robot, q, target)
        v = self._gain * direction
        if self._local is not None:
            v = v + self._local.null_space_input(q, t)
        return track(self.robot, t, q, state, v, self.params, targets.copy(), values.copy())


@dataclass(frozen=True)
class Route:
    """The chosen sequence of peaks of :class:`ReachController`, one per preview time.

    Attributes:
        nodes: ``(len, nq)`` configurations, level 1 first.
        S: ``(len,)`` their AMSIP values.
        complete: whether it reaches the last preview time (otherwise the longest feasible prefix).
        lead: ``(nq,)`` the planned configuration one sweep step ahead on the move to ``nodes[0]``.
    """

    nodes: Array
    S: Array
    complete: bool
    lead: Array


class ReachController:
    """``reach``: the reachability sequence of the paper's Fig. 3.

    At each camera frame every imaginary arm ``i`` (at ``t_i* = t + i t̃``) runs one GA generation;
    its top-K distinct peaks with ``S > 0`` are the nodes of level ``i`` (a negative future node is
    dropped, and every route through it with it). The current configuration is level 0. An edge
    from node ``a`` (level ``i-1``, time ``t_a``) to node ``b`` (level ``i``, time ``t_a + t̃``) is
    *feasible* when the arm can move from one to the other while its hand follows the path:

    1. ``sweep_samples`` intermediate times ``tau`` split the move; at each, the genes are
       interpolated between ``a``'s and ``b``'s (angles the short way round) and solved onto the
       hand target ``r_d(tau)`` by the redundancy map; the elbow branch switches from ``a``'s to
       ``b``'s at the middle sample (a switch is only continuous through a stretched elbow, so a
       switch elsewhere fails the speed test below);
    2. every such configuration is reachable and collision-free (``S >= 0``) with the scene at
       ``tau``;
    3. consecutive configurations differ by at most ``v_max_j (tau_k+1 - tau_k) velocity_scale``
       per joint (the joint speed limits).

    The route (one node per level) with the best total S over feasible edges is found by dynamic
    programming (Viterbi); if no route reaches the last level, the one reaching furthest is taken.
    The arm then follows the planned move toward the route's first node: ``v = (q_lead ⊖ q) / dtau``,
    ``q_lead`` being the move's first sample (``dtau = t̃ / (sweep_samples + 1)`` ahead), re-planned
    at every frame (receding horizon). If not even level 1 is reachable, eq. 21 on the imaginary
    arms' best candidates is used, as in ``multi``.

    Unlike plain eq. 21, whose targets are each time's own best (possibly on different, mutually
    unreachable peaks) and whose null-space pull toward a configuration on the other elbow branch
    does not lead through the stretched elbow, the arm here follows a move that was checked to be
    on the path, collision-free and within the speed limits.
    """

    name = "reach"

    def __init__(
        self,
        robot: Robot,
        params: ControllerParams,
        evaluator: Evaluator,
        searches: Sequence[SearchLike],
        redundancy: Any,
        *,
        sweep_samples: int = 6,
    ) -> None:
        self.robot, self.params, self.evaluator, self.redundancy = robot, params, evaluator, redundancy
        self.weights = np.array(params.preview_weights("multi"))
        if len(searches) != len(self.weights):
            raise ConfigurationError(
                f"reach needs {len(self.weights)} searches (one per preview time), got {len(searches)}"
            )
        self.searches = tuple(searches)
        self.sweep_samples = sweep_samples
        self._gain = _gain_vector(params.gain, robot.nv, "gain")
        self._speed = effective_velocity_limits(robot, params.velocity_scale)
        self._sweep_step = params.preview_time / (sweep_samples + 1)
        self._route: Route | None = None
        self._fallback: tuple[Array, Array] | None = None

    @property
    def route(self) -> Route | None:
        """The route chosen at the last frame (``None`` before the first or when none was feasible)."""
        return self._route

    def _edges(self, starts: Array, ends: Array, t0: float, path: HandPath) -> tuple[NDArray[np.bool_], Array]:
        """Feasibility ``(len(starts), len(ends))`` of the moves between two levels starting at ``t0`` [s],
        and each move's first sample ``(len(starts), len(ends), nq)`` (its configuration at ``t0 + dtau``)."""
        red = self.redundancy
        genes_a, branch_a = red.genes_of(starts)
        genes_b, branch_b = red.genes_of(ends)
        delta = genes_b[None, :, :] - genes_a[:, None, :]
        delta = np.where(red.periodic, wrap_angle(delta), delta)
        feasible = np.ones(delta.shape[:2], bool)
        pairs = np.argwhere(feasible)
        dtau = self.params.preview_time / (self.sweep_samples + 1)
        previous = starts[pairs[:, 0]]
        ok = np.ones(len(pairs), bool)
        first = np.empty((len(starts), len(ends), starts.shape[1]))
        for k in range(1, self.sweep_samples + 2):
            tau = t0 + k * dtau
            genes = genes_a[pairs[:, 0]] + (k / (self.sweep_samples + 1)) * delta[pairs[:, 0], pairs[:, 1]]
            if k == self.sweep_samples + 1:
                Q, reachable = ends[pairs[:, 1]], np.ones(len(pairs), bool)
            else:
                branch = branch_a[pairs[:, 0]] if 2 * k <= self.sweep_samples + 1 else branch_b[pairs[:, 1]]
                Q, reachable = red.solve(genes, branch, np.asarray(path.position(tau), float), previous)
                ok &= reachable & (self.evaluator(Q, tau).S >= 0.0)
            steps = np.array([wrapped_difference(self.robot, a, b) for a, b in zip(previous, Q, strict=True)])
            ok &= np.all(np.abs(steps) <= self._speed * dtau, axis=1)
            if k == 1:
                first[pairs[:, 0], pairs[:, 1]] = Q
            previous = Q
        feasible[pairs[~ok, 0], pairs[~ok, 1]] = False
        return feasible, first

    def _choose(self, t: float, q: Array, levels: list[tuple[Array, Array]], path: HandPath) -> Route | None:
        """Viterbi over the levels: the feasible route with the best total S (or the longest prefix)."""
        total = np.zeros(1)
        nodes_prev = q[None, :]
        back: list[NDArray[np.int_]] = []
        reached: list[Array] = []
        for i, (nodes, values) in enumerate(levels):
            if not len(nodes):
                break
            feasible, first = self._edges(nodes_prev, nodes, t + i * self.params.preview_time, path)
            if i == 0:
                leads = first[0]
            score = np.where(feasible, total[:, None] + values[None, :], -np.inf)
            best_prev = score.argmax(axis=0)
            best = score.max(axis=0)
            if not np.isfinite(best).any():
                break
            back.append(best_prev)
            reached.append(best)
            total, nodes_prev = best, nodes
        if not back:
            return None
        last = int(np.argmax(reached[-1]))
        chain = [last]
        for pointers in reversed(back[1:]):
            chain.append(int(pointers[chain[-1]]))
        chain.reverse()
        nodes = np.stack([levels[i][0][k] for i, k in enumerate(chain)])
        S = np.array([levels[i][1][k] for i, k in enumerate(chain)])
        return Route(nodes, S, complete=len(chain) == len(levels), lead=leads[chain[0]])

    def _update(self, t: float, q: Array, path: HandPath) -> tuple[Array, Array]:
        if self._fallback is None:
            for search in self.searches:
                search.seed(np.array(q, dtype=float))
        levels: list[tuple[Array, Array]] = []
        best_q, best_S = np.empty((len(self.searches), self.robot.nq)), np.empty(len(self.searches))
        times = [t + (i + 1) * self.params.preview_time for i in range(len(self.searches))]
        for i, (search, best) in enumerate(zip(self.searches, step_searches(self.searches, path, times), strict=True)):
            best_q[i], best_S[i] = np.asarray(best.q, dtype=float), float(best.S)
            peaks = [c for c in search.peaks() if c.S > 0]
            levels.append((np.array([c.q for c in peaks]).reshape(-1, self.robot.nq), np.array([c.S for c in peaks])))
        self._fallback = (best_q, best_S)
        self._route = self._choose(t, q, levels, path)
        return self._fallback

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]."""
        if state.frame_due or self._fallback is None:
            targets, values = self._update(t, q, state.path)
        else:
            targets, values = self._fallback
        if self._route is not None:
            n = len(self._route.nodes)
            targets, values = targets.copy(), values.copy()
            targets[:n], values[:n] = self._route.nodes, self._route.S
            v = wrapped_difference(self.robot, q, self._route.lead) / self._sweep_step
        else:
            pulls = [k * wrapped_difference(self.robot, q, g) for k, g in zip(self.weights, targets, strict=True)]
            v = self._gain * np.sum(pulls, axis=0)
        return track(self.robot, t, q, state, v, self.params, targets.copy(), values.copy())


SearchFactory = Callable[[int, np.random.Generator], SearchLike]


def make_controller(
    spec: ControllerSpec,
    robot: Robot,
    evaluator: Evaluator,
    rng: np.random.Generator,
    *,
    search_factory: SearchFactory | None = None,
) -> Controller:
    """Build the controller ``spec`` names.

    Args:
        spec: name and parameters.
        robot: the arm (the search robot: convex geometry).
        evaluator: AMSIP evaluator for the gradient and the searches.
        rng: random generator; each imaginary arm gets an independent child stream.
        search_factory: ``factory(i, rng_i)`` building the search of preview ``i``; default: a
            :class:`previewctl.search.OneStepGA` over :func:`previewctl.redundancy.redundancy_map`.

    Raises:
        PreviewctlError: the GA module is not available.
    """
    params = spec.params
    if spec.name == "none":
        return TrackingController(robot, params)
    if spec.name == "gradient":
        return GradientController(robot, evaluator, params)
    mode = "multi" if spec.name == "reach" else spec.name
    count = len(params.preview_weights(mode))
    factory = search_factory or _ga_factory(robot, evaluator, params, spec.name)
    streams = rng.spawn(count)
    searches = [factory(i, streams[i]) for i in range(count)]
    if spec.name == "reach":
        from previewctl.redundancy import redundancy_map

        return ReachController(robot, params, evaluator, searches, redundancy_map(robot))
    return PreviewController(robot, params, spec.name, searches, evaluator)


def _ga_factory(robot: Robot, evaluator: Evaluator, params: ControllerParams, mode: str) -> SearchFactory:
    """The default search factory: one 1-step GA per imaginary arm (imported lazily)."""
    try:
        from previewctl.redundancy import redundancy_map
        from previewctl.search import OneStepGA
    except ImportError as exc:
        raise PreviewctlError(
            f"controller {mode!r} needs the 1-step GA (previewctl.search, previewctl.redundancy), "
            f"which is not available: {exc}"
        ) from exc
    redundancy = redundancy_map(robot)
    options: Mapping[str, Any] = dict(params.ga_options)

    def factory(i: int, rng: np.random.Generator) -> SearchLike:
        try:
            ga: SearchLike = OneStepGA(
                robot, evaluator, redundancy, rng,
                population=params.population, elite=params.elite, top_k=params.top_k, **options,
            )
        except TypeError as exc:
            raise ConfigurationError(f"controller GA options {dict(options)!r} rejected: {exc}") from exc
        return ga

    return factory


__all__ = [
    "CONTROLLER_NAMES",
    "PAPER_WEIGHTS",
    "ControlInfo",
    "ControlState",
    "Controller",
    "ControllerParams",
    "ControllerSpec",
    "GradientController",
    "PreviewController",
    "ReachController",
    "Route",
    "TrackingController",
    "apply_limits",
    "check_preview_weights",
    "damped_pseudo_inverse",
    "make_controller",
    "null_space_budget",
    "track",
    "wrapped_difference",
]
