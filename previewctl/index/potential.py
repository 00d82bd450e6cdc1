"""The potential ``U <= 0`` of AMSIP (eq. 18; the paper defers its shape to its ref. [8]): obstacles, self-contact."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
from numpy.typing import NDArray

from previewctl.types import Array
from previewctl.validation import Checked, Finite, Negative, Positive, interval


@dataclass(frozen=True)
class Potential(Checked):
    """The potential ``U`` from obstacles and self-contact (see :mod:`previewctl.index.evaluator`).

    Attributes:
        influence_distance: ``d_0`` [m]; links further than this from every obstacle feel nothing.
        gain: ``g`` in (0, 1]; the fraction of E removed at contact (with an obstacle or with itself).
        collision_value: the (negative) S of a colliding configuration.
        self_influence_distance: ``d_s`` [m]; an arm whose self pairs are all further apart than this feels
            nothing of itself. Shorter than ``d_0``: links pass close to their neighbours in ordinary poses.
    """

    influence_distance: Positive = 0.15
    gain: Annotated[Finite, interval(0, 1, "(]")] = 1.0
    collision_value: Negative = -1.0
    self_influence_distance: Positive = 0.05

    def apply(
        self, amsi: Array, link_distances: Array, self_distance: Array | None = None
    ) -> tuple[Array, Array, NDArray[np.bool_]]:
        """``(S, U, collision)`` from ``amsi`` ``(B,)``, ``link_distances`` ``(B, L)`` [m] and the smallest self-pair
        distance ``self_distance`` ``(B,)`` [m] (``None``: an arm without self pairs).

        ``collision`` flags contact with an obstacle; self-contact (``self_distance <= 0``) also gives
        ``S = collision_value``.
        """
        ramp = np.clip((self.influence_distance - link_distances) / self.influence_distance, 0.0, 1.0)
        factor = np.prod(1.0 - self.gain * ramp**2, axis=1)
        collision = np.asarray((link_distances <= 0.0).any(axis=1), dtype=bool)
        hit = collision
        if self_distance is not None:
            d_s = self.self_influence_distance
            factor = factor * (1.0 - self.gain * np.clip((d_s - self_distance) / d_s, 0.0, 1.0) ** 2)
            hit = collision | (self_distance <= 0.0)
        S = np.where(hit, self.collision_value, amsi * factor)
        return S, S - amsi, collision
