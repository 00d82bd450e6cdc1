"""Redundancy maps: from a few free parameters ("genes") to configurations that put the hand on a target.

For a hand target ``x`` the candidates of the search are the configurations with ``f(q) = x`` (the
self-motion manifold). A :class:`RedundancyMap` parameterises them:

* :class:`~previewctl.search.planar.PlanarRedundancy` (planar arms of revolute z joints, the paper's section 4.3):
  the genes are the first ``n - 2`` joint angles; they fix the origin ``w`` of joint ``n - 1`` (the "wrist"), and the
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

* :class:`~previewctl.search.newton.NewtonRedundancy` (any other arm): the genes are a full vector of ``nv`` joint
  angles within the joint limits, used as the start of damped-least-squares Newton steps onto ``f(q) = target``::

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

:func:`~previewctl.search.scoring.score` solves genes and evaluates AMSIP for the reachable ones; unreachable
candidates get ``S = evaluator.potential.collision_value`` (< 0): as in the paper, S < 0 exactly when the configuration
collides *or* cannot reach the hand target.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.robot.joints import FULL_TURN
from previewctl.robot.model import Robot
from previewctl.types import Array
from previewctl.validation import rotation_matrix, show


def wrap_angle(angle: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """Wrap angles [rad] to ``[-pi, pi)`` (``floor`` instead of the much slower ``%`` on floats)."""
    x = np.asarray(angle, dtype=float)
    out = np.asarray(x - FULL_TURN * np.floor((x + np.pi) * (1.0 / FULL_TURN)))
    out[out >= np.pi] -= FULL_TURN  # rounding at the borders
    out[out < -np.pi] += FULL_TURN
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
            raise ConfigurationError(f"target must be numbers [m], got {show(target)}") from exc
        if arr.shape == (4, 4):
            position, rotation = arr[:3, 3].copy(), arr[:3, :3].copy()
        else:
            position = arr
    if position.shape not in ((2,), (3,)):
        raise ConfigurationError(
            f"target position has shape {position.shape}; robot {robot.name!r} (task {robot.task!r}) needs "
            f"(2,) or (3,) [m]{' plus a (3, 3) rotation' if robot.task == 'pose' else ''}: got {show(target)}"
        )
    if not np.all(np.isfinite(position)) or (rotation is not None and not np.all(np.isfinite(rotation))):
        raise ConfigurationError(f"target must be finite, got {show(target)}")
    planar = position.shape == (2,)
    if planar:
        position = np.array([position[0], position[1], 0.0])
    if rotation is not None:
        rotation = rotation_matrix(rotation, "target rotation", ConfigurationError)
    if robot.task == "pose" and rotation is None:
        raise ConfigurationError(
            f"robot {robot.name!r} has a pose task: give the target as (position (3,), rotation (3, 3)), "
            f"a pin.SE3 or a (4, 4) matrix, got {show(target)}"
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


def check_genes(genes: object, branch: object, g: int, branches: int) -> tuple[Array, NDArray[np.int_]]:
    G = np.array(genes, dtype=float)
    if G.ndim == 1 and g > 0 and G.shape[0] == g:
        G = G[None]
    if G.ndim != 2 or G.shape[1] != g:
        raise ConfigurationError(f"genes has shape {G.shape}; expected (B, {g})")
    if not np.all(np.isfinite(G)):
        raise ConfigurationError(f"genes must be finite, got {show(G.tolist())}")
    br = np.broadcast_to(np.asarray(branch), (G.shape[0],))
    if br.dtype.kind not in "iub":
        raise ConfigurationError(f"branch must be integers, got dtype {br.dtype}")
    br = br.astype(int)
    if ((br < 0) | (br >= branches)).any():
        bad = br[(br < 0) | (br >= branches)][0]
        raise ConfigurationError(f"branch {bad} out of range; valid: 0..{branches - 1}")
    return G, br


def fit_limits(Q: Array, lower: Array, upper: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Angles already in ``[-pi, pi)`` shifted by ``+-2 pi`` where that puts them within limits."""
    out = Q.copy()
    ok = np.ones(Q.shape[0], dtype=bool)
    for j in range(Q.shape[1]):
        col = Q[:, j]
        inside = (col >= lower[j]) & (col <= upper[j])
        up, down = col + FULL_TURN, col - FULL_TURN
        in_up = (up >= lower[j]) & (up <= upper[j])
        in_down = (down >= lower[j]) & (down <= upper[j])
        out[:, j] = np.where(inside, col, np.where(in_up, up, np.where(in_down, down, col)))
        ok &= inside | in_up | in_down
    return out, ok
