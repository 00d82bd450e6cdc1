"""The window planner: a motion that tracks the path through the future, checked collision-free, and the plans
toward the imaginary arms' peaks.

:class:`WindowPlanner` plans from the arm's configuration over ``[t, t + window]`` (or, with no window, over the
whole rest of the path: the non-causal ``oracle``), and replans every ``replan_period``:

* on a planar arm of 2-4 joints, by the reachability DP (:func:`previewctl.search.reachability.reach_over_time`),
  which maximises the worst AMSIP along the motion, then its total;
* on a spatial arm, by the sampled forward search (:func:`previewctl.search.roadmap.roadmap_over_time`), its samples
  0.05 s apart: checked at its samples only, and not complete ("none found" only means that its beam found none).

With observed obstacles (:mod:`previewctl.sensing`) the plan keeps each predicted obstacle inflated by its margin. The
margin is insurance against a wrong prediction, not a certainty: when no motion gets through the window with the
margins, the plan is made again with the obstacles at their predicted size, and that plan is followed if a motion
gets through (:attr:`WindowPlanner.plans_without_margins` counts them); a route that is free if the prediction holds
beats one certain to end (the choice: docs/decisions.md#plans-without-the-margins-issue-33). The QP keeps its own
margin at the present.

A plan made at ``t`` is followed from ``t + latency`` (a planner beside the control loop; the first at once), or with
the ``"measured"`` latency from ``t`` plus its own CPU time rounded up to whole control periods. The
plan's configuration at any time, :meth:`WindowPlanner.point`, is linear between samples, unwrapped along the motion
(a continuous joint's angle stands for its (cos, sin) pair), so the difference to it is taken without wrapping: a
planar elbow changes branch where the plan does, at the stretched wrist.

:class:`PeakPlanner` plans toward goals: the imaginary arms' positive peaks
(:mod:`~previewctl.search.reachability.goals`). The goal is the best peak that some collision-free motion reaches,
and can go on from to the window's end, at the latest preview time that has one (a peak near the last goal gets the
``hysteresis`` bonus); with no peak reached, the plan is the planner's best motion over the window.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from previewctl.control.base import ControlState
from previewctl.control.params import MEASURED, ControllerParams, PlanLatency
from previewctl.control.peaks import near
from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.search.reachability import ReachMotion, ReachOptions, ReachResult, reach_over_time
from previewctl.search.reachability.goals import Goals
from previewctl.search.reachability.grid import fast_enough
from previewctl.search.roadmap import RoadmapOptions, roadmap_over_time
from previewctl.types import Array
from previewctl.validation import Checked, NonNegative, Positive

ORACLE_OPTIONS = ReachOptions(resolution_deg=2.0, steps=50, max_step_cells=3, map_times=0)
"""The DP the oracle plans with by default: 2° grid, at least 50 steps over the rest of the path, no figure maps.
Each plan raises the steps until a gene may move at :data:`ORACLE_GENE_SPEED` of its joint speed limit,
coarsening the grid (4°, 8°, ...) when that many steps would not fit
(:func:`~previewctl.search.reachability.grid.fast_enough`). What that gives on the bench and paper scenes:
docs/guide/search.md#reachability-over-time."""
ORACLE_GENE_SPEED = 0.5
"""The share of a gene's joint speed limit the oracle's DP must allow at least. The rest is the hand task's: with
plans at the full limit eq. 19 has no speed left for the hand (tried: docs/decisions.md#the-oracles-gene-speed)."""
HORIZON_OPTIONS = ReachOptions(resolution_deg=4.0, steps=1, max_step_cells=3, map_times=0)
"""The DP ``horizon`` replans with: the bench witness's 4° grid; ``steps`` is set per plan (one per
:data:`HORIZON_STEP` of the window)."""
HORIZON_ROADMAP = RoadmapOptions(beam=16, children=8)
"""The sampled search ``horizon`` (and coherent ``reach``) replans a spatial arm with: a third of the oracle's beam and
two thirds of its moves per node, for cost (what a plan costs: docs/speed.md); not tuned further."""
HORIZON_STEP = 0.16
"""[s] the DP's time step in ``horizon``'s plans (the oracle's 8 s / 50 steps on the bench scenes) ..."""
HORIZON_MAX_STEPS = 24
"""... up to this many steps per plan (a longer window gets longer steps: the paper's 15 s, 0.63 s each)."""


@dataclass(frozen=True)
class PlanTiming(Checked):
    """When plans are made and followed.

    Attributes:
        replan_period: time between two plans [s].
        window: how far ahead [s] each plan looks; ``None``: over the whole rest of the path (one plan).
        latency: how long [s] a plan takes to arrive: a plan made from the state at ``t`` is followed from
            ``t + latency`` on, the previous one until then (the first plan at once). At most ``replan_period``.
            ``"measured"``: the plan's own CPU time, rounded up to whole control periods (the next plan is made once
            it has arrived, as one planner beside the loop would).
        lookahead: ``t_l`` [s], how far ahead on the plan a follower takes its target.
    """

    error = ConfigurationError

    replan_period: Positive = 0.5
    window: Positive | None = None
    latency: PlanLatency = 0.0
    lookahead: NonNegative = 0.1

    def check(self) -> None:
        """The planner makes one plan at a time: ``latency <= replan_period``."""
        if isinstance(self.latency, float) and self.latency > self.replan_period:
            raise ConfigurationError(f"a plan latency of {self.latency:g} s is longer than the replan period "
                                     f"{self.replan_period:g} s; the planner makes one plan at a time, so the latency "
                                     "must be at most the period")

    @classmethod
    def of(cls, params: ControllerParams) -> PlanTiming:
        """A replanning planner's timing from the controller's settings: ``plan_window`` (default ``p t̃``, the
        preview controllers' reach into the future), ``replan_period`` (default ``t̃ / 2``), ``plan_latency``."""
        replan = params.replan_period if params.replan_period is not None else params.preview_time / 2
        window = params.plan_window if params.plan_window is not None else params.preview_time * len(params.weights)
        return cls(replan_period=replan, window=window, latency=params.plan_latency)


class WindowPlanner:
    """Plans and replans the arm's motion (module docstring); :meth:`point` reads the plan being followed.

    Args:
        robot: the arm (a planar arm: the DP, which needs 2 to 4 joints; a spatial arm: the sampled search).
        evaluator: the AMSIP evaluator of the scene (the DP's S and distances).
        timing: window, replan period, latency and lookahead.
        plan: a plan made before (a :class:`ReachResult` or its :class:`ReachMotion`); default: planned when due.
        options: the DP's grid and transition model (default :data:`ORACLE_OPTIONS` with no window,
            :data:`HORIZON_OPTIONS` with one). Without a window, the steps are raised until a gene may move at
            :data:`ORACLE_GENE_SPEED` of its joint speed limit (coarsening the grid if needed); every plan lowers
            them when the path left is too short for them (a step must let a gene move by at least one grid cell).
        roadmap: the spatial arm's search (default :class:`~previewctl.search.roadmap.RoadmapOptions` with no
            window, :data:`HORIZON_ROADMAP` with one).
        clock: the CPU clock [s] a plan's compute time is read from (a test's stand-in controls it).

    Attributes:
        motion, result: the plan being followed, and its DP result (``None`` for a plan with nothing left to
            track, or one given as a bare motion).
        planned: the DP result of the last plan made, which may not be followed yet (``None`` on a spatial arm).
        goal: ``(level, index)`` of the goal the last plan made heads for (``goals[level].q[index]``), or ``None``.
        costs: the CPU time [s] of each plan made, in order.
        plans_without_margins: how many plans were made without the predicted obstacles' margins (module docstring).
    """

    def __init__(
        self,
        robot: Robot,
        evaluator: Evaluator,
        timing: PlanTiming,
        *,
        plan: ReachResult | ReachMotion | None = None,
        options: ReachOptions | None = None,
        roadmap: RoadmapOptions | None = None,
        clock: Callable[[], float] = time.process_time,
    ) -> None:
        self.robot, self.evaluator, self.timing, self.clock = robot, evaluator, timing, clock
        self.costs: list[float] = []
        self.plans_without_margins = 0
        windowed = timing.window is not None
        self.options = options or (HORIZON_OPTIONS if windowed else ORACLE_OPTIONS)
        self.roadmap = roadmap or (HORIZON_ROADMAP if windowed else RoadmapOptions())
        self._next_plan = -math.inf
        self.result: ReachResult | None = plan if isinstance(plan, ReachResult) else None
        self.motion: ReachMotion | None = plan.motion if isinstance(plan, ReachResult) else plan
        self.planned: ReachResult | None = self.result
        self.goal: tuple[int, int] | None = None
        self._pending: tuple[float, ReachMotion, ReachResult | None] | None = None  # (from when [s], motion, result)
        self._angles: tuple[ReachMotion, ReachMotion] | None = None  # (a plan, it in joint coordinates)
        self._join: tuple[float, Array] | None = None  # (fades from [s], offset (nv,)) of a late plan (follow())

    @property
    def kind(self) -> str:
        """``dp`` (the reachability DP, planar arms) or ``sampled`` (the sampled search, spatial arms)."""
        return "sampled" if self.robot.planar is None else "dp"

    def plan(self, state: ControlState, goals: Sequence[Goals] = ()) -> ReachMotion:
        """Make the plan from the state's configuration and time over the rest of its path (no window), or over the
        window ``[t, t + window]`` cut at the path's end; toward the best reached of ``goals`` when one is (see
        :func:`~previewctl.search.reachability.reach_over_time`)."""
        start = self.clock()
        self._next_plan = state.t + self.timing.replan_period
        motion, result, goal = self._search(state, goals)
        return self._made(state, motion, result, goal, self.clock() - start)

    def _search(self, state: ControlState,
                goals: Sequence[Goals]) -> tuple[ReachMotion, ReachResult | None, tuple[int, int] | None]:
        """The plan from ``state``: its motion, DP result (``None`` on a spatial arm) and goal (:meth:`plan`); if no
        motion gets through the window with the predicted obstacles inflated by their margins, the plan without the
        margins when one gets through (module docstring)."""
        motion, result, goal, through = self._find(state, goals)
        if not through and self.evaluator.predicts:
            with self.evaluator.without_margins():
                bare = self._find(state, goals)
            if bare[3]:
                self.plans_without_margins += 1
                motion, result, goal, _ = bare
        return motion, result, goal

    def _find(self, state: ControlState, goals: Sequence[Goals]
              ) -> tuple[ReachMotion, ReachResult | None, tuple[int, int] | None, bool]:
        """The search's plan from ``state`` (:meth:`_search`), and whether its motion gets through the window."""
        t, q = state.t, state.q
        horizon = state.path.end_time - t
        if self.timing.window is not None:
            horizon = min(horizon, self.timing.window)
        if horizon <= 0:  # nothing left to track: hold q (no DP result, so no goal of an earlier plan either)
            return _hold(t, q), None, None, True
        if self.robot.planar is None:  # a spatial arm: the sampled forward search
            found = roadmap_over_time(self.robot, self.evaluator, state.path, q, horizon, self.roadmap, t_start=t,
                                      goals=goals)
            return found.motion, None, found.goal, found.exists
        options = self.options
        if self.timing.window is not None:
            options = replace(options, steps=min(HORIZON_MAX_STEPS, max(1, round(horizon / HORIZON_STEP))))
        else:  # the reference's genes may move at half the arm's speed limits
            options = fast_enough(self.robot, options, horizon, ORACLE_GENE_SPEED)
        slowest = float(np.min(self.robot.velocity_limits[: max(self.robot.nq - 2, 0)], initial=np.inf))
        if math.isfinite(slowest) and slowest > 0 and self.robot.nq > 2:
            fit = math.floor(horizon * slowest * options.velocity_scale / math.radians(options.resolution_deg) + 1e-9)
            if fit < 1:  # too little path left for a joint to move one grid cell: no step to plan
                return _hold(t, q), None, None, True
            options = replace(options, steps=min(options.steps, fit))
        result = reach_over_time(self.robot, self.evaluator, state.path, q, horizon, options, t_start=t, goals=goals)
        return result.motion, result, result.goal, result.exists

    def _made(self, state: ControlState, motion: ReachMotion, result: ReachResult | None,
              goal: tuple[int, int] | None, cost: float) -> ReachMotion:
        """A plan made at ``t`` [s] in ``cost`` [s] of CPU time: followed from now on, or from ``t`` + its latency
        once there is one to follow."""
        t = state.t
        self.arrive(t)
        self.planned, self.goal, self._join = result, goal, None
        self.costs.append(cost)
        measured = self.timing.latency == MEASURED
        delay = math.ceil(cost / state.dt - 1e-9) * state.dt if measured else float(self.timing.latency)
        if measured:  # one plan at a time: the next once this one has arrived
            self._next_plan = max(self._next_plan, t + delay)
        if delay > 0 and self.motion is not None:
            self._pending = (t + delay, motion, result)
        else:
            self.motion, self.result, self._pending = motion, result, None
        return motion

    def arrive(self, t: float) -> None:
        """Follow the pending plan from ``t`` [s] on if it has arrived by then."""
        if self._pending is not None and t >= self._pending[0] - 1e-9:
            _, self.motion, self.result = self._pending
            self._pending = None

    def follow(self, motion: ReachMotion, t: float, q: Array) -> None:
        """Follow ``motion``, a plan made elsewhere from an earlier state, from ``t`` [s] on, joined to the arm's
        configuration ``q`` at ``t`` (a late plan, :mod:`previewctl.control.background`).

        The plan followed is ``q_J(τ) = q*(τ) ⊕ (1 − s(u)) (q ⊖ q*(t))`` with ``u = clip((τ − t − t_l) / T, 0, 1)``,
        ``s(u) = 3u² − 2u³``, ``t_l`` the lookahead and ``T`` the replan period: up to the lookahead it is the plan
        moved to start where the arm is, so the first command after the delivery (:meth:`pull`) is the one an arm on
        the plan gets; the offset then fades smoothly (``s'(0) = s'(1) = 0``), and from ``t + t_l + T`` on it is the
        plan itself. The plan is read at the present time, never from its own start, so a plan that arrives late
        neither replays the motion it planned for the time it took nor pulls the arm back toward where the arm was
        when it was made.
        """
        self.motion, self.result, self._pending = motion, None, None
        self._join = None
        self._join = (t + self.timing.lookahead, pin.difference(self.robot.model, self.configuration(t)[0], q))

    def due(self, t: float) -> bool:
        """Whether a plan is due at ``t`` [s]: none made yet, or a replan (with a window; without, it plans once)."""
        return self.motion is None or (self.timing.window is not None and t >= self._next_plan)

    def point(self, t: float) -> tuple[Array, Array, float]:
        """The plan being followed at time ``t`` [s]: its configuration ``(nq,)``, velocity ``(nv,)`` [rad/s] and S
        (linear between samples; the first or last sample, at rest, outside the plan)."""
        q, S = self.configuration(t)
        coordinates = self._coordinates(self._followed())
        rate = coordinates.velocity(t)
        if self._join is not None:  # a late plan joined to the arm (follow()): the offset's fade
            start, offset = self._join
            u, period = self._fade(t, start)
            rate = rate - 6.0 * u * (1.0 - u) / period * offset
        return q, rate, S

    def configuration(self, t: float) -> tuple[Array, float]:
        """The configuration ``(nq,)`` and S of :meth:`point` at ``t`` [s], without the velocity."""
        q, S = self.configurations(np.array([t], dtype=float))
        return q[0], float(S[0])

    def configurations(self, times: Array) -> tuple[Array, Array]:
        """The configurations ``(T, nq)`` and S ``(T,)`` of :meth:`point` at the times ``(T,)`` [s], without the
        velocities (one compiled call for the plan's samples, however many times)."""
        motion = self._followed()
        angles, S = self._coordinates(motion).sample(times)
        if self._join is not None:  # a late plan joined to the arm (follow()): the offset, fading
            start, offset = self._join
            for row, t in zip(angles, times.tolist(), strict=True):
                u, _ = self._fade(t, start)
                row += (1.0 - u * u * (3.0 - 2.0 * u)) * offset
        q = angles if self.robot.joints.vector_space else self.robot.configurations_from_angles(angles)
        return q, S

    def _followed(self) -> ReachMotion:
        """The plan being followed; a :class:`~previewctl.errors.ConfigurationError` before the first."""
        if self.motion is None:
            raise ConfigurationError("no plan was made yet: plan() makes one")
        return self.motion

    def _fade(self, t: float, start: float) -> tuple[float, float]:
        """Where ``t`` [s] is in the fade of a join that fades from ``start`` [s] (:meth:`follow`): ``u`` in [0, 1],
        and the fade's length [s]."""
        period = self.timing.replan_period
        return min(max((t - start) / period, 0.0), 1.0), period

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

    def pull(self, q: Array, t: float, gain: Array) -> tuple[Array, Array, float]:
        """The null-space input that follows the plan, ``v = q̇*(t + t_l) + K_v (q*(t + t_l) ⊖ q)`` [rad/s] ``(nv,)``
        (feed-forward and feedback toward the plan at the lookahead ``t_l``), with that point of the plan
        ``(nq,)`` and its S."""
        self.arrive(t)
        q_ref, rate, S_ref = self.point(t + self.timing.lookahead)
        return rate + gain * pin.difference(self.robot.model, q, q_ref), q_ref, S_ref


def _hold(t: float, q: Array) -> ReachMotion:
    """The plan that holds ``q`` from ``t`` [s]: one sample, no step."""
    return ReachMotion(times=np.array([t]), q=np.array([q], dtype=float), S=np.array([np.nan]),
                       branch=np.zeros(1, dtype=np.int64), cells=np.full(1, -1, dtype=np.int64), min_S=float("nan"),
                       total_S=0.0)


class PeakPlanner:
    """A :class:`WindowPlanner` that heads for the imaginary arms' peaks (module docstring).

    Args:
        robot: the arm.
        planner: the window planner.
        hysteresis: relative S bonus of the peaks near the last goal.
        track_radius: how near [rad] a peak must be to the last goal to get it.

    Attributes:
        peaks: the last frame's positive peaks, ``(t_i [s], nodes (K, nq), S (K,))`` per preview time.
        goal: ``(level, configuration, S)`` of the peak the last plan heads for (``None``: no plan yet, or no
            peak reached: the plan is then the planner's best motion over the window).
    """

    def __init__(self, robot: Robot, planner: WindowPlanner, *, hysteresis: float, track_radius: float) -> None:
        self.robot, self.planner, self.hysteresis, self.track_radius = robot, planner, hysteresis, track_radius
        self.peaks: list[tuple[float, Array, Array]] = []
        self.goal: tuple[int, Array, float] | None = None

    def update(self, state: ControlState, *, settled: bool) -> None:
        """Replan when due, toward the peaks once ``settled`` (before, they are not worth heading for)."""
        planner = self.planner
        if planner.due(state.t):
            planner.plan(state, goals=self._goals() if settled else ())
            pick = planner.goal
            if pick is None:
                self.goal = None
            else:
                _, nodes, peak_S = self.peaks[pick[0]]
                self.goal = (pick[0], nodes[pick[1]], float(peak_S[pick[1]]))
        planner.arrive(state.t)

    def _goals(self) -> list[Goals]:
        """The last frame's peaks as goals, those near the last planned goal with the hysteresis bonus."""
        goal = self.goal
        return [Goals(t_i, nodes, values * (1.0 + self.hysteresis * near(
                    self.robot, goal[1] if goal and goal[0] == i else None, nodes, self.track_radius)))
                for i, (t_i, nodes, values) in enumerate(self.peaks)]
