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
from numpy.typing import NDArray

from previewctl.avoidance import IndexParams, amsi_from_volumes, unit_ball_volume
from previewctl.robot import PlanarChain

Array = NDArray[np.float64]


def joint_origins(chain: PlanarChain, Q: Array) -> tuple[Array, Array]:
    """Joint origins and the tip for a batch.

    Args:
        chain: the planar chain.
        Q: ``(B, n)`` joint angles [rad].

    Returns:
        ``points`` ``(2, n + 1, B)`` [m] (x then y; joint origins, then the tip) and the cosines and
        sines ``(2, n, B)`` of the absolute link angles ``theta_j = q_1 + ... + q_j`` (kept for
        :func:`link_segments`: float64 trigonometry is the costliest step here). Joint-major layout
        keeps every per-joint slice contiguous, so the arithmetic below is elementwise on ``(B,)``
        arrays.
    """
    theta = np.cumsum(Q.T, axis=0)
    trig = np.empty((2, *theta.shape))
    np.cos(theta, out=trig[0])
    np.sin(theta, out=trig[1])
    cos, sin = trig
    n = Q.shape[1]
    points = np.empty((2, n + 1, Q.shape[0]))
    points[0, 0], points[1, 0] = chain.offsets[0]
    for k in range(1, n + 1):
        dx, dy = chain.offsets[k] if k < n else chain.tip_offset
        c, s = cos[k - 1], sin[k - 1]
        points[0, k] = points[0, k - 1] + c * dx - s * dy
        points[1, k] = points[1, k - 1] + s * dx + c * dy
    return points, trig


def jacobian(points: Array, index: int) -> tuple[Array, Array]:
    """Rows ``(Jx, Jy)`` ``(index, B)`` of the planar Jacobian of point ``index``: its non-zero columns.

    Column ``j < index`` is ``e_z x (r - o_j)``; the columns of joints downstream of the point are 0
    and are left out.
    """
    x, y = points[0], points[1]
    return y[:index] - y[index], x[index] - x[:index]


def amsi(chain: PlanarChain, points: Array, ranks: tuple[int, ...], params: IndexParams) -> tuple[Array, Array]:
    """Volumes ``(B, k)`` [m^p_i] and AMSI ``(B,)`` from the joint origins ``(2, n + 1, B)``.

    The task pseudo-inverse uses the same relative tolerance as the general path: an eigenvalue of
    ``J_n J_n^T`` below ``rank_tolerance^2 * lambda_max`` counts as zero.
    """
    n = points.shape[1] - 1
    jx, jy = jacobian(points, n)
    a, b, c = _dot(jx, jx), _dot(jx, jy), _dot(jy, jy)
    lam_max, lam_min = _eig2(a, b, c)
    full = lam_min > params.rank_tolerance**2 * lam_max
    det = np.where(full, a * c - b * b, 1.0)
    inv_lmax2 = np.where(lam_max > 0, 1.0 / np.where(lam_max > 0, lam_max, 1.0) ** 2, 0.0)
    # (J J^T)^+ : the inverse when full rank, A / lambda_max^2 when rank one.
    pa = np.where(full, c / det, a * inv_lmax2)
    pb = np.where(full, -b / det, b * inv_lmax2)
    pc = np.where(full, a / det, c * inv_lmax2)
    volumes = np.empty((points.shape[2], len(chain.control_joints)))
    for i, joint in enumerate(chain.control_joints):
        if joint == 0 or ranks[i] == 0:  # the base joint's origin never moves: V = 0
            volumes[:, i] = 0.0
            continue
        kx, ky = jacobian(points, joint)
        # P = J_i J_n^T, G = J_i J_i^T - P A^+ P^T (only the point's own columns are non-zero)
        p11, p12 = _dot(kx, jx[:joint]), _dot(kx, jy[:joint])
        p21, p22 = _dot(ky, jx[:joint]), _dot(ky, jy[:joint])
        g11 = _dot(kx, kx) - (p11 * (pa * p11 + pb * p12) + p12 * (pb * p11 + pc * p12))
        g12 = _dot(kx, ky) - (p11 * (pa * p21 + pb * p22) + p12 * (pb * p21 + pc * p22))
        g22 = _dot(ky, ky) - (p21 * (pa * p21 + pb * p22) + p22 * (pb * p21 + pc * p22))
        if ranks[i] == 2:
            volumes[:, i] = unit_ball_volume(2) * np.sqrt(np.maximum(g11 * g22 - g12 * g12, 0.0))
        else:
            volumes[:, i] = unit_ball_volume(1) * np.sqrt(np.maximum(_eig2(g11, g12, g22)[0], 0.0))
    return volumes, amsi_from_volumes(volumes, ranks, params)


def _dot(u: Array, v: Array) -> Array:
    """Column-wise dot product of two ``(j, B)`` arrays: a sum of ``j`` contiguous products."""
    out = u[0] * v[0]
    for row in range(1, len(u)):
        out += u[row] * v[row]
    return out


def _eig2(a: Array, b: Array, c: Array) -> tuple[Array, Array]:
    """Eigenvalues (max, min) of the symmetric 2x2 matrices ``[[a, b], [b, c]]``."""
    half_trace = 0.5 * (a + c)
    root = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return half_trace + root, half_trace - root


def link_segments(chain: PlanarChain, points: Array, trig: Array) -> tuple[Array, Array]:
    """End points ``a``, ``b`` ``(B, L, 3)`` [m] of the guarded capsules' axes (z = 0), from the
    joint origins and link-angle cosines/sines of :func:`joint_origins`."""
    B, L = points.shape[2], len(chain.link_joints)
    ends = np.zeros((2, B, L, 3))
    for slot, joint in enumerate(chain.link_joints):
        c, s = trig[0, joint], trig[1, joint]
        for e in range(2):
            lx, ly = chain.link_segments[slot, e]
            ends[e, :, slot, 0] = points[0, joint] + c * lx - s * ly
            ends[e, :, slot, 1] = points[1, joint] + s * lx + c * ly
    return ends[0], ends[1]
