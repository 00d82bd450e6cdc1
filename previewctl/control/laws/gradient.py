"""``gradient``: the local null-space ascent of the AMSIP, ``v = K_g ∇_q S``."""

from __future__ import annotations

from previewctl.control.base import ControlState, NullInput
from previewctl.control.nullspace import AmsipGradient


class Gradient:
    """``gradient``: ``v = K_g ∇_q S`` (:class:`~previewctl.control.nullspace.AmsipGradient`).

    Args:
        ascent: the AMSIP gradient term.
    """

    name = "gradient"

    def __init__(self, ascent: AmsipGradient) -> None:
        self.ascent = ascent

    def null_input(self, state: ControlState) -> NullInput:
        """``v = K_g ∇_q S`` at the state's configuration and time."""
        return NullInput(self.ascent(state.q, state.t))
