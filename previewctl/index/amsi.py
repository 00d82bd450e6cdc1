"""Avoidance manipulability (paper eqs. 3-17) for one configuration or a batch.

For each configuration, Pinocchio computes the kinematics once (joint placements and Jacobians);
the task Jacobian ``J_n`` and the control-point Jacobians ``J_i`` are assembled from it for the whole
batch (:class:`~previewctl.kinematics.FrameKinematics`), then the linear algebra runs batched over the population too:

* ``N = I - J_n^+ J_n`` (eq. 3) from the SVD of ``J_n``: singular values below
  ``rank_tolerance * sigma_max(J_n)`` count as zero (``rank_tolerance`` defaults to ``1e-9``), and
  ``|J_n N| <~ 1e-14 sigma_max`` holds at every configuration (:func:`null_space_projector`). The
  AMSI-only fast path (:func:`amsi_from_kinematics`) uses the m x m Gram matrix instead, which resolves
  singular values down to about ``1e-7 sigma_max`` (:func:`gram_pseudo_inverse`).
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

from dataclasses import dataclass
from math import gamma, pi
from typing import Annotated

import numba
import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ParameterError
from previewctl.kinematics import Kinematics, kinematics
from previewctl.robot.model import Robot
from previewctl.types import Array
from previewctl.validation import Checked, Finite, NonNegative, Positive, interval

RANK_TOLERANCE = 1e-9
"""Singular values of ``J_n`` below this share of ``σ_max`` count as zero (eq. 3's ``J_n⁺``; the default)."""


def unit_ball_volume(p: int) -> float:
    """Volume of the unit ball in ``p`` dimensions, eq. 14: c_1 = 2, c_2 = pi, c_3 = 4 pi / 3."""
    return float(pi ** (p / 2) / gamma(p / 2 + 1))


@dataclass(frozen=True)
class IndexParams(Checked):
    """Parameters of the AMSI.

    Attributes:
        weights: ``a_i`` per control point (dimensionless, applied after the unit scaling);
            ``None`` gives the paper's eq. 17 (all ones).
        length_unit: ``L_ref`` [m], the length unit of the index (default 0.01: centimetres).
        rank_tolerance: relative singular-value threshold for ``J_n^+`` and numerical ranks.
    """

    weights: tuple[NonNegative, ...] | None = None
    length_unit: Positive = 0.01
    rank_tolerance: Annotated[Finite, interval(0, 1, "()")] = RANK_TOLERANCE

    def weight_vector(self, count: int) -> Array:
        """The weights ``a_i`` as an array of ``count`` entries."""
        if self.weights is None:
            return np.ones(count)
        if len(self.weights) != count:
            raise ParameterError(f"weights has {len(self.weights)} entries; the robot has {count} control points")
        return np.array(self.weights, dtype=float)


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


def gram_pseudo_inverse(J: Array, rank_tolerance: float = RANK_TOLERANCE) -> Array:
    """``(J J^T)^+`` for ``J`` of shape ``(..., m, n)``; returns ``(..., m, m)``.

    Eigenvalues of ``J J^T`` below ``c * lambda_max`` count as zero, with ``c = max(rank_tolerance^2,
    10 n eps)``: singular values of ``J`` below ``rank_tolerance * sigma_max``, and those the Gram
    matrix cannot resolve from rounding (below about ``1e-7 sigma_max``), are treated as zero (a
    symmetric eigendecomposition). For ``m <= 3`` the well-conditioned matrices (``lambda_min /
    lambda_max`` above about ``1e-8``, where the plain inverse is the pseudo-inverse) are inverted in
    closed form, several times faster than LAPACK on stacks of small matrices.
    """
    gram = J @ np.ascontiguousarray(np.swapaxes(J, -1, -2))
    cutoff = max(rank_tolerance**2, 10 * J.shape[-1] * float(np.finfo(float).eps))
    m = gram.shape[-1]
    if m > 3 or gram.size == 0:
        return _eigh_pseudo_inverse(gram, cutoff)
    adjugate, det = _adjugate(gram)
    trace = np.trace(gram, axis1=-2, axis2=-1)
    good = det > 1e-8 * (trace / m) ** m  # >= lambda_min lambda_max^(m-1) / m^m: conditioning
    out = adjugate / np.where(good, det, 1.0)[..., None, None]
    if not good.all():
        out[~good] = _eigh_pseudo_inverse(gram[~good], cutoff)
    return out


def _adjugate(G: Array) -> tuple[Array, Array]:
    """Adjugate and determinant of symmetric ``G`` ``(..., m, m)``, ``m <= 3``, in closed form."""
    m = G.shape[-1]
    adj = np.empty_like(G)
    if m == 1:
        adj[..., 0, 0] = 1.0
        return adj, G[..., 0, 0]
    if m == 2:
        adj[..., 0, 0], adj[..., 1, 1] = G[..., 1, 1], G[..., 0, 0]
        adj[..., 0, 1] = adj[..., 1, 0] = -G[..., 0, 1]
        return adj, G[..., 0, 0] * G[..., 1, 1] - G[..., 0, 1] ** 2
    a, b, c = G[..., 0, 0], G[..., 0, 1], G[..., 0, 2]
    d, e, f = G[..., 1, 1], G[..., 1, 2], G[..., 2, 2]
    adj[..., 0, 0] = d * f - e * e
    adj[..., 1, 1] = a * f - c * c
    adj[..., 2, 2] = a * d - b * b
    adj[..., 0, 1] = adj[..., 1, 0] = c * e - b * f
    adj[..., 0, 2] = adj[..., 2, 0] = b * e - c * d
    adj[..., 1, 2] = adj[..., 2, 1] = b * c - a * e
    return adj, a * adj[..., 0, 0] + b * adj[..., 0, 1] + c * adj[..., 0, 2]


def _eigh_pseudo_inverse(G: Array, cutoff: float) -> Array:
    lam, vec = np.linalg.eigh(G)
    keep = lam > cutoff * lam[..., -1:]
    inv = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    return (vec * inv[..., None, :]) @ np.swapaxes(vec, -1, -2)


def null_space_projector(J: Array, rank_tolerance: float = RANK_TOLERANCE) -> Array:
    """``N = I - J^+ J`` for ``J`` of shape ``(..., m, n)``; returns ``(..., n, n)``.

    From the SVD ``J = U S V^T``: ``N = I - V_r V_r^T`` with the ``r`` singular values above
    ``rank_tolerance * sigma_max`` (a relative cutoff). Exact to rounding, ``|J N| <~ 10 eps sigma_max``,
    also near a singularity, where the Gram route ``J^T (J J^T)^+ J`` loses ``eps cond(J)^2``.
    """
    n = J.shape[-1]
    if J.size == 0:
        return np.broadcast_to(np.eye(n), (*J.shape[:-2], n, n)).copy()
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    return projector_from_svd(s, Vt, rank_tolerance)


def projector_from_svd(s: Array, Vt: Array, rank_tolerance: float = RANK_TOLERANCE) -> Array:
    """``N = I - V_r V_r^T`` of :func:`null_space_projector` from the singular values ``s`` ``(..., k)`` and ``V^T``
    ``(..., k, n)`` of an SVD of ``J`` taken already (one SVD then serves the pseudo-inverse too)."""
    V_r = Vt * (s > rank_tolerance * s[..., :1])[..., None]
    return np.eye(Vt.shape[-1]) - np.swapaxes(V_r, -1, -2) @ V_r


@numba.njit(cache=True, nogil=True)
def projector_from_svd_of_one(s: Array, Vt: Array, rank_tolerance: float) -> Array:  # pragma: no cover - compiled
    """:func:`projector_from_svd` of one matrix (``s`` ``(k,)``, ``Vt`` ``(k, n)``), compiled for eq. 19's
    once-per-cycle projector: the same arithmetic, so the same bits (a test checks them)."""
    keep = s > rank_tolerance * s[0]
    V_r = Vt * keep.reshape(-1, 1)
    return np.eye(Vt.shape[1]) - V_r.T @ V_r


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


def amsi_weights(ranks: tuple[int, ...] | NDArray[np.int_], params: IndexParams) -> Array:
    """``(k,)`` factors ``a_i / L_ref^p_i`` of the volumes in the AMSI."""
    exponents = np.asarray(ranks, dtype=float)
    return params.weight_vector(exponents.size) / params.length_unit**exponents


def amsi_from_volumes(volumes: Array, ranks: tuple[int, ...] | NDArray[np.int_], params: IndexParams) -> Array:
    """``E = sum_i a_i V_i / L_ref^p_i`` for ``volumes`` of shape ``(..., k)``."""
    return np.asarray(volumes @ amsi_weights(ranks, params))


def amsi_from_kinematics(robot: Robot, kin: Kinematics, params: IndexParams) -> Array:
    """AMSI ``(B,)`` without an SVD: ``V_i = c_p sqrt(e_p(M_i M_i^T))`` with the structural ``p``.

    ``N`` is symmetric and idempotent, so ``M_i M_i^T = J_i N J_i^T = J_i J_i^T - A_i (J_n J_n^T)^+ A_i^T``
    with ``A_i = J_i J_n^T``: small ``d x m`` products instead of ``n x n`` ones.
    """
    B, k, d, nv = kin.J_points.shape
    J_points = kin.J_points.reshape(B, k * d, nv)
    A = J_points @ np.ascontiguousarray(np.swapaxes(kin.J_task, 1, 2))
    G = J_points @ np.ascontiguousarray(np.swapaxes(J_points, 1, 2))
    G -= A @ gram_pseudo_inverse(kin.J_task, params.rank_tolerance) @ np.ascontiguousarray(np.swapaxes(A, 1, 2))
    volumes = np.zeros((B, k))
    for i, p in enumerate(robot.structural_ranks):
        if p > 0:
            block = G[:, i * d : (i + 1) * d, i * d : (i + 1) * d]
            volumes[:, i] = unit_ball_volume(p) * np.sqrt(np.maximum(elementary_symmetric(block, p), 0.0))
    return amsi_from_volumes(volumes, robot.structural_ranks, params)


def avoidance_from_kinematics(
    robot: Robot, kin: Kinematics, params: IndexParams, use_structural_ranks: bool = True
) -> AvoidanceResult:
    """Batched eqs. 3-17 from precomputed kinematics."""
    N = null_space_projector(kin.J_task, params.rank_tolerance)
    M = kin.J_points @ N[:, None]
    sv = np.asarray(np.linalg.svd(M, compute_uv=False) if M.size else np.zeros((*M.shape[:2], 0)), dtype=np.float64)
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
