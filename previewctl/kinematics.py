"""Kinematics computed once per configuration batch: hand and control-point positions and Jacobians."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numba
import numpy as np
import pinocchio as pin

from previewctl.errors import ConfigurationError
from previewctl.robot.compiled_kinematics import CompiledKinematics
from previewctl.robot.model import Robot
from previewctl.types import Array, IntArray
from previewctl.validation import show


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
        joint_placements: ``(B, J, 4, 4)`` world placements of the reader's extra ``joints`` (the self pairs' bounds
            read them; ``J = 0`` by default).
    """

    q: Array
    tip_position: Array
    tip_rotation: Array
    J_task: Array
    point_positions: Array
    J_points: Array
    joint_placements: Array


# entries of the row-major 3 x 3 matrix -[p]x (so that -[p]x w = w x p), from p[source] * sign
_SKEW_SLOTS = np.array([1, 2, 3, 5, 6, 7])
_SKEW_SOURCES = np.array([2, 1, 2, 0, 1, 0])
_SKEW_SIGNS = np.array([1.0, -1.0, -1.0, 1.0, 1.0, -1.0])


def support_mask(model: pin.Model, joints: Sequence[int] | IntArray) -> Array:
    """``(len(joints), nv)``: 1 in the velocity columns that move each joint (its supporting joints), else 0."""
    mask = np.zeros((len(joints), model.nv))
    for k, joint_id in enumerate(joints):
        for j in model.supports[int(joint_id)]:
            if j > 0:
                joint = model.joints[j]
                mask[k, joint.idx_v : joint.idx_v + joint.nv] = 1.0
    return mask


class FrameKinematics:
    """Placements and world-aligned Jacobians of chosen frames, for batches of configurations.

    Per configuration, one Pinocchio call (``computeJointJacobians``) fills the joint placements and
    the world-frame joint Jacobian ``data.J``; both are copied out through references held once (each
    lookup through the bindings costs about a microsecond, more than the kinematics itself). The frame
    Jacobians are then assembled for the whole batch: a frame at ``p`` [m] moves with the columns of the
    joints that support it as ``(v_j + w_j x p, w_j)``, where ``(v_j, w_j)`` is column ``j`` of
    ``data.J`` -- what ``pin.getFrameJacobian(..., LOCAL_WORLD_ALIGNED)`` returns, for all frames and
    configurations at once.

    Args:
        model: the Pinocchio model.
        frame_ids: the frames to follow.
        data: the ``Data`` to fill (one is created if ``None``).
        joints: joints whose placements are wanted as well (:attr:`joint_placements`), read on the same pass
            (those that also carry a followed frame are read once).
        compiled: compute the placements and Jacobians of a whole batch in one compiled call
            (:mod:`~previewctl.robot.compiled_kinematics`, equal to Pinocchio's to rounding) when the model allows it
            (an ``after_each`` then gets ``data`` from ``pin.forwardKinematics``); for the searches' large batches.
    """

    def __init__(self, model: pin.Model, frame_ids: tuple[int, ...], data: pin.Data | None = None,
                 joints: Sequence[int] = (), compiled: bool = False) -> None:
        self.model = model
        self._compiled = CompiledKinematics.of(model) if compiled else None
        self.data = model.createData() if data is None else data
        parents = [int(model.frames[f].parentJoint) for f in frame_ids]
        followed = sorted(set(parents) | {int(j) for j in joints})
        self._slot = np.array([followed.index(j) for j in parents], dtype=int)
        self._joint_slot = np.array([followed.index(int(j)) for j in joints], dtype=int)
        offsets = [model.frames[f].placement.homogeneous for f in frame_ids]
        # the compiled path: the frames, then the extra joints as frames at their joint's origin
        self._frame_joints = np.array([*parents, *joints], dtype=int)
        self._frame_offsets = np.array([*offsets, *[np.eye(4)] * len(joints)]).reshape(-1, 4, 4)
        self._moved = np.array([k for k, h in enumerate(offsets) if not np.allclose(h, np.eye(4))], dtype=int)
        self._offset = np.array(offsets).reshape(-1, 4, 4)[self._moved]
        support = support_mask(model, parents)
        self._support = np.repeat(support[:, None, :], 6, axis=1)  # full shape (K, 6, nv): a fast broadcast
        self._partial_support = not self._support.all()  # some joint columns do not move some frame
        self._joint_J = self.data.J  # a view on the C++ buffer, refreshed by every computeJointJacobians
        placements = list(self.data.oMi)  # element references, read without a lookup each
        # the universe (joint 0, where a fixed base's geometry hangs) is the identity: not read, put in once a batch
        self._universe = bool(followed) and followed[0] == 0
        self._placements = [placements[j] for j in followed[self._universe:]]
        self.joint_placements: Array = np.zeros((0, len(self._joint_slot), 4, 4))
        """``(B, J, 4, 4)`` the placements of the extra ``joints`` at the last batch."""

    def __call__(self, Q: Array, after_each: Callable[[pin.Data], None] | None = None) -> tuple[Array, Array]:
        """Placements ``(B, K, 4, 4)`` and Jacobians ``(B, K, 6, nv)`` (linear rows first) of the frames; the extra
        joints' placements go to :attr:`joint_placements`.

        Args:
            Q: ``(B, nq)`` validated configurations.
            after_each: called as ``after_each(data)`` once the joint placements of each configuration
                are in ``data``, in batch order (the scene uses it to compute distances on the same pass).
        """
        model, K = self.model, len(self._slot)
        if self._compiled is not None:
            if after_each is not None:  # the placements in data for it; the results from the compiled call
                for q in Q:
                    pin.forwardKinematics(model, self.data, q)
                    after_each(self.data)
            placements, jacobians = self._compiled.frames(Q, self._frame_joints, self._frame_offsets, K)
            self.joint_placements = placements[:, K:]
            return placements[:, :K], jacobians
        placements, J = self._pinocchio(Q, after_each)
        frames, jacobians, self.joint_placements = _assemble(placements, J, int(self._universe), self._slot,
                                                             self._joint_slot, self._moved, self._offset,
                                                             self._support, self._partial_support)
        return frames, jacobians

    def _pinocchio(self, Q: Array, after_each: Callable[[pin.Data], None] | None) -> tuple[Array, Array]:
        """Placements ``(B, F, 4, 4)`` of the followed joints (the universe left out) and world joint Jacobians
        ``(B, 6, nv)``, one Pinocchio call per configuration."""
        model, data, joint_J, placements = self.model, self.data, self._joint_J, self._placements
        B = Q.shape[0]
        joint_jacobians, homogeneous = [], []  # appended, stacked once: cheaper than B x S row writes
        for q in Q:
            pin.computeJointJacobians(model, data, q)
            joint_jacobians.append(joint_J.copy())
            for placement in placements:
                homogeneous.append(placement.homogeneous)
            if after_each is not None:
                after_each(data)
        frames = np.array(homogeneous).reshape(B, len(placements), 4, 4)
        return frames, np.array(joint_jacobians).reshape(B, 6, model.nv)


@numba.njit(cache=True, nogil=True)
def _assemble(placements: Array, J: Array, universe: int, slot: IntArray, joint_slot: IntArray, moved: IntArray,
              offset: Array, support: Array, partial_support: bool) -> tuple[Array, Array, Array]:  # pragma: no cover
    """The frames' placements ``(B, K, 4, 4)`` and Jacobians ``(B, K, 6, nv)`` and the extra joints' placements
    ``(B, J, 4, 4)``, from the followed joints' ``placements`` ``(B, F, 4, 4)`` and world joint Jacobians ``J``
    ``(B, 6, nv)``; with ``universe`` = 1 the universe is followed too (the identity, put first). One compiled call:
    the numpy expressions it replaced cost about 20 µs a configuration warm and 90 µs with cold caches; the same
    operations, so the same bits.

    A frame at ``p`` moves with joint column ``(v, w)`` as ``v + w x p = v + C(p) w``, ``C(p) = -[p]x``: one matrix
    product for all the frames of a configuration, then the support mask (columns of joints that do not move it).
    """
    B, K, nv = placements.shape[0], slot.size, J.shape[2]
    followed = np.empty((B, placements.shape[1] + universe, 4, 4))
    if universe:
        followed[:, 0] = np.eye(4)
    followed[:, universe:] = placements
    frames = np.empty((B, K, 4, 4))
    joints = np.empty((B, joint_slot.size, 4, 4))
    jacobians = np.empty((B, K, 6, nv))
    cross = np.zeros((3 * K, 3))
    for b in range(B):
        for k in range(joint_slot.size):
            joints[b, k] = followed[b, joint_slot[k]]
        for k in range(K):
            frames[b, k] = followed[b, slot[k]]
        for i in range(moved.size):
            frames[b, moved[i]] = frames[b, moved[i]] @ offset[i]
        for k in range(K):
            for e in range(_SKEW_SLOTS.size):
                entry = _SKEW_SLOTS[e]
                cross[3 * k + entry // 3, entry % 3] = frames[b, k, _SKEW_SOURCES[e], 3] * _SKEW_SIGNS[e]
        linear = cross @ J[b, 3:]
        for k in range(K):
            jacobians[b, k, :3] = linear[3 * k:3 * k + 3] + J[b, :3]
            jacobians[b, k, 3:] = J[b, 3:]
        if partial_support:
            jacobians[b] *= support
    return frames, jacobians, joints


def kinematics(
    robot: Robot,
    Q: Array,
    after_each: Callable[[pin.Data], None] | None = None,
    reader: FrameKinematics | None = None,
) -> Kinematics:
    """Hand and control-point kinematics, one Pinocchio pass per configuration.

    Args:
        robot: the arm.
        Q: ``(B, nq)`` validated configurations.
        after_each: called as ``after_each(data)`` once each configuration's joint placements are in ``data``, in
            batch order (as by :class:`FrameKinematics`).
        reader: the :func:`kinematics_reader` of ``robot`` to reuse (building one costs far more than a
            configuration; keep it across calls).
    """
    reader = kinematics_reader(robot) if reader is None else reader
    frames, jacobians = reader(Q, after_each)
    tip = frames[:, -1]
    return Kinematics(
        Q,
        tip[:, :3, 3],
        tip[:, :3, :3],
        jacobians[:, -1, robot.task_rows],
        frames[:, :-1, :3, 3],
        jacobians[:, :-1, robot.point_rows],
        reader.joint_placements,
    )


def kinematics_reader(robot: Robot, data: pin.Data | None = None, joints: Sequence[int] = (),
                      compiled: bool = False) -> FrameKinematics:
    """The :class:`FrameKinematics` of :func:`kinematics`: the control points, then the tip (and the placements of
    ``joints``, :attr:`Kinematics.joint_placements`); ``compiled`` as there."""
    return FrameKinematics(robot.model, (*robot.control_frame_ids, robot.tip_frame_id), data, joints, compiled)


def hand_placement(robot: Robot, q: Array, data: pin.Data) -> tuple[Array, Array]:
    """Hand position ``(3,)`` [m] and rotation ``(3, 3)`` at one validated configuration ``q`` ``(nq,)``, computed
    in ``data`` (forward kinematics only: no Jacobian)."""
    pin.forwardKinematics(robot.model, data, q)
    placement = pin.updateFramePlacement(robot.model, data, robot.tip_frame_id)
    return placement.translation.copy(), placement.rotation.copy()


def integrate(robot: Robot, q: Array, qdot: Array, dt: float) -> Array:
    """The configuration reached from ``q`` ``(nq,)`` moving at ``qdot`` ``(nv,)`` [rad/s] for ``dt`` [s].

    ``q ⊕ q̇ dt`` (``pin.integrate``): ``q + q̇ dt`` for ordinary joints, a rotation of the (cos, sin)
    pair for a continuous joint, where plain addition would be wrong.

    Raises:
        ConfigurationError: ``q`` or ``qdot`` of the wrong length or not finite.
    """
    batch, single = robot.check_configurations(q)
    velocity = np.asarray(qdot, dtype=float)
    if not single or velocity.shape != (robot.nv,) or not np.isfinite(velocity).all():
        raise ConfigurationError(
            f"integrate needs one configuration ({robot.nq},) and a finite velocity ({robot.nv},); "
            f"got q of shape {np.shape(q)} and qdot = {show(velocity)}"
        )
    return np.asarray(pin.integrate(robot.model, batch[0], velocity * dt), dtype=float)
