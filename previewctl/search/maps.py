"""Choosing the redundancy map of a robot (closed form for planar arms, Newton otherwise) and reading joint angles."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.planar.redundancy import PlanarRedundancy
from previewctl.robot.model import Robot
from previewctl.search.newton import NewtonRedundancy
from previewctl.types import Array


def redundancy_map(robot: Robot, **options: Any) -> PlanarRedundancy | NewtonRedundancy:
    """The redundancy map of ``robot``: the closed form for a planar chain, else the Newton map.

    Args:
        robot: the arm.
        **options: keyword options of :class:`PlanarRedundancy` or :class:`NewtonRedundancy`; pass
            ``general=True`` to force the Newton map on a planar arm.
    """
    general = bool(options.pop("general", False))
    if robot.planar is not None and robot.nq >= 2 and not general:
        return PlanarRedundancy(robot, **options)
    return NewtonRedundancy(robot, **options)


def joint_angles(robot: Robot, Q: Array) -> Array:
    """Joint coordinates ``(B, nv)`` [rad] of configurations ``(B, nq)`` (continuous joints as angles)."""
    if robot.nq == robot.nv:
        return np.array(Q, dtype=float)
    neutral = robot.neutral()
    return np.stack([pin.difference(robot.model, neutral, q) for q in Q])
