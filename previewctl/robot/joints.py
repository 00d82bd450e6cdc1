"""Joint facts: what each velocity coordinate of a model is, computed once when the robot is loaded.

Every rule about joints reads these facts instead of walking ``model.joints`` again: which coordinates
are angles that turn a full circle (compared and searched modulo ``2 pi``), which have finite position
limits, and where each coordinate sits in ``q``. As in pink's ``ConfigurationLimit``, the facts are
derived from the Pinocchio model once and kept as read-only arrays.

A URDF ``continuous`` joint becomes a (cos, sin) pair in Pinocchio (``nq = 2``, ``nv = 1``): its
coordinate is *continuous* here (any joint with ``nq != nv`` is), has no position limits and turns a
full circle. A 1-dof revolute joint turns a full circle when its limits are infinite or span at least
``2 pi`` (the paper's planar arm: 0-360 degrees per joint).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

FULL_TURN = 2.0 * np.pi
"""One turn [rad]."""
FULL_TURN_SLACK = 1e-9
"""Limits spanning ``FULL_TURN - FULL_TURN_SLACK`` [rad] or more turn a full circle (rounding in URDF values)."""


_Item = TypeVar("_Item", bound=np.generic)


def _frozen(array: NDArray[_Item]) -> NDArray[_Item]:
    """``array``, made read-only."""
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class JointFacts:
    """Per-coordinate facts of a Pinocchio model. Build them with :meth:`of`.

    Arrays indexed by velocity coordinate have shape ``(nv,)``; those indexed by configuration entry
    ``(nq,)``. All arrays are read-only.

    Attributes:
        revolute: the coordinate is a rotation angle [rad] (a revolute joint, continuous ones included).
        continuous: its joint stores the coordinate other than as itself (``nq != nv``, e.g. a URDF
            continuous joint's (cos, sin) pair); ``pin.difference`` already returns it as an angle.
        full_turn: an angle that turns a full circle: continuous, or revolute with infinite limits or
            limits spanning at least ``2 pi``. Compare such angles modulo ``2 pi``.
        lower, upper: position limits [rad or m]; ``-inf`` / ``inf`` where the model gives none and for
            continuous coordinates.
        bounded: both limits finite.
        velocity: speed limits [rad/s or m/s] as the model gives them (``<= 0`` or ``inf``: none).
        q_index: the configuration entry of each coordinate whose joint has ``nq == nv``
            (``q[q_index[i]]`` is coordinate ``i``); ``-1`` for continuous coordinates.
        q_joint: ``(nq,)`` the Pinocchio joint id of each configuration entry.
        vector_space: every joint is a 1-dof revolute or prismatic one: ``q`` and the coordinates
            coincide and ``pin.integrate`` is plain addition.
        unit_pairs: ``(P, 2)`` the configuration entries of each continuous joint's (cos, sin) pair.
    """

    revolute: NDArray[np.bool_]
    continuous: NDArray[np.bool_]
    full_turn: NDArray[np.bool_]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    bounded: NDArray[np.bool_]
    velocity: NDArray[np.float64]
    q_index: NDArray[np.int_]
    q_joint: NDArray[np.int_]
    vector_space: bool
    unit_pairs: NDArray[np.int_]

    @classmethod
    def of(cls, model: pin.Model) -> JointFacts:
        """The facts of ``model`` (one walk over its joints)."""
        nv = model.nv
        revolute, continuous = np.zeros(nv, dtype=bool), np.zeros(nv, dtype=bool)
        lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
        q_index, q_joint = np.full(nv, -1, dtype=int), np.zeros(model.nq, dtype=int)
        q_lower, q_upper = np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
        vector_space, pairs = True, []
        for j in range(1, model.njoints):
            joint = model.joints[j]
            kind = joint.shortname()
            v, q = slice(joint.idx_v, joint.idx_v + joint.nv), slice(joint.idx_q, joint.idx_q + joint.nq)
            q_joint[q] = j
            revolute[v] = kind.startswith("JointModelR")
            vector_space &= joint.nq == joint.nv == 1 and kind.startswith(("JointModelR", "JointModelP"))
            if joint.nq != joint.nv:
                continuous[v] = True
                if joint.nq == 2:
                    pairs.append((joint.idx_q, joint.idx_q + 1))
                continue
            q_index[v] = np.arange(joint.idx_q, joint.idx_q + joint.nq)
            lower[v], upper[v] = q_lower[q], q_upper[q]
        bounded = np.isfinite(lower) & np.isfinite(upper)
        span_ok = ~bounded | (upper - lower >= FULL_TURN - FULL_TURN_SLACK)
        full_turn = continuous | (revolute & span_ok)
        return cls(
            revolute=_frozen(revolute),
            continuous=_frozen(continuous),
            full_turn=_frozen(full_turn),
            lower=_frozen(lower),
            upper=_frozen(upper),
            bounded=_frozen(bounded),
            velocity=_frozen(np.array(model.velocityLimit, dtype=float)),
            q_index=_frozen(q_index),
            q_joint=_frozen(q_joint),
            vector_space=bool(vector_space),
            unit_pairs=_frozen(np.array(pairs, dtype=int).reshape(-1, 2)),
        )
