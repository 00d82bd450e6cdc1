"""Choosing the redundancy map of a robot: closed form for planar arms, Newton otherwise."""

from __future__ import annotations

from typing import Any

from previewctl.robot.model import Robot
from previewctl.search.newton import NewtonRedundancy
from previewctl.search.planar import PlanarRedundancy


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

