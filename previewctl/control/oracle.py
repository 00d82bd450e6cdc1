"""``oracle``: a NON-CAUSAL reference controller that follows the reachability DP's best motion.

Not a controller the paper proposes, and not one a robot could run on-line: it reads the whole
future (the hand path and every obstacle's motion over the run) before the first cycle, and asks
:func:`previewctl.search.reachability.reach_over_time` for the collision-free tracking motion with the
best minimum AMSIP (max-min S, then max total S). It then tracks that motion through eq. 19, like a
preview controller whose imaginary arm is the oracle's configuration ``q*(t + t_l)`` a small lookahead
``t_l`` ahead:

    v = q̇*(t + t_l) + K_v (q*(t + t_l) − q),        q̇ = J#(ṙ_d + K_p e) + (I − J⁺J) v,

with ``q*`` the DP's samples interpolated linearly in time (unwrapped along the motion, so the
difference is taken without wrapping: the elbow changes branch where the plan does, at the
stretched wrist) and ``q̇*`` its slope (feed-forward); a continuous joint's angle stands for its (cos, sin)
pair. ``K_v`` is ``ControllerParams.gain``.

Its purpose is comparison: any run can be set against what was possible in the same scene. When
the DP finds no motion to the end, the oracle follows the best motion to the dead end and then holds
its last configuration as the target (the run will then show where the scene defeats every motion
of the DP's model).

The plan is made at the first call of :meth:`OracleController.command` from the state's path and
scene, the evaluator's index and potential and the configuration at that time, over the rest of
the path (``path.end_time − t``); that first cycle therefore takes seconds. Pass ``plan=`` to reuse
a plan made before. The DP needs a planar arm of 2-4 joints (its grid). On a spatial arm the plan is the best
motion of the sampled forward search :func:`previewctl.search.roadmap.roadmap_over_time`, its samples 0.05 s
apart: checked at its samples only, and not complete ("none found" only means that its beam found none). On
held-out Panda bench scenes (scene seeds 1 and 2, 40 scenes, QP execution) the spatial oracle followed its
motion within 1 mm without collision on 38.

``horizon`` is the same machinery made causal: the paper's "future reachability evaluation" done by
the DP instead of by imaginary arms. It reads the future only over a window of ``plan_window`` [s]
(default: as far as the preview controllers do, to the last preview time ``t + p t̃``; the bench's planar
scenes set 6 s): every ``replan_period`` [s] (default ``t̃ / 2``) it plans from the arm's configuration
over ``[t, t + plan_window]`` only, on a coarser grid (:data:`HORIZON_OPTIONS`: 4°, one step per 0.16 s, at
most 24 steps), and follows that plan as the oracle follows its own. The plan maximises the worst S inside
the window and knows nothing beyond it. On a spatial arm it replans with a smaller sampled search
(:data:`HORIZON_ROADMAP`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pinocchio as pin

from previewctl.control.base import ControlInfo, ControlState
from previewctl.control.params import ControllerParams
from previewctl.control.tracking import gain_vector, track
from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.search.reachability import ReachMotion, ReachOptions, ReachResult, reach_over_time
from previewctl.search.reachability.goals import Goals
from previewctl.search.reachability.grid import fast_enough
from previewctl.search.roadmap import RoadmapOptions, roadmap_over_time
from previewctl.types import Array

ORACLE_OPTIONS = ReachOptions(resolution_deg=2.0, steps=50, max_step_cells=3, map_times=0)
"""The DP the oracle plans with by default: 2° grid, at least 50 steps over the rest of the path, no figure maps.
Each plan raises the steps until a gene may move at :data:`ORACLE_GENE_SPEED` of its joint speed limit,
coarsening the grid (4°, 8°, ...) when that many steps would not fit
(:func:`~previewctl.search.reachability.grid.fast_enough`): on the 8 s bench scenes that leaves 2° and 50 steps
(genes up to 65 % of their limit), on the paper's 50 s scenes it gives 4° and 120 steps (genes up to 50 %
instead of 10 % with 50 steps at 2°)."""
ORACLE_GENE_SPEED = 0.5
"""The share of a gene's joint speed limit the oracle's DP must allow at least. The rest is the hand task's:
with plans at the full limit (tried), eq. 19 scaled the commands down and the oracle collided on 4 more of the
50 bench scenes (98 % -> 90 % collision-free under eq. 19; 92 % at 1 mm under the QP either way)."""
HORIZON_OPTIONS = ReachOptions(resolution_deg=4.0, steps=1, max_step_cells=3, map_times=0)
"""The DP ``horizon`` replans with: the bench witness's 4° grid; ``steps`` is set per plan (one per
:data:`HORIZON_STEP` of the window)."""
HORIZON_ROADMAP = RoadmapOptions(beam=16, children=8)
"""The sampled search ``horizon`` (and coherent ``reach``) replans a spatial arm with: a third of the oracle's beam and
two thirds of its moves per node, for cost (a 6 s plan on the Panda bench scenes costs 0.58 s of CPU at the median,
0.95 s at the 95th percentile); not tuned further."""
HORIZON_STEP = 0.16
"""[s] the DP's time step in ``horizon``'s plans (the oracle's 8 s / 50 steps on the bench scenes) ..."""
HORIZON_MAX_STEPS = 24
"""... up to this many steps per plan (a longer window gets longer steps: the paper's 15 s, 0.63 s each)."""


class OracleController:
    """``oracle`` (non-causal): tracks the reachability DP's best motion; with ``window``, the causal ``horizon``
    that replans over the preview window (see the module docstring).

    Args:
        robot: the arm (a planar arm: the DP, which needs 2 to 4 joints; a spatial arm: the sampled search).
        params: gains (``gain`` is ``K_v`` [1/s]), feedback, damping and limits of eq. 19.
        evaluator: the AMSIP evaluator of the scene (the DP's S and distances).
        plan: a plan made before (a :class:`ReachResult` or its :class:`ReachMotion`); default: planned at
            the first call.
        options: the DP's grid and transition model (default :data:`ORACLE_OPTIONS`). The oracle raises the
            number of steps until a gene may move at :data:`ORACLE_GENE_SPEED` of its joint speed limit
            (coarsening the grid if needed); every plan lowers it when the path left is too short for it (a
            step must let a gene move by at least one grid cell).
        roadmap: the spatial oracle's search (default :class:`~previewctl.search.roadmap.RoadmapOptions`).
        lookahead: ``t_l`` [s], how far ahead on the plan the target is taken (>= 0).
        window: ``horizon`` mode: how far ahead [s] each plan looks (``None``: the oracle, the whole rest).
        replan_period: ``horizon`` mode: time between plans [s].
        latency: ``horizon`` mode: how long [s] a plan takes to arrive (a planner beside the control loop): a
            plan made from the state at ``t`` is followed from ``t + latency`` on, the previous one until then.
            The first plan is made before the run starts and followed at once. At most ``replan_period``
            (one plan at a time); 0: each plan is followed in the cycle that makes it.

    Attributes:
        motion, result: the plan being followed, and its DP result (``None`` for a plan with nothing left to
            track, or one given as a bare motion).
        planned: the DP result of the last plan made, which may not be followed yet (``None`` on a spatial arm).
        goal: ``(level, index)`` of the goal the last plan made heads for (``goals[level].q[index]``), or ``None``.

    Raises:
        ConfigurationError: a negative or non-finite lookahead, window, replan period or latency, or a latency
            longer than the replan period.
    """

    def __init__(
        self,
        robot: Robot,
        params: ControllerParams,
        evaluator: Evaluator,
        *,
        plan: ReachResult | ReachMotion | None = None,
        options: ReachOptions | None = None,
        roadmap: RoadmapOptions | None = None,
        lookahead: float = 0.1,
        window: float | None = None,
        replan_period: float = 0.5,
        latency: float = 0.0,
    ) -> None:
        self.name = "oracle" if window is None else "horizon"
        times = {"lookahead": (lookahead, True), "replan period": (replan_period, False), "latency": (latency, True)}
        if window is not None:
            times["window"] = (window, False)
        for label, (value, zero_ok) in times.items():
            finite = isinstance(value, (int, float)) and math.isfinite(value)
            if not finite or value < 0 or (value == 0 and not zero_ok):
                bound = ">= 0" if zero_ok else "> 0"
                raise ConfigurationError(f"{self.name} {label} must be a finite number {bound} [s], got {value!r}")
        if latency > replan_period:
            raise ConfigurationError(f"{self.name}: a plan latency of {latency:g} s is longer than the replan period "
                                     f"{replan_period:g} s; the planner makes one plan at a time, so the latency "
                                     "must be at most the period")
        self.robot, self.params, self.evaluator = robot, params, evaluator
        self.options = options or (ORACLE_OPTIONS if window is None else HORIZON_OPTIONS)
        self.roadmap = roadmap or (RoadmapOptions() if window is None else HORIZON_ROADMAP)
        self.lookahead = float(lookahead)
        self.window = None if window is None else float(window)
        self.replan_period = float(replan_period)
        self.latency = float(latency)
        self._next_plan = -math.inf
        self.result: ReachResult | None = plan if isinstance(plan, ReachResult) else None
        self.motion: ReachMotion | None = plan.motion if isinstance(plan, ReachResult) else plan
        self.planned: ReachResult | None = self.result
        self.goal: tuple[int, int] | None = None
        self._pending: tuple[float, ReachMotion, ReachResult | None] | None = None  # (from when [s], motion, result)
        self._gain = gain_vector(params.gain, robot.nv, "gain")
        self._angles: tuple[ReachMotion, ReachMotion] | None = None  # (a plan, it in joint coordinates)

    @classmethod
    def horizon(cls, robot: Robot, params: ControllerParams, evaluator: Evaluator) -> OracleController:
        """``horizon`` with the window ``params.plan_window`` (default ``p t̃``, the preview controllers' reach into
        the future, ``p`` the number of preview weights) and ``params.replan_period`` (default ``t̃ / 2``)."""
        replan = params.replan_period if params.replan_period is not None else params.preview_time / 2
        window = params.plan_window if params.plan_window is not None else params.preview_time * len(params.weights)
        return cls(robot, params, evaluator, window=window, replan_period=replan, latency=params.plan_latency)

    def plan(self, t: float, q: Array, state: ControlState, goals: Sequence[Goals] = ()) -> ReachMotion:
        """Make the plan from configuration ``q`` at time ``t`` [s] over the rest of ``state.path`` (the oracle), or
        over the window ``[t, t + window]`` cut at the path's end (``horizon``); toward the best reached of
        ``goals`` when one is (see :func:`~previewctl.search.reachability.reach_over_time`)."""
        self._next_plan = t + self.replan_period
        horizon = state.path.end_time - t
        if self.window is not None:
            horizon = min(horizon, self.window)
        if horizon <= 0:  # nothing left to track: hold q (no DP result, so no goal of an earlier plan either)
            hold = ReachMotion(times=np.array([t]), q=np.array([q], dtype=float), S=np.array([np.nan]),
                               branch=np.zeros(1, dtype=np.int64), cells=np.full(1, -1, dtype=np.int64),
                               min_S=float("nan"), total_S=0.0)
            return self._made(t, hold, None)
        if self.robot.planar is None:  # a spatial arm: the sampled forward search
            found = roadmap_over_time(self.robot, self.evaluator, state.path, q, horizon, self.roadmap, t_start=t,
                                      goals=goals)
            return self._made(t, found.motion, None, found.goal)
        options = self.options
        if self.window is not None:
            options = replace(options, steps=min(HORIZON_MAX_STEPS, max(1, round(horizon / HORIZON_STEP))))
        else:  # the reference's genes may move at half the arm's speed limits
            options = fast_enough(self.robot, options, horizon, ORACLE_GENE_SPEED)
        slowest = float(np.min(self.robot.velocity_limits[: max(self.robot.nq - 2, 0)], initial=np.inf))
        if math.isfinite(slowest) and slowest > 0 and self.robot.nq > 2:
            fit = math.floor(horizon * slowest * options.velocity_scale / math.radians(options.resolution_deg) + 1e-9)
            if fit < options.steps:
                options = replace(options, steps=max(1, fit))
        result = reach_over_time(self.robot, self.evaluator, state.path, q, horizon, options, t_start=t, goals=goals)
        return self._made(t, result.motion, result, result.goal)

    def _made(self, t: float, motion: ReachMotion, result: ReachResult | None,
              goal: tuple[int, int] | None = None) -> ReachMotion:
        """A plan made at ``t`` [s]: followed from now on, or from ``t + latency`` once there is one to follow."""
        self.arrive(t)
        self.planned, self.goal = result, goal
        if self.latency > 0 and self.motion is not None:
            self._pending = (t + self.latency, motion, result)
        else:
            self.motion, self.result, self._pending = motion, result, None
        return motion

    def arrive(self, t: float) -> None:
        """Follow the pending plan from ``t`` [s] on if it has arrived by then."""
        if self._pending is not None and t >= self._pending[0] - 1e-9:
            _, self.motion, self.result = self._pending
            self._pending = None

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]: eq. 19 pulled toward the plan at ``t + lookahead``."""
        if self.motion is None or self.due(t):
            self.plan(t, q, state)
        return self.follow(t, q, state)

    def due(self, t: float) -> bool:
        """Whether a ``horizon`` plan is due at ``t`` [s] (the oracle plans once)."""
        return self.window is not None and t >= self._next_plan

    def point(self, t: float) -> tuple[Array, Array, float]:
        """The plan being followed at time ``t`` [s]: its configuration ``(nq,)``, velocity ``(nv,)`` [rad/s] and S
        (linear between samples; the first or last sample, at rest, outside the plan)."""
        motion = self.motion
        if motion is None:
            raise ConfigurationError(f"{self.name}: no plan was made yet (plan() or command() makes one)")
        coordinates = self._coordinates(motion)
        angles = coordinates.at(t)
        q = angles if self.robot.joints.vector_space else self.robot.configuration_from_angles(angles)
        S = float(np.interp(t, motion.times, motion.S)) if motion.times.size else float("nan")
        return q, coordinates.velocity(t), S

    def _coordinates(self, motion: ReachMotion) -> ReachMotion:
        """``motion`` in joint coordinates ``(nv)``: itself on an arm whose configuration is its joint angles;
        otherwise each continuous joint's angle in place of its (cos, sin) pair, unwrapped along the motion (so
        the linear interpolation between samples is the search's move), made once per plan."""
        if self.robot.joints.vector_space:
            return motion
        if self._angles is None or self._angles[0] is not motion:
            angles = self.robot.angles_of(motion.q)
            turning = self.robot.joints.continuous
            angles[:, turning] = np.unwrap(angles[:, turning], axis=0)
            self._angles = (motion, replace(motion, q=angles))
        return self._angles[1]

    def follow(self, t: float, q: Array, state: ControlState, targets: Array | None = None,
               values: Array | None = None) -> tuple[Array, ControlInfo]:
        """Eq. 19 pulled toward the current plan at ``t + lookahead``; ``targets``/``values`` (default: that
        point of the plan and its S) are what the log records as the imaginary arms."""
        self.arrive(t)
        q_ref, rate, S_ref = self.point(t + self.lookahead)
        v = rate + self._gain * pin.difference(self.robot.model, q, q_ref)
        if targets is None or values is None:
            targets, values = q_ref[None, :], np.array([S_ref])
        return track(self.robot, t, q, state, v, self.params, targets, values)
