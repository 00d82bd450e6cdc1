"""Closed-form, fully vectorised kinematics and AMSI for planar arms of revolute z joints.

With ``theta_j = q_1 + ... + q_j`` and joint origins ``o_j``, a point ``r`` downstream of joint ``j``
has Jacobian column ``e_z x (r - o_j)``. The avoidance Gram matrix of control point ``i`` is

    G_i = M_i M_i^T = J_i N J_i^T = J_i J_i^T - (J_i J_n^T) (J_n J_n^T)^+ (J_n J_i^T),

a 2x2 matrix per configuration, so ``sigma_1 sigma_2 = sqrt(det G_i)`` and
``sigma_1 = sqrt(lambda_max(G_i))`` need no SVD. Every quantity is an elementwise array operation
over the batch; this is what makes ~10^6 configurations per second possible.
"""

from __future__ import annotations

import numpy as np

from previewctl.index.amsi import IndexParams, amsi_weights, unit_ball_volume
from previewctl.robot.planar import PlanarChain
from previewctl.types import Array


class PlanarArm:
    """The closed-form path of one planar chain. Its constants (link offsets, capsule ends, AMSI
    weights) are prepared once, and link vectors and capsule ends are computed for all links in one
    array operation: on a small batch (a GA population) the number of numpy calls sets the cost.

    Args:
        chain: the planar chain.
        ranks: structural rank of each control point's avoidance matrix.
        params: AMSI parameters.
    """

    def __init__(self, chain: PlanarChain, ranks: tuple[int, ...], params: IndexParams) -> None:
        self.chain, self.params = chain, params
        self._weights = amsi_weights(ranks, params)
        steps = np.vstack([chain.offsets[1:], chain.tip_offset])  # each joint's successor in its frame
        self._dx, self._dy = steps[:, :1], steps[:, 1:]  # (n, 1) [m]
        self._base = np.asarray(chain.offsets[0], dtype=float)[:, None]
        self._ranks = tuple(int(p) for p in ranks)
        self._link_joints = np.array(chain.link_joints)
        self._lx = chain.link_segments[..., 0, None]  # (L, 2, 1) [m]
        self._ly = chain.link_segments[..., 1, None]

    def joint_origins(self, Q: Array) -> tuple[Array, Array]:
        """Joint origins and the tip for a batch.

        Args:
            Q: ``(B, n)`` joint angles [rad].

        Returns:
            ``points`` ``(2, n + 1, B)`` [m] (x then y; joint origins, then the tip) and the cosines
            and sines ``(2, n, B)`` of the absolute link angles ``theta_j = q_1 + ... + q_j`` (kept for
            :meth:`link_segments`: float64 trigonometry is the costliest step here). Joint-major layout
            keeps every per-joint slice contiguous.
        """
        # running sums as row-by-row additions: numpy's accumulate along a leading axis is ~10x slower
        theta = np.array(Q.T)
        for k in range(1, theta.shape[0]):
            theta[k] += theta[k - 1]
        trig = np.empty((2, *theta.shape))
        np.cos(theta, out=trig[0])
        np.sin(theta, out=trig[1])
        cos, sin = trig
        # row 0 holds the base, rows k >= 1 the k-th link vector, then their running sum
        points = np.empty((2, Q.shape[1] + 1, Q.shape[0]))
        points[:, 0] = self._base
        points[0, 1:] = cos * self._dx - sin * self._dy
        points[1, 1:] = sin * self._dx + cos * self._dy
        for k in range(1, points.shape[1]):
            points[:, k] += points[:, k - 1]
        return points, trig

    def amsi(self, points: Array) -> tuple[Array, Array]:
        """Volumes ``(B, k)`` [m^p_i] and AMSI ``(B,)`` from the joint origins ``(2, n + 1, B)``.

        The task pseudo-inverse uses the same relative tolerance as the general path: an eigenvalue
        of ``J_n J_n^T`` below ``rank_tolerance^2 * lambda_max`` counts as zero.
        """
        n = points.shape[1] - 1
        jx, jy = _jacobian(points, n)
        a, b, c = _dot(jx, jx), _dot(jx, jy), _dot(jy, jy)
        lam_max, lam_min = _eig2(a, b, c)
        full = lam_min > self.params.rank_tolerance**2 * lam_max
        det = np.where(full, a * c - b * b, 1.0)
        positive = lam_max > 0
        inv_lmax2 = np.where(positive, 1.0 / np.where(positive, lam_max, 1.0) ** 2, 0.0)
        # (J J^T)^+ : the inverse when full rank, A / lambda_max^2 when rank one.
        pa = np.where(full, c / det, a * inv_lmax2)
        pb = np.where(full, -b / det, b * inv_lmax2)
        pc = np.where(full, a / det, c * inv_lmax2)
        volumes = np.zeros((points.shape[2], len(self._ranks)))
        for i, (joint, rank) in enumerate(zip(self.chain.control_joints, self._ranks, strict=True)):
            if joint == 0 or rank == 0:  # the base joint's origin never moves: V = 0
                continue
            kx, ky = _jacobian(points, joint)
            # P = J_i J_n^T, G = J_i J_i^T - P A^+ P^T (only the point's own columns are non-zero)
            p11, p12 = _dot(kx, jx[:joint]), _dot(kx, jy[:joint])
            p21, p22 = _dot(ky, jx[:joint]), _dot(ky, jy[:joint])
            g11 = _dot(kx, kx) - (p11 * (pa * p11 + pb * p12) + p12 * (pb * p11 + pc * p12))
            g12 = _dot(kx, ky) - (p11 * (pa * p21 + pb * p22) + p12 * (pb * p21 + pc * p22))
            g22 = _dot(ky, ky) - (p21 * (pa * p21 + pb * p22) + p22 * (pb * p21 + pc * p22))
            squared = g11 * g22 - g12 * g12 if rank == 2 else _eig2(g11, g12, g22)[0]
            volumes[:, i] = unit_ball_volume(rank) * np.sqrt(np.maximum(squared, 0.0))
        return volumes, np.asarray(volumes @ self._weights)

    def link_segments(self, points: Array, trig: Array) -> tuple[Array, Array]:
        """End points ``a``, ``b`` ``(B, L, 3)`` [m] of the guarded capsules' axes (z = 0), from the
        joint origins and link-angle cosines/sines of :meth:`joint_origins`."""
        joints = self._link_joints
        (cos, sin), (x, y) = trig[:, joints, None], points[:, joints, None]  # (L, 1, B)
        ends = np.zeros((2, points.shape[2], joints.size, 3))  # (end, B, L, xyz)
        ends[..., 0] = (x + cos * self._lx - sin * self._ly).transpose(1, 2, 0)
        ends[..., 1] = (y + sin * self._lx + cos * self._ly).transpose(1, 2, 0)
        return ends[0], ends[1]


def _jacobian(points: Array, index: int) -> tuple[Array, Array]:
    """Rows ``(Jx, Jy)`` ``(index, B)`` of the planar Jacobian of point ``index``: its non-zero columns.

    Column ``j < index`` is ``e_z x (r - o_j)``; the columns of joints downstream of the point are 0
    and are left out.
    """
    x, y = points[0], points[1]
    return y[:index] - y[index], x[index] - x[:index]


def _dot(u: Array, v: Array) -> Array:
    """Column-wise dot product of two ``(j, B)`` arrays: their rows multiplied and added in order."""
    return np.add.reduce(u * v, axis=0)


def _eig2(a: Array, b: Array, c: Array) -> tuple[Array, Array]:
    """Eigenvalues (max, min) of the symmetric 2x2 matrices ``[[a, b], [b, c]]``."""
    half_trace = 0.5 * (a + c)
    root = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return half_trace + root, half_trace - root
