"""``reach`` (the paper's Fig. 3): heads for the imaginary arms' best peak that a checked motion reaches.

At each camera frame every imaginary arm runs one generation; its positive peaks are the nodes of its preview
time. The arm then moves along a motion checked to keep the hand on the path, collision-free and within the speed
limits, toward the best peak it reaches:

* planned (coherent mode where a window planner covers the arm: spatial arms, planar arms of up to 4 joints): the
  planner's motion toward the best reached peak (:class:`~previewctl.control.planner.PeakPlanner`), replanned
  every ``replan_period``; the plans made before the searches have run ``settle_frames`` generations take no goal;
* straight sweeps otherwise (the paper-literal mode, and planar arms of more than 4 joints): the Viterbi route of
  :class:`~previewctl.control.sweeps.SweepRoutes`, re-chosen every frame; the arm follows the first sample of the
  move to the route's first node, ``v = (q_lead ⊖ q) / dtau``. With no feasible route, eq. 21 on the imaginary arms'
  best candidates. In coherent mode the input is ramped in over ``settle_frames``.

Unlike eq. 21, whose targets may lie on mutually unreachable peaks, the arm here follows a move that was checked.
"""

from __future__ import annotations

import numpy as np

from previewctl.control.base import ControlState, NullInput
from previewctl.control.imaginary import ImaginaryArms
from previewctl.control.nullspace import gain_vector, preview_pull, wrapped_difference
from previewctl.control.params import ControllerParams
from previewctl.control.planner import PeakPlanner
from previewctl.control.sweeps import SweepRoutes
from previewctl.errors import ConfigurationError
from previewctl.robot.model import Robot


class Reach:
    """``reach`` (module docstring).

    Args:
        robot: the arm.
        params: ``gain``, ``weights`` (the fallback blend), ``coherent`` and ``settle_frames``.
        arms: one imaginary arm per weight.
        route: the planner toward the peaks, or the straight sweeps.
        keep: velocity indices whose differences are never wrapped (the planar elbow in coherent mode).

    Raises:
        ConfigurationError: not one imaginary arm per weight.
    """

    name = "reach"

    def __init__(self, robot: Robot, params: ControllerParams, arms: ImaginaryArms, route: PeakPlanner | SweepRoutes,
                 *, keep: tuple[int, ...] = ()) -> None:
        if len(arms) != len(params.weights):
            raise ConfigurationError(f"reach needs {len(params.weights)} imaginary arms (one per weight k_i), "
                                     f"got {len(arms)}")
        self.robot, self.params, self.arms, self.route, self._keep = robot, params, arms, route, keep
        self.weights = np.array(params.weights)
        self._gain = gain_vector(params.gain, robot.nv, "gain")

    def null_input(self, state: ControlState) -> NullInput:
        """Step the searches at a frame, then move toward the chosen peak."""
        q, t, route = state.q, state.t, self.route
        if self.arms.update(state):
            if isinstance(route, PeakPlanner):
                route.peaks = self.arms.levels()
            else:
                route.choose(q, t, [(nodes, values) for _, nodes, values in self.arms.levels()], state.path)
        targets, values = self.arms.best[0].copy(), self.arms.best[1].copy()
        if isinstance(route, PeakPlanner):
            route.update(state, settled=self.arms.frames >= self.params.settle_frames)
            if route.goal is not None:
                level, goal, S = route.goal
                targets[level], values[level] = goal, S
            v = route.planner.pull(q, t, self._gain)[0]
            return NullInput(v, targets, values)
        if route.route is not None:
            n = len(route.route.nodes)
            targets[:n], values[:n] = route.route.nodes, route.route.S
            v = wrapped_difference(self.robot, q, route.route.lead, keep=self._keep) / route.step
        else:
            v = self._gain * preview_pull(self.robot, q, targets, self.weights, keep=self._keep)
        if self.params.coherent:  # ramp in while the searches settle
            v = v * min(1.0, self.arms.frames / self.params.settle_frames)
        return NullInput(v, targets, values)
