"""Closed-form description of a planar arm of revolute z joints, built once when the robot is loaded."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class PlanarChain:
    """Closed-form description of a planar arm of revolute z joints (for the vectorised path).

    Attributes:
        offsets: ``(n, 2)`` translation [m] of joint ``k`` in the frame of joint ``k-1`` (row 0: in the
            base frame).
        tip_offset: ``(2,)`` tip position [m] in the frame of the last joint.
        control_joints: index of the joint whose origin is each control point.
        link_joints: for each guarded capsule, the joint that carries it.
        link_segments: ``(L, 2, 2)`` capsule axis end points [m] in the carrying joint's frame.
        link_radii: ``(L,)`` capsule radii [m].
        link_index: for each guarded capsule, the index of its link in ``Robot.guarded_links``.
    """

    offsets: NDArray[np.float64]
    tip_offset: NDArray[np.float64]
    control_joints: tuple[int, ...]
    link_joints: tuple[int, ...]
    link_segments: NDArray[np.float64]
    link_radii: NDArray[np.float64]
    link_index: tuple[int, ...]


# ------------------------------------------------------------------------------ derived facts


