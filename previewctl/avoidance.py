"""Avoidance manipulability (paper eqs. 3-17) for one configuration or a batch.

For each configuration, Pinocchio computes the kinematics once (joint Jacobians, frame placements);
the task Jacobian ``J_n`` and the control-point Jacobians ``J_i`` are read from it, then the linear
algebra runs batched over the whole population:

* ``N = I - J_n^+ J_n`` (eq. 3). ``J_n^+`` is the SVD pseudo-inverse; singular values below
  ``rank_tolerance * sigma_max(J_n)`` count as zero (default ``1e-9``).
* ``M_i = J_i N`` (eq. 6), its singular values ``sigma_i1 >= sigma_i2 >= ...``.
* ``V_i = c_p * sigma_i1 ... sigma_ip`` (eqs. 13-15) with ``c_p`` the volume of the unit p-ball
  (eq. 14) and ``p`` the point's *structural* rank (its rank at generic configurations), so that
  ``V_i`` falls continuously to 0 at a singular configuration instead of jumping to a
  lower-dimensional volume. ``ranks`` still reports the numerical rank at each configuration.
* AMSI ``E = sum_i a_i V_i / L_ref^p_i`` (eqs. 16-17): ``L_ref`` (``length_unit``) is the length
  unit of the index, by default the paper's centimetre, which makes the paper's
  ``a_1 = a_{n-1} = 1 [m^-1]``, ``a_middle = 1 [m^-2]`` read in cm: ``E = V_1[cm] + V_2[cm^2] + V_3[cm]``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from math import gamma, pi

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.robot import Robot

Array = NDArray[np.float64]


def unit_ball_volume(p: int) -> float:
    """Volume of the unit ball in ``p`` dimensions, eq. 14: c_1 = 2, c_2 = pi, c_3 = 4 pi / 3."""
    return float(pi ** (p / 2) / gamma(p / 2 + 1))


@dataclass(frozen=True)
class IndexParams:
    """Parameters of the AMSI.

    Attributes:
        weights: ``a_i`` per control point (dimensionless, applied after the unit scaling);
            ``None`` gives the paper's eq. 17 (all ones).
        length_unit: ``L_ref`` [m], the length unit of the index (default 0.01: centimetres).
        rank_tolerance: relative singular-value threshold for ``J_n^+`` and numerical ranks.
    """

    weights: tuple[float, ...] | None = None
    length_unit: float = 0.01
    rank_tolerance: float = 1e-9

    def __post_init__(self) -> None:
        if not (np.isfinite(self.length_unit) and self.length_unit > 0):
            raise ConfigurationError(f"length_unit must be a positive length [m], got {self.length_unit!r}")
        if not (0 < self.rank_tolerance < 1):
            raise ConfigurationError(f"rank_tolerance must lie in (0, 1), got {self.rank_tolerance!r}")

    def weight_vector(self, count: int) -> Array:
        """The weights ``a_i`` as an array of ``count`` entries."""
        if self.weights is None:
            return np.ones(count)
        if len(self.weights) != count:
            raise ConfigurationError(f"weights has {len(self.weights)} entries; the robot has {count} control points")
        return np.array(self.weights, dtype=float)


@dataclass(frozen=True)
class Kinematics:
    """Hand and control-point kinematics of a batch of configurations.

    Attributes:
        q: ``(B, nq)`` configurations.
        tip_position: ``(B, 3)`` hand position [m].
        tip_rotation: ``(B, 3, 3)`` hand orientation.
        J_task: ``(B, m, nv)`` task Jacobian ``J_n`` (world-aligned, at the tip).
        point_positions: ``(B, k, 3)`` control-point positions [m].
        J_points: ``(B, k, d, nv)`` control-point position Jacobians ``J_i``.
    """

    q: Array
    tip_position: Array
    tip_rotation: Array
    J_task: Array
    point_positions: Array
    J_points: Array


def kinematics(
    robot: Robot,
    Q: Array,
    data: pin.Data | None = None,
    after_each: Callable[[int, pin.Data], None] | None = None,
) -> Kinematics:
    """Forward kinematics and Jacobians, one Pinocchio pass per configuration.

    Args:
        robot: the arm.
        Q: ``(B, nq)`` validated configurations.
        data: a Pinocchio ``Data`` to reuse (one is created if ``None``).
        after_each: called as ``after_each(b, data)`` once the joint placements of configuration
            ``b`` are in ``data`` (the scene uses it to compute distances on the same pass).
    """
    model = robot.model
    data = model.createData() if data is None else data
    rows, point_rows = robot.task_rows, robot.point_rows
    tip_id, point_ids = robot.tip_frame_id, robot.control_frame_ids
    B, k = Q.shape[0], len(point_ids)
    tip_position, tip_rotation = np.empty((B, 3)), np.empty((B, 3, 3))
    J_task = np.empty((B, rows.stop - rows.start, robot.nv))
    point_positions = np.empty((B, k, 3))
    J_points = np.empty((B, k, point_rows.stop - point_rows.start, robot.nv))
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    placements = data.oMf  # held once: each attribute lookup through the bindings costs microseconds
    for b in range(B):
        pin.computeJointJacobians(model, data, Q[b])
        pin.updateFramePlacements(model, data)
        tip = placements[tip_id]
        tip_position[b], tip_rotation[b] = tip.translation, tip.rotation
        J_task[b] = pin.getFrameJacobian(model, data, tip_id, frame)[rows]
        for i, fid in enumerate(point_ids):
            point_positions[b, i] = placements[fid].translation
            J_points[b, i] = pin.getFrameJacobian(model, data, fid, frame)[point_rows]
        if after_each is not None:
            after_each(b, data)
    return Kinematics(Q, tip_position, tip_rotation, J_task, point_positions, J_points)


@dataclass(frozen=True)
class AvoidanceResult:
    """Avoidance manipulability of one configuration (unbatched shapes) or a batch (leading ``B``).

    Attributes:
        q: configuration(s).
        J_task: task Jacobian ``J_n``, ``(m, nv)``.
        J_points: control-point Jacobians ``J_i``, ``(k, d, nv)``.
        N: null-space projector ``I - J_n^+ J_n``, ``(nv, nv)``.
        M: avoidance matrices ``M_i = J_i N``, ``(k, d, nv)``.
        singular_values: of each ``M_i``, descending, ``(k, min(d, nv))``.
        ranks: numerical rank of each ``M_i``, ``(k,)``.
        structural_ranks: the ``p_i`` used for the volumes, ``(k,)``.
        volumes: ``V_i = c_p sigma_1...sigma_p`` [m^p_i], ``(k,)``.
        amsi: ``E = sum a_i V_i / L_ref^p_i`` (dimensionless), scalar.
    """

    q: Array
    J_task: Array
    J_points: Array
    N: Array
    M: Array
    singular_values: Array
    ranks: NDArray[np.int_]
    structural_ranks: NDArray[np.int_]
    volumes: Array
    amsi: Array


def null_space_projector(J: Array, rank_tolerance: float = 1e-9) -> Array:
    """``N = I - J^+ J`` for ``J`` of shape ``(..., m, n)``; returns ``(..., n, n)``.

    ``J^+ = J^T (J J^T)^+`` with ``(J J^T)^+`` from a symmetric eigendecomposition (an m x m problem
    instead of an SVD of J): eigenvalues below ``rank_tolerance^2 * lambda_max`` -- singular values
    of J below ``rank_tolerance * sigma_max`` -- count as zero.
    """
    n = J.shape[-1]
    JT = np.swapaxes(J, -1, -2)
    lam, vec = np.linalg.eigh(J @ JT)
    keep = lam > rank_tolerance**2 * lam[..., -1:]
    inv = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    gram_pinv = (vec * inv[..., None, :]) @ np.swapaxes(vec, -1, -2)
    return np.eye(n) - JT @ gram_pinv @ J


def elementary_symmetric(G: Array, p: int) -> Array:
    """Sum of the principal ``p x p`` minors of symmetric ``G`` ``(..., d, d)`` (d <= 3).

    For ``G = M M^T`` with ``rank M <= p`` this is ``(sigma_1 ... sigma_p)^2`` exactly: the product of
    the ``p`` leading squared singular values, in closed form.
    """
    d = G.shape[-1]
    if p == 1:
        return np.trace(G, axis1=-2, axis2=-1)
    if p == d:
        return np.linalg.det(G)
    if p == 2 and d == 3:
        g = G
        return (
            g[..., 0, 0] * g[..., 1, 1] - g[..., 0, 1] ** 2
            + g[..., 0, 0] * g[..., 2, 2] - g[..., 0, 2] ** 2
            + g[..., 1, 1] * g[..., 2, 2] - g[..., 1, 2] ** 2
        )
    raise ValueError(f"elementary_symmetric supports d <= 3 and 1 <= p <= d, got d={d}, p={p}")


def volumes_from_singular_values(singular_values: Array, ranks: tuple[int, ...] | NDArray[np.int_]) -> Array:
    """``V_i = c_p prod_{j<p} sigma_j`` for ``singular_values`` of shape ``(..., k, r)``; 0 when p = 0."""
    out = np.zeros(singular_values.shape[:-1])
    for i, p in enumerate(ranks):
        if p > 0:
            out[..., i] = unit_ball_volume(int(p)) * np.prod(singular_values[..., i, :p], axis=-1)
    return out


def amsi_from_volumes(volumes: Array, ranks: tuple[int, ...] | NDArray[np.int_], params: IndexParams) -> Array:
    """``E = sum_i a_i V_i / L_ref^p_i`` for ``volumes`` of shape ``(..., k)``."""
    scale = params.weight_vector(volumes.shape[-1]) / params.length_unit ** np.asarray(ranks, dtype=float)
    return np.asarray(volumes @ scale)


def amsi_from_kinematics(robot: Robot, kin: Kinematics, params: IndexParams) -> Array:
    """AMSI ``(B,)`` without an SVD: ``V_i = c_p sqrt(e_p(M_i M_i^T))`` with the structural ``p``."""
    N = null_space_projector(kin.J_task, params.rank_tolerance)
    M = kin.J_points @ N[:, None]
    G = M @ np.swapaxes(M, -1, -2)
    volumes = np.zeros(G.shape[:2])
    for i, p in enumerate(robot.structural_ranks):
        if p > 0:
            volumes[:, i] = unit_ball_volume(p) * np.sqrt(np.maximum(elementary_symmetric(G[:, i], p), 0.0))
    return amsi_from_volumes(volumes, robot.structural_ranks, params)


def avoidance_from_kinematics(
    robot: Robot, kin: Kinematics, params: IndexParams, use_structural_ranks: bool = True
) -> AvoidanceResult:
    """Batched eqs. 3-17 from precomputed kinematics."""
    N = null_space_projector(kin.J_task, params.rank_tolerance)
    M = kin.J_points @ N[:, None]
    sv = np.linalg.svd(M, compute_uv=False) if M.size else np.zeros((*M.shape[:2], 0))
    scale = np.linalg.svd(kin.J_task, compute_uv=False)[:, :1] if kin.J_task.size else np.ones((len(M), 1))
    tol = params.rank_tolerance * np.maximum(scale, np.finfo(float).tiny)
    ranks = (sv > tol[:, :, None]).sum(axis=-1)
    if use_structural_ranks:
        p = np.array(robot.structural_ranks, dtype=int)
    else:
        p = ranks.max(axis=0) if len(ranks) else np.zeros(len(robot.control_points), dtype=int)
    volumes = volumes_from_singular_values(sv, p)
    return AvoidanceResult(
        q=kin.q,
        J_task=kin.J_task,
        J_points=kin.J_points,
        N=N,
        M=M,
        singular_values=sv,
        ranks=ranks,
        structural_ranks=p,
        volumes=volumes,
        amsi=amsi_from_volumes(volumes, p, params),
    )


def avoidance(
    robot: Robot, q: object, params: IndexParams | None = None, *, use_structural_ranks: bool = True
) -> AvoidanceResult:
    """Avoidance manipulability of ``q`` (``(nq,)``) or of a batch ``(B, nq)``.

    Args:
        robot: the arm.
        q: configuration(s) [rad].
        params: AMSI parameters (defaults: paper weights, centimetre unit).
        use_structural_ranks: volumes use each point's generic rank (default); ``False`` uses the
            largest rank found in this batch (used once, when the robot is loaded).

    Returns:
        The result, with unbatched shapes for a single configuration.

    Raises:
        ConfigurationError: ``q`` of the wrong length or with a non-finite entry.
    """
    Q, single = robot.check_configurations(q)
    result = avoidance_from_kinematics(robot, kinematics(robot, Q), params or IndexParams(), use_structural_ranks)
    if not single:
        return result
    return AvoidanceResult(
        q=result.q[0],
        J_task=result.J_task[0],
        J_points=result.J_points[0],
        N=result.N[0],
        M=result.M[0],
        singular_values=result.singular_values[0],
        ranks=result.ranks[0],
        structural_ranks=result.structural_ranks,
        volumes=result.volumes[0],
        amsi=result.amsi[0],
    )
