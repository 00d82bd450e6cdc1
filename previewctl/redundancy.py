"""Redundancy maps: from a few free parameters ("genes") to configurations that put the hand on a target.

For a hand target ``x`` the candidates of the search are the configurations with ``f(q) = x`` (the
self-motion manifold). A :class:`RedundancyMap` parameterises them:

* :class:`PlanarRedundancy` (planar arms of revolute z joints, the paper's section 4.3): the genes are
  the first ``n - 2`` joint angles; they fix the origin ``w`` of joint ``n - 1`` (the "wrist"), and the
  last two links reach from ``w`` to the target in closed form (two-link inverse kinematics). With
  link vectors ``a`` (joint ``n - 1`` to joint ``n``, length ``l_1``) and ``b`` (joint ``n`` to the tip,
  length ``l_2``) and ``d = x - w``::

      cos(beta) = (|d|^2 - l_1^2 - l_2^2) / (2 l_1 l_2),      beta = +-acos(...)  (branch 0: +, 1: -)
      phi_1     = atan2(d) - atan2(l_2 sin(beta), l_1 + l_2 cos(beta))         (absolute angle of a)

  ``beta`` is the angle from ``a`` to ``b``; for straight links (planar4) ``beta = q_n``, so branch 0 is
  ``q_n >= 0`` and branch 1 is ``q_n < 0``. Genes whose wrist is out of the annulus
  ``| l_1 - l_2 | <= |d| <= l_1 + l_2`` are unreachable: the returned configuration is still finite
  (stretched or folded toward the target) and ``reachable`` is ``False``. Every angle is wrapped to
  ``[-pi, pi)`` (then shifted by ``2 pi`` if that is needed to fit the joint limits; a value that fits no
  shift is unreachable too). Fully vectorised.

* :class:`NewtonRedundancy` (any other arm): the genes are a full vector of ``nv`` joint angles within
  the joint limits, used as the start of damped-least-squares Newton steps onto ``f(q) = target``::

      dq = J^T (J J^T + lambda^2 I)^-1 e,         q <- clip(integrate(q, dq), joint limits)

  where ``e`` is the task error (position; for ``robot.task == "pose"`` the 6-D error
  ``[x_d - x; log3(R_d R^T)]``), clamped to ``max_step`` [m] of position error per step, and ``J`` the
  world-aligned task Jacobian. The damping shrinks with the error,
  ``lambda^2 = damping^2 * clip(|e| / max_step, 1e-3, 1)``: robust far from the target, nearly
  Gauss-Newton (fast) close to it. Joints sitting at a limit that the step would push further are frozen
  for that step (their Jacobian columns zeroed), so the iteration slides along the limit instead of
  stalling. Continuous joints (``nq != nv``) move through ``pin.integrate`` and are never clipped. The
  iteration stops per configuration once the position error is below ``tolerance`` (default
  ``1e-4`` m) and, for a pose task, the rotation error below ``angle_tolerance`` (default ``1e-3``
  rad); ``reachable`` is that test after at most ``iterations`` steps -- so a start far from the
  manifold may be flagged unreachable although the target is reachable from elsewhere. The map is a
  deterministic function of the genes (with no ``q_seed``); ``q_seed`` replaces the start (a warm
  start, e.g. last frame's solution). There is a single branch.

:func:`score` solves genes and evaluates AMSIP for the reachable ones; unreachable candidates get
``S = evaluator.potential.collision_value`` (< 0): as in the paper, S < 0 exactly when the configuration
collides *or* cannot reach the hand target.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.amsip import Evaluator
from previewctl.errors import ConfigurationError
from previewctl.robot import Robot
from previewctl.validation import rotation_matrix
from previewctl.validation import show as _show

Array = NDArray[np.float64]
TWO_PI = 2.0 * np.pi

__all__ = [
    "NewtonRedundancy",
    "PlanarRedundancy",
    "RedundancyMap",
    "Scored",
    "Target",
    "joint_angles",
    "parse_target",
    "redundancy_map",
    "score",
    "score_configurations",
    "wrap_angle",
]


def wrap_angle(angle: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """Wrap angles [rad] to ``[-pi, pi)`` (``floor`` instead of the much slower ``%`` on floats)."""
    x = np.asarray(angle, dtype=float)
    out = np.asarray(x - TWO_PI * np.floor((x + np.pi) * (1.0 / TWO_PI)))
    out[out >= np.pi] -= TWO_PI  # rounding at the borders
    out[out < -np.pi] += TWO_PI
    return out


@dataclass(frozen=True)
class Target:
    """A validated hand target.

    Attributes:
        position: ``(3,)`` [m] (``z = 0`` for a planar target given with two entries).
        rotation: ``(3, 3)`` hand orientation for a pose task, else ``None``.
        planar: whether it was given as ``(x, y)``.
    """

    position: Array
    rotation: Array | None = None
    planar: bool = False


def parse_target(target: object, robot: Robot) -> Target:
    """Validate a hand target for ``robot``.

    Accepted forms: ``(2,)`` (planar arms, or the x-y of a planar task) or ``(3,)`` positions [m]; for a
    ``"pose"`` task a ``(position (3,), rotation (3, 3))`` pair, a ``pin.SE3`` or a ``(4, 4)`` homogeneous
    matrix. A pose given to a position task keeps only its position.

    Raises:
        ConfigurationError: a wrong shape, a non-finite entry, or a position given to a pose task.
    """
    rotation: Array | None = None
    if isinstance(target, Target):
        return target
    if isinstance(target, pin.SE3):
        position, rotation = np.array(target.translation, float), np.array(target.rotation, float)
    elif isinstance(target, tuple) and len(target) == 2 and np.shape(target[1]) == (3, 3):
        position, rotation = np.array(target[0], dtype=float), np.array(target[1], dtype=float)
    else:
        try:
            arr = np.array(target, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ConfigurationError(f"target must be numbers [m], got {_show(target)}") from exc
        if arr.shape == (4, 4):
            position, rotation = arr[:3, 3].copy(), arr[:3, :3].copy()
        else:
            position = arr
    if position.shape not in ((2,), (3,)):
        raise ConfigurationError(
            f"target position has shape {position.shape}; robot {robot.name!r} (task {robot.task!r}) needs "
            f"(2,) or (3,) [m]{' plus a (3, 3) rotation' if robot.task == 'pose' else ''}: got {_show(target)}"
        )
    if not np.all(np.isfinite(position)) or (rotation is not None and not np.all(np.isfinite(rotation))):
        raise ConfigurationError(f"target must be finite, got {_show(target)}")
    planar = position.shape == (2,)
    if planar:
        position = np.array([position[0], position[1], 0.0])
    if rotation is not None:
        rotation = rotation_matrix(rotation, "target rotation", ConfigurationError)
    if robot.task == "pose" and rotation is None:
        raise ConfigurationError(
            f"robot {robot.name!r} has a pose task: give the target as (position (3,), rotation (3, 3)), "
            f"a pin.SE3 or a (4, 4) matrix, got {_show(target)}"
        )
    if robot.task != "pose":
        rotation = None
    return Target(position, rotation, planar)


@runtime_checkable
class RedundancyMap(Protocol):
    """Genes (free parameters) -> configurations with the hand on the target.

    Attributes:
        gene_lower: ``(g,)`` lower bounds of the genes [rad].
        gene_upper: ``(g,)`` upper bounds [rad].
        periodic: ``(g,)`` whether a gene is an angle on the full circle (wrapped, not clipped).
        branches: number of discrete branches (2 for a planar arm's elbow, 1 for the general map).
    """

    gene_lower: Array
    gene_upper: Array
    periodic: NDArray[np.bool_]
    branches: int

    def solve(
        self, genes: Array, branch: NDArray[np.int_], target: object, q_seed: Array | None = None
    ) -> tuple[Array, NDArray[np.bool_]]:
        """Configurations ``(B, nq)`` and ``reachable`` ``(B,)`` for genes ``(B, g)`` and branches ``(B,)``."""
        ...

    def genes_of(self, Q: Array) -> tuple[Array, NDArray[np.int_]]:
        """The genes ``(B, g)`` and branches ``(B,)`` of configurations ``(B, nq)``."""
        ...


def _check_genes(genes: object, branch: object, g: int, branches: int) -> tuple[Array, NDArray[np.int_]]:
    G = np.array(genes, dtype=float)
    if G.ndim == 1 and g > 0 and G.shape[0] == g:
        G = G[None]
    if G.ndim != 2 or G.shape[1] != g:
        raise ConfigurationError(f"genes has shape {G.shape}; expected (B, {g})")
    if not np.all(np.isfinite(G)):
        raise ConfigurationError(f"genes must be finite, got {_show(G.tolist())}")
    br = np.broadcast_to(np.asarray(branch), (G.shape[0],))
    if br.dtype.kind not in "iub":
        raise ConfigurationError(f"branch must be integers, got dtype {br.dtype}")
    br = br.astype(int)
    if ((br < 0) | (br >= branches)).any():
        bad = br[(br < 0) | (br >= branches)][0]
        raise ConfigurationError(f"branch {bad} out of range; valid: 0..{branches - 1}")
    return G, br


def _fit_limits(Q: Array, lower: Array, upper: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Angles already in ``[-pi, pi)`` shifted by ``+-2 pi`` where that puts them within limits."""
    out = Q.copy()
    ok = np.ones(Q.shape[0], dtype=bool)
    for j in range(Q.shape[1]):
        col = Q[:, j]
        inside = (col >= lower[j]) & (col <= upper[j])
        up, down = col + TWO_PI, col - TWO_PI
        in_up = (up >= lower[j]) & (up <= upper[j])
        in_down = (down >= lower[j]) & (down <= upper[j])
        out[:, j] = np.where(inside, col, np.where(in_up, up, np.where(in_down, down, col)))
        ok &= inside | in_up | in_down
    return out, ok


class PlanarRedundancy:
    """Closed-form redundancy map of a planar arm (see the module docstring).

    Args:
        robot: a planar arm (``robot.planar`` set) with at least 2 joints.
        reach_tolerance: slack [m] on the two-link annulus test (for targets exactly on its border).

    Attributes:
        gene_lower, gene_upper: ``(n - 2,)`` gene bounds [rad]: ``[-pi, pi)`` for joints that turn a full
            circle within their limits, else the joint limits.
        periodic: ``(n - 2,)`` whether each gene wraps.
        branches: 2 (elbow branches, ``beta >= 0`` and ``beta < 0``).
        link_lengths: ``(l_1, l_2)`` of the last two links [m].
    """

    branches: int = 2

    def __init__(self, robot: Robot, *, reach_tolerance: float = 1e-9) -> None:
        if robot.planar is None:
            raise ConfigurationError(f"robot {robot.name!r} is not a planar chain; use NewtonRedundancy")
        if robot.nq < 2:
            raise ConfigurationError(f"robot {robot.name!r} has {robot.nq} joint(s); the planar map needs >= 2")
        self.robot = robot
        self.chain = robot.planar
        self.n = robot.nq
        self.g = self.n - 2
        a = np.asarray(self.chain.offsets[self.n - 1], float)
        b = np.asarray(self.chain.tip_offset, float)
        self.l1, self.l2 = float(np.hypot(*a)), float(np.hypot(*b))
        if min(self.l1, self.l2) < 1e-9:
            raise ConfigurationError(
                f"robot {robot.name!r}: the last two links must have non-zero length, got {self.l1}, {self.l2} m"
            )
        self.alpha1, self.alpha2 = float(np.arctan2(a[1], a[0])), float(np.arctan2(b[1], b[0]))
        self.link_lengths = (self.l1, self.l2)
        self.reach_tolerance = float(reach_tolerance)
        self.lower, self.upper = robot.lower_limits, robot.upper_limits
        full = (self.upper - self.lower) >= TWO_PI - 1e-9
        self._covers_circle = bool(np.all(self.lower <= -np.pi) and np.all(self.upper >= np.pi))
        self.periodic = full[: self.g].copy()
        self.gene_lower = np.where(self.periodic, -np.pi, self.lower[: self.g])
        self.gene_upper = np.where(self.periodic, np.pi, self.upper[: self.g])
        self.max_reach = float(np.sum(np.hypot(*self.chain.offsets[1:].T)) + self.l2)

    def wrist(self, genes: Array) -> tuple[Array, Array]:
        """Origin of joint ``n - 1`` ``(B, 2)`` [m] and the absolute angle ``theta_{n-2}`` ``(B,)`` [rad]."""
        B = genes.shape[0]
        theta = np.zeros(B)
        point = np.broadcast_to(self.chain.offsets[0], (B, 2)).copy()
        for k in range(self.g):
            theta = theta + genes[:, k]
            dx, dy = self.chain.offsets[k + 1]
            c, s = np.cos(theta), np.sin(theta)
            point[:, 0] += c * dx - s * dy
            point[:, 1] += s * dx + c * dy
        return point, theta

    def wrist_grid(self, axes: tuple[Array, ...]) -> tuple[Array, Array]:
        """:meth:`wrist` over the grid ``axes[0] x axes[1] x ...`` (up to 2 genes), with trig tables.

        Returns:
            The wrist ``(n_1, ..., n_g, 2)`` [m] and ``theta_{n-2}`` ``(n_1, ..., n_g)`` [rad]. Only the
            ``n_k`` cosines and sines of each axis are computed; the sums of angles use the addition
            formulas, which saves most of the trigonometry of a 259,200-point grid.
        """
        if len(axes) != self.g or self.g > 2:
            raise ConfigurationError(f"wrist_grid needs {self.g} axes (and at most 2 genes), got {len(axes)}")
        shape = tuple(len(a) for a in axes)
        point = np.broadcast_to(self.chain.offsets[0], (*shape, 2)).copy()
        theta = np.zeros(shape)
        c, s = np.ones(shape), np.zeros(shape)
        for k, axis in enumerate(axes):
            view = [1] * len(axes)
            view[k] = len(axis)
            ck, sk = np.cos(axis).reshape(view), np.sin(axis).reshape(view)
            c, s = c * ck - s * sk, s * ck + c * sk
            theta = theta + np.asarray(axis).reshape(view)
            dx, dy = self.chain.offsets[k + 1]
            point[..., 0] += c * dx - s * dy
            point[..., 1] += s * dx + c * dy
        return point, theta

    def two_link(self, wrist: Array, theta_w: Array, target: object) -> tuple[Array, NDArray[np.bool_]]:
        """The last two joint angles for both branches.

        Args:
            wrist: ``(..., 2)`` origins of joint ``n - 1`` [m].
            theta_w: ``(...)`` absolute angle ``theta_{n-2}`` of the link before it [rad].
            target: hand position.

        Returns:
            ``(branches, ..., 2)`` angles ``(q_{n-1}, q_n)`` [rad], wrapped to ``[-pi, pi)`` (not yet fitted
            to the joint limits), and ``reachable`` ``(...)`` (the annulus test and the target's z).
        """
        goal = parse_target(target, self.robot)
        dx, dy = goal.position[0] - wrist[..., 0], goal.position[1] - wrist[..., 1]
        dist = np.hypot(dx, dy)
        l1, l2 = self.l1, self.l2
        reachable = (dist <= l1 + l2 + self.reach_tolerance) & (dist >= abs(l1 - l2) - self.reach_tolerance)
        reachable &= abs(goal.position[2]) <= self.reach_tolerance
        cos_beta = np.clip((dist * dist - (l1 * l1 + l2 * l2)) / (2.0 * l1 * l2), -1.0, 1.0)
        beta = np.arccos(cos_beta)
        gamma = np.arctan2(l2 * np.sqrt(1.0 - cos_beta * cos_beta), l1 + l2 * cos_beta)
        base = np.arctan2(dy, dx) - self.alpha1 - theta_w
        out = np.empty((2, *dist.shape, 2))
        out[0, ..., 0], out[1, ..., 0] = base - gamma, base + gamma
        out[0, ..., 1], out[1, ..., 1] = beta, -beta
        out[..., 1] += self.alpha1 - self.alpha2
        return wrap_angle(out), reachable

    def _finish(self, Q: Array, reachable: NDArray[np.bool_]) -> tuple[Array, NDArray[np.bool_]]:
        if self._covers_circle:
            return Q, reachable
        Q, within = _fit_limits(Q, self.lower, self.upper)
        return Q, reachable & within

    def solve(
        self, genes: Array, branch: NDArray[np.int_], target: object, q_seed: Array | None = None
    ) -> tuple[Array, NDArray[np.bool_]]:
        """Configurations for genes ``(B, n - 2)`` [rad] and elbow branches ``(B,)`` in {0, 1}.

        Args:
            genes: the first ``n - 2`` joint angles [rad].
            branch: 0 (``beta >= 0``) or 1 (``beta < 0``), broadcast to ``(B,)``.
            target: hand position ``(2,)`` [m] (or ``(3,)`` with ``z = 0``: another z is unreachable).
            q_seed: ignored (the map is closed form).

        Returns:
            ``Q`` ``(B, n)`` [rad] wrapped to ``[-pi, pi)`` (or shifted by 2 pi into the limits) and
            ``reachable`` ``(B,)``.
        """
        del q_seed
        G, br = _check_genes(genes, branch, self.g, self.branches)
        w, theta_w = self.wrist(G)
        last, reachable = self.two_link(w, theta_w, target)
        Q = np.empty((G.shape[0], self.n))
        Q[:, : self.g] = wrap_angle(G)
        Q[:, self.g :] = np.where((br == 0)[:, None], last[0], last[1])
        return self._finish(Q, reachable)

    def solve_grid(self, axes: tuple[Array, ...], target: object) -> tuple[Array, NDArray[np.bool_]]:
        """:meth:`solve` over every branch and the grid of gene ``axes`` (at most 2 genes).

        Returns:
            ``Q`` ``(branches * n_1 * ... * n_g, n)`` in branch-major then C order of the axes, and
            ``reachable`` of the same length; equal to :meth:`solve` on the same candidates.
        """
        w, theta_w = self.wrist_grid(axes)
        last, reachable = self.two_link(w, theta_w, target)
        cells = int(np.prod([len(a) for a in axes]))
        Q = np.empty((2, cells, self.n))
        if self.g:
            mesh = np.meshgrid(*axes, indexing="ij")
            for k in range(self.g):
                Q[:, :, k] = wrap_angle(mesh[k].ravel())
        Q[:, :, self.g :] = last.reshape(2, cells, 2)
        return self._finish(Q.reshape(2 * cells, self.n), np.tile(reachable.ravel(), 2))

    def genes_of(self, Q: Array) -> tuple[Array, NDArray[np.int_]]:
        """Genes (the first ``n - 2`` angles, wrapped to ``[-pi, pi)``) and branch of ``(B, n)`` configurations."""
        Qb, _ = self.robot.check_configurations(Q)
        beta = wrap_angle(Qb[:, self.g + 1] + self.alpha2 - self.alpha1)
        genes = Qb[:, : self.g]
        genes = np.where(self.periodic, wrap_angle(genes), genes)
        return genes, (beta < 0).astype(int)


class NewtonRedundancy:
    """General redundancy map: genes = a joint vector projected onto ``f(q) = target`` (module docstring).

    Args:
        robot: any arm.
        tolerance: position residual [m] below which the hand is on the target (default 1e-4).
        angle_tolerance: rotation residual [rad] for a pose task (default 1e-3).
        iterations: the most Newton steps per call (default 20; converged rows stop early).
        damping: largest ``lambda`` [m] of the damped least squares (default 0.02; see the module docstring).
        max_step: largest task-error norm [m] corrected per step (default 0.2).

    Attributes:
        gene_lower, gene_upper: ``(nv,)`` bounds [rad]: the joint limits, ``[-pi, pi)`` for continuous
            joints (and for revolute joints without finite limits).
        periodic: ``(nv,)`` true for the continuous/unbounded joints.
        branches: 1.
    """

    branches: int = 1

    def __init__(
        self,
        robot: Robot,
        *,
        tolerance: float = 1e-4,
        angle_tolerance: float = 1e-3,
        iterations: int = 20,
        damping: float = 0.02,
        max_step: float = 0.2,
    ) -> None:
        for name, value in (("tolerance", tolerance), ("angle_tolerance", angle_tolerance),
                            ("damping", damping), ("max_step", max_step)):
            if not (np.isfinite(value) and value > 0):
                raise ConfigurationError(f"{name} must be > 0, got {value!r}")
        if not (isinstance(iterations, int) and iterations >= 0):
            raise ConfigurationError(f"iterations must be a non-negative integer, got {iterations!r}")
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        # an element reference: computeFrameJacobian(..., LOCAL_WORLD_ALIGNED) writes the hand's placement
        # there (Pinocchio's frames.hxx); the Newton tests check the hand by independent forward kinematics
        self._hand_placement = self.data.oMf[robot.tip_frame_id]
        self.tolerance, self.angle_tolerance = float(tolerance), float(angle_tolerance)
        self.iterations, self.damping = iterations, float(damping)
        self.max_step = float(max_step)
        self.rows = robot.task_rows
        self.m = self.rows.stop - self.rows.start
        self.tip_id = robot.tip_frame_id
        self.neutral = robot.neutral()
        nv = robot.nv
        lower, upper = np.full(nv, -np.pi), np.full(nv, np.pi)
        periodic = np.ones(nv, dtype=bool)
        clip_q: list[int] = []
        clip_v: list[int] = []
        for j in range(1, self.model.njoints):
            joint = self.model.joints[j]
            if joint.nq == joint.nv:
                for k in range(joint.nv):
                    lo, hi = robot.lower_limits[joint.idx_q + k], robot.upper_limits[joint.idx_q + k]
                    if np.isfinite(lo) and np.isfinite(hi):
                        lower[joint.idx_v + k], upper[joint.idx_v + k] = lo, hi
                        periodic[joint.idx_v + k] = False
                        clip_q.append(joint.idx_q + k)
                        clip_v.append(joint.idx_v + k)
        self.gene_lower, self.gene_upper, self.periodic = lower, upper, periodic
        self._clip = np.array(clip_q, dtype=int)
        self._clip_v = np.array(clip_v, dtype=int)
        # every joint a 1-dof revolute/prismatic one: pin.integrate is plain addition, done for the batch
        self._vector_space = all(
            self.model.joints[j].nq == self.model.joints[j].nv == 1
            and self.model.joints[j].shortname().startswith(("JointModelR", "JointModelP"))
            for j in range(1, self.model.njoints)
        )
        self._q_lower = robot.lower_limits[self._clip]
        self._q_upper = robot.upper_limits[self._clip]
        self._lower_margin, self._upper_margin = self._q_lower + 1e-9, self._q_upper - 1e-9
        self._eye = np.eye(self.m)

    # ------------------------------------------------------------------ genes <-> configurations

    def configurations(self, genes: Array) -> Array:
        """Configurations ``(B, nq)`` of joint-angle vectors ``(B, nv)`` (no projection)."""
        if self.robot.nq == self.robot.nv:
            return np.array(genes, dtype=float)
        return np.stack([pin.integrate(self.model, self.neutral, g) for g in genes])

    def genes_of(self, Q: Array) -> tuple[Array, NDArray[np.int_]]:
        """Joint angles ``(B, nv)`` of configurations ``(B, nq)``; branch 0."""
        Qb, _ = self.robot.check_configurations(Q)
        if self.robot.nq == self.robot.nv:
            genes = Qb.copy()
        else:
            genes = np.stack([pin.difference(self.model, self.neutral, q) for q in Qb])
        genes = np.where(self.periodic, wrap_angle(genes), genes)
        return genes, np.zeros(Qb.shape[0], dtype=int)

    # ----------------------------------------------------------------------------- projection

    def _hand(self, Q: Array) -> tuple[Array, Array]:
        """Hand placements ``(A, 4, 4)`` and world-aligned Jacobians ``(A, 6, nv)`` (linear rows first).

        One ``computeFrameJacobian`` per row: for the hand frame alone this beats the batched assembly
        of :class:`~previewctl.avoidance.FrameKinematics`, whose fixed numpy cost dominates the small
        batches of the late Newton passes.
        """
        model, data, frame, placement = self.model, self.data, self.tip_id, self._hand_placement
        jacobians, placements = [], []
        for q in Q:
            jacobians.append(pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED))
            placements.append(placement.homogeneous)
        return np.array(placements).reshape(-1, 4, 4), np.array(jacobians).reshape(-1, 6, model.nv)

    def _task_error(self, goal_positions: Array, goal_rotations: Array | None, positions: Array,
                    rotations: Array) -> Array:
        """Task errors ``(A, m)`` from hand placements toward per-row goals ``(A, 3)`` (and ``(A, 3, 3)``
        orientations for a pose task)."""
        linear = goal_positions - positions
        if goal_rotations is None:
            return linear[:, self.rows]
        angular = np.array([pin.log3(Rd @ R.T) for Rd, R in zip(goal_rotations, rotations, strict=True)])
        return np.concatenate([linear, angular.reshape(-1, 3)], axis=1)

    def _converged(self, err: Array) -> NDArray[np.bool_]:
        pos = _row_norm(err[:, :3] if self.m >= 3 else err) < self.tolerance
        if self.m == 6:
            pos &= _row_norm(err[:, 3:]) < self.angle_tolerance
        return pos

    def _clip_limits(self, Q: Array) -> Array:
        """Clip the bounded joints of configurations ``(A, nq)`` to their limits (in place)."""
        if self._clip.size:
            Q[:, self._clip] = np.minimum(np.maximum(Q[:, self._clip], self._q_lower), self._q_upper)
        return Q

    def _step(self, J: Array, err: Array, Q: Array) -> Array:
        """Damped least-squares steps ``(A, nv)``; joints at a limit that the step pushes further are frozen."""
        JT = np.ascontiguousarray(np.swapaxes(J, 1, 2))
        ratio = np.minimum(np.maximum(_row_norm(err[:, :3] if self.m >= 3 else err) / self.max_step, 1e-3), 1.0)
        eye = (self.damping**2 * ratio)[:, None, None] * self._eye
        step = (JT @ np.linalg.solve(J @ JT + eye, err[..., None]))[..., 0]
        if not self._clip.size:
            return step
        q, pushed = Q[:, self._clip], step[:, self._clip_v]
        blocked_v = ((q <= self._lower_margin) & (pushed < 0)) | ((q >= self._upper_margin) & (pushed > 0))
        rows = blocked_v.any(axis=1)
        if rows.any():
            free = np.ones((int(rows.sum()), J.shape[2]))
            free[:, self._clip_v] = ~blocked_v[rows]
            Jf = J[rows] * free[:, None, :]
            JfT = np.ascontiguousarray(np.swapaxes(Jf, 1, 2))
            step[rows] = (JfT @ np.linalg.solve(Jf @ JfT + eye[rows], err[rows][..., None]))[..., 0]
        return step

    def solve(
        self, genes: Array, branch: NDArray[np.int_], target: object, q_seed: Array | None = None
    ) -> tuple[Array, NDArray[np.bool_]]:
        """Project genes ``(B, nv)`` [rad] onto the target's self-motion manifold.

        Args:
            genes: joint-angle vectors [rad] (clipped to the gene bounds, periodic ones wrapped).
            branch: ignored beyond validation (single branch 0).
            target: hand position ``(3,)`` [m] (``(2,)`` for a planar task), or a pose for a pose task.
            q_seed: optional ``(B, nq)`` start configurations (warm start); default: the genes.

        Returns:
            ``Q`` ``(B, nq)`` within the joint limits, ``reachable`` ``(B,)``: residual below tolerance.
        """
        G = self._checked_genes(genes, branch)
        return self._project(G, [self._goal(target)], np.zeros(G.shape[0], dtype=int), q_seed)

    def solve_many(
        self, genes: Array, branch: NDArray[np.int_], targets: Sequence[object], groups: object
    ) -> tuple[Array, NDArray[np.bool_]]:
        """:meth:`solve` for rows aimed at different targets: row ``b`` goes to ``targets[groups[b]]``.

        Row for row the same result as :meth:`solve` on each group (rows never interact), in one
        iteration whose per-step overhead is paid once: the preview controller projects the
        populations of all its imaginary arms together.

        Raises:
            ConfigurationError: ``groups`` not one index in ``[0, len(targets))`` per row.
        """
        G = self._checked_genes(genes, branch)
        index = np.asarray(groups)
        if (index.shape != (G.shape[0],) or not np.issubdtype(index.dtype, np.integer)
                or (index.size and (index.min() < 0 or index.max() >= len(targets)))):
            raise ConfigurationError(
                f"groups must hold one target index in [0, {len(targets)}) per gene row ({G.shape[0]}), "
                f"got {_show(groups)}"
            )
        return self._project(G, [self._goal(target) for target in targets], index, None)

    def _checked_genes(self, genes: Array, branch: NDArray[np.int_]) -> Array:
        G, _ = _check_genes(genes, branch, self.robot.nv, self.branches)
        return np.where(self.periodic, wrap_angle(G), np.clip(G, self.gene_lower, self.gene_upper))

    def _goal(self, target: object) -> Target:
        goal = parse_target(target, self.robot)
        if goal.planar and self.m == 3:
            raise ConfigurationError(
                f"robot {self.robot.name!r} has a {self.robot.task} task: the target needs 3 coordinates [m], "
                f"got {goal.position[:2].tolist()}"
            )
        return goal

    def _project(
        self, G: Array, goals: list[Target], groups: NDArray[np.int_], q_seed: Array | None
    ) -> tuple[Array, NDArray[np.bool_]]:
        """Damped Newton from the genes ``G`` (or ``q_seed``), row ``b`` toward ``goals[groups[b]]``."""
        pose = goals[0].rotation is not None
        if any((goal.rotation is not None) != pose for goal in goals):
            raise ConfigurationError("targets mix poses and positions; give all of them the same form")
        goal_positions = np.array([goal.position for goal in goals])[groups]
        goal_rotations = np.array([goal.rotation for goal in goals])[groups] if pose else None
        anchor = self.configurations(G)
        if q_seed is None:
            Q = anchor.copy()
        else:
            Q, _ = self.robot.check_configurations(q_seed)
            if Q.shape[0] != G.shape[0]:
                raise ConfigurationError(f"q_seed has {Q.shape[0]} rows, genes {G.shape[0]}")
            Q = Q.copy()
        B, m = G.shape[0], self.m
        model = self.model
        active = np.arange(B)
        reachable = np.zeros(B, dtype=bool)
        for iteration in range(self.iterations + 1):
            placements, jacobians = self._hand(Q[active])
            J = jacobians[:, self.rows]
            err = self._task_error(
                goal_positions[active],
                None if goal_rotations is None else goal_rotations[active],
                placements[:, :3, 3],
                placements[:, :3, :3],
            )
            done = self._converged(err)
            reachable[active[done]] = True
            keep = ~done
            active, J, err = active[keep], J[keep], err[keep]
            if active.size == 0 or iteration == self.iterations:
                break
            norm = _row_norm(err[:, :3] if m >= 3 else err)[:, None]
            err = err * np.minimum(1.0, self.max_step / np.maximum(norm, 1e-300))
            step = self._step(J, err, Q[active])
            if self._vector_space:
                Q[active] = self._clip_limits(Q[active] + step)
            else:
                moved = np.stack([pin.integrate(model, Q[b], step[i]) for i, b in enumerate(active)])
                Q[active] = self._clip_limits(moved)
        return Q, reachable


def _row_norm(x: Array) -> Array:
    """Euclidean norm of each row of ``(A, k)`` (what ``np.linalg.norm(x, axis=1)`` computes, with
    less overhead: this runs several times per Newton step on small batches)."""
    return np.asarray(np.sqrt(np.add.reduce(x * x, axis=1)))


def redundancy_map(robot: Robot, **options: Any) -> PlanarRedundancy | NewtonRedundancy:
    """The redundancy map of ``robot``: the closed form for a planar chain, else the Newton map.

    Args:
        robot: the arm.
        **options: keyword options of :class:`PlanarRedundancy` or :class:`NewtonRedundancy`; pass
            ``general=True`` to force the Newton map on a planar arm.
    """
    general = bool(options.pop("general", False))
    if robot.planar is not None and robot.nq >= 2 and not general:
        return PlanarRedundancy(robot, **options)
    return NewtonRedundancy(robot, **options)


def joint_angles(robot: Robot, Q: Array) -> Array:
    """Joint coordinates ``(B, nv)`` [rad] of configurations ``(B, nq)`` (continuous joints as angles)."""
    if robot.nq == robot.nv:
        return np.array(Q, dtype=float)
    neutral = robot.neutral()
    return np.stack([pin.difference(robot.model, neutral, q) for q in Q])


@dataclass(frozen=True)
class Scored:
    """Genes solved and scored.

    Attributes:
        Q: ``(B, nq)`` configurations.
        reachable: ``(B,)`` whether the hand is on the target.
        S: ``(B,)`` AMSIP; ``collision_value`` (< 0) where unreachable.
        collision: ``(B,)`` whether a reachable configuration collides (False where unreachable).
    """

    Q: Array
    reachable: NDArray[np.bool_]
    S: Array
    collision: NDArray[np.bool_]


def score(
    evaluator: Evaluator,
    redundancy: RedundancyMap,
    genes: Array,
    branch: NDArray[np.int_],
    target: object,
    t: float = 0.0,
    q_seed: Array | None = None,
) -> Scored:
    """Solve genes for ``target`` and evaluate AMSIP at time ``t`` [s]; only reachable rows are evaluated."""
    Q, reachable = redundancy.solve(genes, branch, target, q_seed)
    return score_configurations(evaluator, Q, reachable, t)


def score_configurations(evaluator: Evaluator, Q: Array, reachable: NDArray[np.bool_], t: float = 0.0) -> Scored:
    """Score solved configurations ``(B, nq)``: AMSIP at time ``t`` [s] where reachable, else ``collision_value``."""
    S = np.full(Q.shape[0], evaluator.potential.collision_value)
    collision = np.zeros(Q.shape[0], dtype=bool)
    if reachable.any():
        ev = evaluator(Q[reachable], t)
        S[reachable] = ev.S
        collision[reachable] = ev.collision
    return Scored(Q, reachable, S, collision)
