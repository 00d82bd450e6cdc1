"""The obstacle potential ``U <= 0`` of AMSIP (eq. 18; the paper defers its shape to its ref. [8])."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
from numpy.typing import NDArray

from previewctl.types import Array
from previewctl.validation import Checked, Finite, Negative, Positive, interval


@dataclass(frozen=True)
class Potential(Checked):
    """The obstacle potential ``U`` (see the module docstring).

    Attributes:
        influence_distance: ``d_0`` [m]; links further than this from every obstacle feel nothing.
        gain: ``g`` in (0, 1]; the fraction of E removed at contact.
        collision_value: the (negative) S of a colliding configuration.
    """

    influence_distance: Positive = 0.15
    gain: Annotated[Finite, interval(0, 1, "(]")] = 1.0
    collision_value: Negative = -1.0

    def apply(self, amsi: Array, link_distances: Array) -> tuple[Array, Array, NDArray[np.bool_]]:
        """``(S, U, collision)`` from ``amsi`` ``(B,)`` and ``link_distances`` ``(B, L)`` [m]."""
        ramp = np.clip((self.influence_distance - link_distances) / self.influence_distance, 0.0, 1.0)
        factor = np.prod(1.0 - self.gain * ramp**2, axis=1)
        collision = np.asarray((link_distances <= 0.0).any(axis=1), dtype=bool)
        S = np.where(collision, self.collision_value, amsi * factor)
        return S, S - amsi, collision
