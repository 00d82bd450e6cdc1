"""How far the hand can be from the arm's base: a conservative shell computed from the model.

For a serial chain of revolute joints the distance between consecutive joint origins is fixed, so
with ``l_k`` those distances (joint 2 onward, then the tip's offset from the last joint) and ``c``
the first joint's origin (fixed in the world), the hand ``p`` obeys

    max(0, 2 max_k l_k − Σ l_k)  <=  |p − c|  <=  Σ l_k.

A joint that translates (prismatic, planar, free) adds its largest travel to the sum (infinite
when unbounded) and removes the inner bound. For a planar
chain whose joints turn fully (planar4), both bounds are reached: the reachable set is that annulus.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from previewctl.robot.model import Robot
from previewctl.types import Array

_ROTATIONAL = ("JointModelR", "JointModelSpherical")
"""Pinocchio joint-model names (prefixes) that only rotate: they keep the distances between joint origins."""


@dataclass(frozen=True)
class Reach:
    """The shell the hand stays in.

    Attributes:
        centre: ``(3,)`` the first joint's origin [m].
        inner: smallest possible distance of the hand from ``centre`` [m].
        outer: largest possible distance [m].
    """

    centre: Array
    inner: float
    outer: float


def reach_of(robot: Robot) -> Reach:
    """The hand's reach shell of ``robot`` (module docstring)."""
    model = robot.model
    lengths = [float(np.linalg.norm(model.jointPlacements[j].translation)) for j in range(2, model.njoints)]
    tip = model.frames[robot.tip_frame_id]
    lengths.append(float(np.linalg.norm(tip.placement.translation)))
    travel = 0.0
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if not joint.shortname().startswith(_ROTATIONAL):
            span = slice(joint.idx_q, joint.idx_q + joint.nq)
            limits = np.abs(np.concatenate([model.lowerPositionLimit[span], model.upperPositionLimit[span]]))
            travel += float(limits.max())  # inf for an unbounded translation: no outer bound
    total = sum(lengths) + travel
    inner = 0.0 if travel > 0 else max(0.0, 2.0 * max(lengths) - sum(lengths))
    return Reach(np.array(model.jointPlacements[1].translation, dtype=float), inner, total)
