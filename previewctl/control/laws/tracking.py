"""``none`` and ``qp``: eq. 19 with no null-space input, under the pseudo-inverse and under the QP execution."""

from __future__ import annotations

import numpy as np

from previewctl.control.base import ControlState, NullInput


class Tracking:
    """``none``: minimum-norm hand tracking, ``v = 0``, executed by the pseudo-inverse (the paper's eq. 19).

    Args:
        nv: the arm's velocity dimension.
    """

    name = "none"

    def __init__(self, nv: int) -> None:
        self._zero = np.zeros(nv)

    def null_input(self, state: ControlState) -> NullInput:
        """``v = 0``."""
        return NullInput(self._zero.copy())


class QPBaseline(Tracking):
    """``qp``: ``v = 0`` executed by the constrained QP: the velocity-damper method of NEO, the peer baseline."""

    name = "qp"
