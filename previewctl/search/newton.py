"""The general redundancy map: free genes, then damped Newton steps onto ``f(q) = x`` within joint limits."""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.robot.compiled_kinematics import CompiledKinematics
from previewctl.robot.model import Robot
from previewctl.search.redundancy import Target, check_genes, parse_target, wrap_angle
from previewctl.types import Array
from previewctl.validation import show


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
        periodic: ``(nv,)`` true for the coordinates without two finite limits (``~robot.joints.bounded``):
            wrapped, not clipped. A bounded joint spanning more than a turn keeps its limits here.
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
        self._compiled = CompiledKinematics.of(self.model)
        tip = self.model.frames[self.tip_id]
        self._tip_joint, self._tip_offset = np.array([tip.parentJoint]), np.array([tip.placement.homogeneous])
        facts = robot.joints
        # genes: the bounded coordinates between their limits (clipped), every other one an angle (wrapped)
        self.periodic = ~facts.bounded
        self.gene_lower = np.where(facts.bounded, facts.lower, -np.pi)
        self.gene_upper = np.where(facts.bounded, facts.upper, np.pi)
        self._clip_v = np.flatnonzero(facts.bounded)
        self._clip = facts.q_index[self._clip_v]
        self._vector_space = facts.vector_space  # pin.integrate is plain addition, done for the batch
        self._q_lower = facts.lower[self._clip_v]
        self._q_upper = facts.upper[self._clip_v]
        self._lower_margin, self._upper_margin = self._q_lower + 1e-9, self._q_upper - 1e-9

    # ------------------------------------------------------------------ genes <-> configurations

    def configurations(self, genes: Array) -> Array:
        """Configurations ``(B, nq)`` of joint-angle vectors ``(B, nv)`` (no projection)."""
        return self.robot.configurations_from_angles(genes)

    def genes_of(self, Q: Array) -> tuple[Array, NDArray[np.int_]]:
        """Joint angles ``(B, nv)`` of configurations ``(B, nq)``; branch 0."""
        Qb, _ = self.robot.check_configurations(Q)
        genes = self.robot.angles_of(Qb)
        genes = np.where(self.periodic, wrap_angle(genes), genes)
        return genes, np.zeros(Qb.shape[0], dtype=int)

    # ----------------------------------------------------------------------------- projection

    def _hand(self, Q: Array) -> tuple[Array, Array]:
        """Hand placements ``(A, 4, 4)`` and world-aligned Jacobians ``(A, 6, nv)`` (linear rows first).

        The whole batch in one compiled call (:mod:`~previewctl.robot.compiled_kinematics`) where the model allows
        it, else one ``computeFrameJacobian`` per row.
        """
        if self._compiled is not None:
            H, J = self._compiled.frames(Q, self._tip_joint, self._tip_offset)
            return H[:, 0], J[:, 0]
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
        """Damped least-squares steps ``(A, nv)`` toward task errors ``err`` ``(A, m)`` (clamped to ``max_step``);
        joints at a limit that the step pushes further are frozen (module docstring of
        :mod:`~previewctl.search.redundancy`)."""
        step = np.empty((J.shape[0], J.shape[2]))
        _damped_steps(np.ascontiguousarray(J), np.ascontiguousarray(err), np.ascontiguousarray(Q[:, self._clip]),
                      self._clip_v, self._lower_margin, self._upper_margin, self.damping**2, self.max_step,
                      min(self.m, 3), step)
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
        self, genes: Array, branch: NDArray[np.int_], targets: Sequence[object], groups: object,
        q_seed: Array | None = None,
    ) -> tuple[Array, NDArray[np.bool_]]:
        """:meth:`solve` for rows aimed at different targets: row ``b`` goes to ``targets[groups[b]]``.

        Row for row the same result as :meth:`solve` on each group (rows never interact), in one
        iteration whose per-step overhead is paid once: the preview controller projects the
        populations of all its imaginary arms together, the roadmap the sub-steps of a layer.

        Raises:
            ConfigurationError: ``groups`` not one index in ``[0, len(targets))`` per row.
        """
        G = self._checked_genes(genes, branch)
        index = np.asarray(groups)
        if (index.shape != (G.shape[0],) or not np.issubdtype(index.dtype, np.integer)
                or (index.size and (index.min() < 0 or index.max() >= len(targets)))):
            raise ConfigurationError(
                f"groups must hold one target index in [0, {len(targets)}) per gene row ({G.shape[0]}), "
                f"got {show(groups)}"
            )
        return self._project(G, [self._goal(target) for target in targets], index, q_seed)

    def _checked_genes(self, genes: Array, branch: NDArray[np.int_]) -> Array:
        G, _ = check_genes(genes, branch, self.robot.nv, self.branches)
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
        B = G.shape[0]
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


@numba.njit(cache=True, nogil=True)
def _damped_steps(J: Array, err: Array, q: Array, clip_v: NDArray[np.intp], lower: Array, upper: Array, damping2: float,
                  max_step: float, position_rows: int, out: Array) -> None:  # pragma: no cover - compiled
    """For each row: ``e`` = ``err`` scaled so that its first ``position_rows`` entries have norm at most
    ``max_step``; ``λ² = damping2 · clip(|e_pos| / max_step, 1e-3, 1)``; ``out = Jᵀ (J Jᵀ + λ² I)⁻¹ e`` (Cholesky),
    again with the columns ``clip_v`` zeroed where ``q`` sits at ``lower`` or ``upper`` and the step pushes on."""
    A, m, nv = J.shape
    Jf = np.empty((m, nv))
    G = np.empty((m, m))
    x = np.empty(m)
    e = np.empty(m)
    for b in range(A):
        norm = 0.0
        for i in range(position_rows):
            norm += err[b, i] * err[b, i]
        norm = np.sqrt(norm)
        scale = min(1.0, max_step / max(norm, 1e-300))
        for i in range(m):
            e[i] = err[b, i] * scale
        lam = damping2 * min(max(norm * scale / max_step, 1e-3), 1.0)
        Jf[:] = J[b]
        _solve_damped(Jf, e, lam, G, x, out[b])
        blocked = False
        for c in range(len(clip_v)):
            v = clip_v[c]
            if (q[b, c] <= lower[c] and out[b, v] < 0) or (q[b, c] >= upper[c] and out[b, v] > 0):
                blocked = True
                Jf[:, v] = 0.0
        if blocked:
            _solve_damped(Jf, e, lam, G, x, out[b])


@numba.njit(cache=True, nogil=True)
def _solve_damped(J: Array, e: Array, lam: float, G: Array, x: Array, out: Array) -> None:  # pragma: no cover
    """``out = Jᵀ (J Jᵀ + lam I)⁻¹ e`` for one ``(m, nv)`` Jacobian, by Cholesky (``G``, ``x``: workspaces)."""
    m, nv = J.shape
    for i in range(m):
        for k in range(i + 1):
            total = lam if i == k else 0.0
            for j in range(nv):
                total += J[i, j] * J[k, j]
            G[i, k] = total
    for i in range(m):  # G = L Lᵀ, L in the lower triangle
        for k in range(i + 1):
            total = G[i, k]
            for j in range(k):
                total -= G[i, j] * G[k, j]
            G[i, k] = np.sqrt(total) if i == k else total / G[k, k]
    for i in range(m):  # L y = e
        total = e[i]
        for j in range(i):
            total -= G[i, j] * x[j]
        x[i] = total / G[i, i]
    for i in range(m - 1, -1, -1):  # Lᵀ x = y
        total = x[i]
        for j in range(i + 1, m):
            total -= G[j, i] * x[j]
        x[i] = total / G[i, i]
    for j in range(nv):
        total = 0.0
        for i in range(m):
            total += J[i, j] * x[i]
        out[j] = total
