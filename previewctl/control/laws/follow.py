"""``oracle`` and ``horizon``: follow a planned motion, ``v = q̇*(t + t_l) + K_v (q*(t + t_l) ⊖ q)``.

``oracle`` is NON-CAUSAL, a reference and not a controller a robot could run: it reads the whole future (the path
and every obstacle's motion) and plans once, at its first cycle, over the rest of the path; any run can then be set
against what was possible in the same scene. When no motion reaches the end, it follows the best one to its dead
end and then holds its last configuration. ``horizon`` is the same made causal, the paper's "future reachability
evaluation" done by a planner instead of by imaginary arms: every ``replan_period`` it plans over
``[t, t + plan_window]`` only (:class:`~previewctl.control.planner.WindowPlanner`).
"""

from __future__ import annotations

import numpy as np

from previewctl.control.base import ControlState, NullInput
from previewctl.control.nullspace import gain_vector
from previewctl.control.params import ControllerParams
from previewctl.control.planner import WindowPlanner
from previewctl.robot.model import Robot


class _Follow:
    """Eq. 19 pulled toward the planner's motion at the lookahead (module docstring).

    Args:
        robot: the arm.
        params: ``gain`` (``K_v`` [1/s]).
        planner: the planner whose motion is followed.
    """

    name = "follow"

    def __init__(self, robot: Robot, params: ControllerParams, planner: WindowPlanner) -> None:
        self.planner = planner
        self._gain = gain_vector(params.gain, robot.nv, "gain")

    def null_input(self, state: ControlState) -> NullInput:
        """Plan when due, then pull toward the plan; the plan's point is the logged imaginary arm."""
        if self.planner.due(state.t):
            self.planner.plan(state)
        v, q_ref, S_ref = self.planner.pull(state.q, state.t, self._gain)
        return NullInput(v, q_ref[None, :], np.array([S_ref]))


class Oracle(_Follow):
    """``oracle`` (non-causal): follows one plan over the whole rest of the path."""

    name = "oracle"


class Horizon(_Follow):
    """``horizon``: follows a plan over the preview window, replanned every ``replan_period``."""

    name = "horizon"
