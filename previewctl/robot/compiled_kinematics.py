"""Forward kinematics and world joint Jacobians of many configurations in one compiled call (numba).

Pinocchio computes one configuration per call; through its Python bindings each call, and each read of its results,
costs more than the kinematics of a 7-joint arm (docs/decisions.md#compiled-kinematics). The planners evaluate
thousands of configurations per plan, so this module runs the same recursion over a whole batch in a numba kernel:

    oMi[j] = oMi[parent(j)] · placement(j) · M_j(q_j)

with ``M_j`` a rotation by ``θ`` about the joint's unit axis ``a`` (``R = c I + s [a]× + (1 - c) a aᵀ``, ``c = cos θ``,
``s = sin θ``; a continuous joint's ``(c, s)`` are its two configuration entries) or a translation ``q_j a``
(prismatic). The world joint Jacobian (Pinocchio's ``data.J`` after ``computeJointJacobians``) has, for the joint's
world axis ``w = R_j a`` and origin ``p_j``, the column ``(p_j × w, w)`` (revolute) or ``(w, 0)`` (prismatic); a frame
at ``p`` on the joint's subtree moves with ``(v + w × p, w)`` (``LOCAL_WORLD_ALIGNED``). Results equal Pinocchio's to
rounding (1e-15 relative; tested to 1e-12).

Covered: every joint with one degree of freedom that Pinocchio builds from a URDF (revolute about any axis, prismatic
along any axis, continuous), fixed joints (folded into the placements by Pinocchio), and trees as well as chains.
:meth:`CompiledKinematics.of` returns ``None`` for a model with any other joint (free-flyer, spherical, mimic, ...):
the callers then keep Pinocchio.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import pinocchio as pin

from previewctl.types import Array, IntArray

REVOLUTE = 0
"""A revolute joint: ``M_j`` a rotation by ``q_j`` [rad] about its axis."""
PRISMATIC = 1
"""A prismatic joint: ``M_j`` a translation by ``q_j`` [m] along its axis."""
CONTINUOUS = 2
"""A continuous joint: ``M_j`` a rotation whose ``(cos, sin)`` are its two configuration entries."""

_KINDS = {
    **{f"JointModelR{x}": REVOLUTE for x in "XYZ"},
    **{f"JointModelP{x}": PRISMATIC for x in "XYZ"},
    **{f"JointModelRUB{x}": CONTINUOUS for x in "XYZ"},
    "JointModelRevoluteUnaligned": REVOLUTE,
    "JointModelPrismaticUnaligned": PRISMATIC,
    "JointModelRevoluteUnboundedUnaligned": CONTINUOUS,
}


def _axis(model: pin.Model, joint: pin.JointModel, kind: int) -> Array:
    """The unit axis of a 1-dof joint in its own frame: its motion subspace ``S`` (linear, angular), which Pinocchio
    computes for every joint kind (the bindings expose no axis for some)."""
    data = joint.createData()
    joint.calc(data, pin.neutral(model))
    motion = np.array(data.S).ravel()
    return motion[:3] if kind == PRISMATIC else motion[3:]


@dataclass(frozen=True, eq=False)
class CompiledKinematics:
    """The joints of a Pinocchio model as arrays, and the compiled kernels over them. Build it with :meth:`of`.

    Attributes:
        parent: ``(N,)`` parent joint of each joint (joint 0 is the universe; ``N = model.njoints``).
        kind: ``(N,)`` :data:`REVOLUTE`, :data:`PRISMATIC` or :data:`CONTINUOUS` (unused for joint 0).
        axis: ``(N, 3)`` unit axis of each joint in its own frame.
        rotation, translation: ``(N, 3, 3)`` and ``(N, 3)`` [m]: each joint's placement in its parent's frame.
        idx_q, idx_v: ``(N,)`` first configuration and velocity entry of each joint.
        nq, nv: sizes of ``q`` and of the velocity.
    """

    parent: IntArray
    kind: IntArray
    axis: Array
    rotation: Array
    translation: Array
    idx_q: IntArray
    idx_v: IntArray
    nq: int
    nv: int

    @classmethod
    def of(cls, model: pin.Model) -> CompiledKinematics | None:
        """The kernel's view of ``model``, or ``None`` when some joint is not covered (module docstring)."""
        count = model.njoints
        kind = np.zeros(count, dtype=np.int64)
        axis = np.zeros((count, 3))
        for j in range(1, count):
            joint = model.joints[j]
            if joint.shortname() not in _KINDS or joint.nv != 1:
                return None
            kind[j] = _KINDS[joint.shortname()]
            axis[j] = _axis(model, joint, int(kind[j]))
        placements = list(model.jointPlacements)
        return cls(
            parent=np.array(model.parents, dtype=np.int64),
            kind=kind,
            axis=axis,
            rotation=np.array([p.rotation for p in placements]).reshape(count, 3, 3),
            translation=np.array([p.translation for p in placements]).reshape(count, 3),
            idx_q=np.array([model.joints[j].idx_q if j else 0 for j in range(count)], dtype=np.int64),
            idx_v=np.array([model.joints[j].idx_v if j else 0 for j in range(count)], dtype=np.int64),
            nq=int(model.nq),
            nv=int(model.nv),
        )

    def frames(self, Q: Array, joints: IntArray, offsets: Array, with_jacobian: int | None = None
               ) -> tuple[Array, Array]:
        """World placements ``(B, K, 4, 4)`` and ``LOCAL_WORLD_ALIGNED`` Jacobians ``(B, K', 6, nv)`` (linear rows
        first; zero in the columns of joints that do not carry the frame) of ``K`` frames at configurations
        ``(B, nq)``: frame ``k`` at ``offsets[k]`` ``(4, 4)`` in joint ``joints[k]``'s frame. What
        ``pin.computeFrameJacobian`` and ``data.oMf`` give, for every frame and configuration at once; only the first
        ``K' = with_jacobian`` frames (default: all) get a Jacobian."""
        Q = np.ascontiguousarray(Q, dtype=float)
        K = len(joints)
        count = K if with_jacobian is None else with_jacobian
        placements = np.empty((Q.shape[0], K, 4, 4))
        jacobians = np.empty((Q.shape[0], count, 6, self.nv))
        _frames(Q, self.parent, self.kind, self.axis, self.rotation, self.translation, self.idx_q, self.idx_v,
                np.asarray(joints, dtype=np.int64), np.ascontiguousarray(offsets, dtype=float).reshape(K, 4, 4),
                placements, jacobians)
        return placements, jacobians


@numba.njit(cache=True, nogil=True)
def _mul(A: Array, B: Array, out: Array) -> None:  # pragma: no cover - compiled
    """``out = A B`` for ``3 x 3`` matrices (written out: numba's ``@`` calls BLAS, slow at this size)."""
    for i in range(3):
        for k in range(3):
            out[i, k] = A[i, 0] * B[0, k] + A[i, 1] * B[1, k] + A[i, 2] * B[2, k]


@numba.njit(cache=True, nogil=True)
def _apply(A: Array, x: Array, out: Array) -> None:  # pragma: no cover - compiled
    """``out = A x`` for a ``3 x 3`` matrix and a 3-vector."""
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]


@numba.njit(cache=True, nogil=True)
def _forward(q: Array, parent: IntArray, kind: IntArray, axis: Array, rotation: Array, translation: Array,
             idx_q: IntArray, R: Array, p: Array, base: Array, M: Array, x: Array) -> None:  # pragma: no cover
    """World rotations ``R`` ``(N, 3, 3)`` and origins ``p`` ``(N, 3)`` of every joint at one configuration
    (``base``, ``M``: ``3 x 3`` and ``x``: 3-vector workspaces)."""
    R[0] = 0.0
    for i in range(3):
        R[0, i, i] = 1.0
    p[0] = 0.0
    for j in range(1, len(parent)):
        Rp = R[parent[j]]
        _mul(Rp, rotation[j], base)
        _apply(Rp, translation[j], x)
        for i in range(3):
            p[j, i] = p[parent[j], i] + x[i]
        a = axis[j]
        if kind[j] == PRISMATIC:
            _apply(base, a, x)
            for i in range(3):
                p[j, i] += x[i] * q[idx_q[j]]
            R[j] = base
            continue
        if kind[j] == CONTINUOUS:
            c, s = q[idx_q[j]], q[idx_q[j] + 1]
        else:
            c, s = np.cos(q[idx_q[j]]), np.sin(q[idx_q[j]])
        t = 1.0 - c
        M[0, 0] = c + t * a[0] * a[0]
        M[1, 1] = c + t * a[1] * a[1]
        M[2, 2] = c + t * a[2] * a[2]
        M[0, 1] = t * a[0] * a[1] - s * a[2]
        M[1, 0] = t * a[0] * a[1] + s * a[2]
        M[0, 2] = t * a[0] * a[2] + s * a[1]
        M[2, 0] = t * a[0] * a[2] - s * a[1]
        M[1, 2] = t * a[1] * a[2] - s * a[0]
        M[2, 1] = t * a[1] * a[2] + s * a[0]
        _mul(base, M, R[j])


@numba.njit(cache=True, nogil=True)
def _column(kind: int, R: Array, p: Array, a: Array, at: Array, out: Array) -> None:  # pragma: no cover - compiled
    """The 6-vector ``out`` (linear first) by which a point at ``at`` moves per unit speed of a joint at ``(R, p)``."""
    w0 = R[0, 0] * a[0] + R[0, 1] * a[1] + R[0, 2] * a[2]
    w1 = R[1, 0] * a[0] + R[1, 1] * a[1] + R[1, 2] * a[2]
    w2 = R[2, 0] * a[0] + R[2, 1] * a[1] + R[2, 2] * a[2]
    if kind == PRISMATIC:
        out[0], out[1], out[2], out[3], out[4], out[5] = w0, w1, w2, 0.0, 0.0, 0.0
        return
    r0, r1, r2 = at[0] - p[0], at[1] - p[1], at[2] - p[2]
    out[0] = w1 * r2 - w2 * r1
    out[1] = w2 * r0 - w0 * r2
    out[2] = w0 * r1 - w1 * r0
    out[3], out[4], out[5] = w0, w1, w2


@numba.njit(cache=True, nogil=True)
def _frames(Q: Array, parent: IntArray, kind: IntArray, axis: Array, rotation: Array, translation: Array,
            idx_q: IntArray, idx_v: IntArray, joints: IntArray, offsets: Array, placements: Array,
            jacobians: Array) -> None:  # pragma: no cover - compiled
    count = len(parent)
    R, p = np.empty((count, 3, 3)), np.empty((count, 3))
    base, M, x = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    Rf, pf, column = np.empty((3, 3)), np.empty(3), np.empty(6)
    offset_R = np.ascontiguousarray(offsets[:, :3, :3])
    offset_p = np.ascontiguousarray(offsets[:, :3, 3])
    for b in range(Q.shape[0]):
        _forward(Q[b], parent, kind, axis, rotation, translation, idx_q, R, p, base, M, x)
        for f in range(len(joints)):
            joint = joints[f]
            _mul(R[joint], offset_R[f], Rf)
            _apply(R[joint], offset_p[f], pf)
            H = placements[b, f]
            for i in range(3):
                pf[i] += p[joint, i]
                for k in range(3):
                    H[i, k] = Rf[i, k]
                H[i, 3] = pf[i]
                H[3, i] = 0.0
            H[3, 3] = 1.0
            if f >= jacobians.shape[1]:
                continue
            jacobians[b, f] = 0.0
            j = joint
            while j > 0:  # the joints that carry the frame
                _column(kind[j], R[j], p[j], axis[j], pf, column)
                for i in range(6):
                    jacobians[b, f, i, idx_v[j]] = column[i]
                j = parent[j]
