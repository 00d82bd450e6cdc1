"""Imaginary arms (eqs. 20-21): one search per preview time ``t + i t̃``, and the policies that pick their targets.

:class:`ImaginaryArms` runs one generation of each search per camera frame, against the hand target
``r_d(t + i t̃)`` and the scene at that time. A *policy* then says which configuration each imaginary arm stands
for, ``q̃_i``:

* :class:`ArgmaxArms` (the paper's literal eqs. 20/21): each frame's best candidate of each search, on any branch;
* :class:`TrackedPeaks`: one tracked peak per arm, chained from the arm and ramped in after a change
  (:mod:`previewctl.control.peaks`);
* :class:`RoutePoints`: where a route planned toward the arms' peaks puts the arm at the preview times,
  ``q_plan(t + i t̃)`` (:class:`~previewctl.control.planner.PeakPlanner`).

Every policy returns :class:`Targets`, which the preview pull (:func:`~previewctl.control.nullspace.preview_pull`)
blends with the weights ``k_i``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from previewctl.control.base import ControlState
from previewctl.control.params import ControllerParams
from previewctl.control.peaks import PeakTracker
from previewctl.control.planner import PeakPlanner, WindowPlanner
from previewctl.control.tracking import effective_velocity_limits
from previewctl.errors import ConfigurationError
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.search.ga import OneStepGA, step_together
from previewctl.search.planar import PlanarRedundancy
from previewctl.types import Array


@runtime_checkable
class SearchLike(Protocol):
    """The interface of :class:`previewctl.search.ga.OneStepGA` that the imaginary arms use."""

    def step(self, target: Array, t: float) -> Any:
        """Run one generation against hand target ``target`` at time ``t`` [s]; return the best candidate."""
        ...

    def peaks(self) -> tuple[Any, ...]:
        """The distinct peaks currently held."""
        ...

    def seed(self, q: Array) -> None:
        """Put configuration ``q`` into the population."""
        ...


SearchFactory = Callable[[int, np.random.Generator], SearchLike]
"""``factory(i, rng_i)`` builds the search of imaginary arm ``i`` from its own random stream."""


def step_searches(searches: Sequence[SearchLike], path: HandPath, times: Sequence[float]) -> list[Any]:
    """One generation of ``searches[i]`` toward the hand target ``path.position(times[i])`` at
    ``times[i]`` [s]; their best candidates. 1-step GAs run through
    :func:`previewctl.search.ga.step_together` (same result, one shared Newton projection)."""
    targets = [np.asarray(path.position(t_i), dtype=float) for t_i in times]

    if all(isinstance(search, OneStepGA) for search in searches):
        return step_together([s for s in searches if isinstance(s, OneStepGA)], targets, times)
    return [search.step(target, t_i) for search, target, t_i in zip(searches, targets, times, strict=True)]


@dataclass(frozen=True)
class Targets:
    """The imaginary arms' configurations at one cycle.

    Attributes:
        q: ``(p, nq)`` the configurations ``q̃_i``.
        S: ``(p,)`` their AMSIP.
        ramp: ``(p,)`` factors in [0, 1] on the weights ``k_i`` (1: full pull).
        keep: velocity indices whose difference to the arm is taken without wrapping
            (:func:`~previewctl.control.nullspace.wrapped_difference`).
    """

    q: Array
    S: Array
    ramp: Array
    keep: tuple[int, ...] = ()


class ImaginaryArms:
    """One search per preview time ``t_i* = t + i t̃``, ``i = 1..p``, stepped once per camera frame.

    Args:
        robot: the arm.
        searches: one search per preview time.
        preview_time: ``t̃`` [s].
        branches: lock every search on the arm's elbow branch before each generation (planar arms), or ``None``.

    Attributes:
        frames: generations run so far.
        times: the preview times [s] of the last frame.
    """

    def __init__(self, robot: Robot, searches: Sequence[SearchLike], preview_time: float,
                 branches: PlanarRedundancy | None = None) -> None:
        self.robot, self.searches, self.preview_time, self.branches = robot, tuple(searches), preview_time, branches
        self.frames = 0
        self._best: tuple[Array, Array] | None = None
        self.times: list[float] = []

    def __len__(self) -> int:
        return len(self.searches)

    @property
    def best(self) -> tuple[Array, Array]:
        """``((p, nq), (p,))``: the searches' best candidates at the last frame, and their AMSIP.

        Raises:
            ConfigurationError: no generation has run yet (:meth:`update` runs one).
        """
        if self._best is None:
            raise ConfigurationError("the imaginary arms have run no generation yet: update() runs one")
        return self._best

    def update(self, state: ControlState) -> bool:
        """Run one generation of every search if a frame is due (or none has run yet); whether one ran.

        The first generation is seeded with the arm's configuration.
        """
        if not state.frame_due and self.frames:
            return False
        q = state.q
        if not self.frames:
            for search in self.searches:
                search.seed(np.array(q, dtype=float))
        if self.branches is not None:
            branch = int(self.branches.genes_of(np.asarray(q, dtype=float)[None])[1][0])
            for search in self.searches:
                if isinstance(search, OneStepGA):
                    search.branch_lock = branch
        self.times = [state.t + (i + 1) * self.preview_time for i in range(len(self.searches))]
        best_q, best_S = np.empty((len(self.searches), self.robot.nq)), np.empty(len(self.searches))
        for i, best in enumerate(step_searches(self.searches, state.path, self.times)):
            best_q[i], best_S[i] = np.asarray(best.q, dtype=float), float(best.S)
        self._best = (best_q, best_S)
        self.frames += 1
        return True

    def levels(self) -> list[tuple[float, Array, Array]]:
        """Each search's positive peaks at the last frame: ``(t_i [s], nodes (K, nq), S (K,))``."""
        levels = []
        for t_i, search in zip(self.times, self.searches, strict=True):
            peaks = [c for c in search.peaks() if c.S > 0]
            levels.append((t_i, np.array([c.q for c in peaks]).reshape(-1, self.robot.nq),
                           np.array([c.S for c in peaks])))
        return levels


class ArmPolicy(Protocol):
    """Which configuration each imaginary arm stands for at a cycle."""

    name: str
    arms: ImaginaryArms

    def targets(self, state: ControlState) -> Targets:
        """The imaginary arms' targets at ``state``."""
        ...


class ArgmaxArms:
    """The paper's literal rule: each frame's best candidate of each search (eqs. 20/21 as printed)."""

    name = "argmax"

    def __init__(self, arms: ImaginaryArms) -> None:
        self.arms = arms
        self._ramp = np.ones(len(arms))

    def targets(self, state: ControlState) -> Targets:
        """The last frame's best candidates."""
        self.arms.update(state)
        return Targets(*self.arms.best, ramp=self._ramp)


class TrackedPeaks:
    """One tracked peak per imaginary arm, chained from the arm (:class:`~previewctl.control.peaks.PeakTracker`).

    Each arm's target is the best individual of its search near its last target; it is kept in the population
    with ``track_neighbours`` mutants so that it climbs, and its pull is ramped in over ``settle_frames`` after a
    change of peak. On a planar arm the searches are locked on the arm's elbow branch, and the elbow joint's
    difference is never wrapped: within one branch its plain difference is the way that does not pass through the
    unreachable folded wrist (``q_n = ±π``).

    Args:
        robot: the arm.
        arms: the imaginary arms (built with ``branches`` on a planar arm).
        params: ``track_radius``, ``settle_frames``, ``track_neighbours``, ``velocity_scale``, ``preview_time``.
    """

    name = "peaks"

    def __init__(self, robot: Robot, arms: ImaginaryArms, params: ControllerParams) -> None:
        self.robot, self.arms = robot, arms
        self._trackers = [
            PeakTracker(robot.angles_of, robot.joints.full_turn,
                        track_radius=params.track_radius, settle_frames=params.settle_frames)
            for _ in arms.searches
        ]
        # [rad] how far each joint can move between two preview times: the chain of imaginary arms' reach
        self._reach = effective_velocity_limits(robot, params.velocity_scale) * params.preview_time
        self._keep = (robot.nv - 1,) if arms.branches is not None else ()
        self._neighbours = params.neighbours(planar=robot.planar is not None)
        self._ramp = np.ones(len(arms))
        self._last: tuple[Array, Array] | None = None

    def targets(self, state: ControlState) -> Targets:
        """The tracked peaks, updated when a frame ran."""
        if self.arms.update(state) or self._last is None:
            targets, values = self.arms.best[0].copy(), self.arms.best[1].copy()
            for i in range(len(self.arms)):
                self._track(i, state.q, targets, values)
            self._last = (targets, values)
        return Targets(*self._last, ramp=self._ramp, keep=self._keep)

    def _track(self, i: int, q: Array, targets: Array, values: Array) -> None:
        """Replace imaginary arm ``i``'s argmax by its tracked peak; arm ``i - 1``'s target (the arm ``q`` for
        ``i = 0``) must already be in ``targets``: it is the link before ``i`` in the chain."""
        search = self.arms.searches[i]
        if isinstance(search, OneStepGA):
            Q, S = search.population_q, search.population_S
        else:  # a stand-in search: its best and peaks
            options = [_Best(targets[i], values[i]), *search.peaks()]
            Q, S = np.array([np.asarray(c.q, dtype=float) for c in options]), np.array([float(c.S) for c in options])
        peak = self._trackers[i].update(Q, S, q if i == 0 else targets[i - 1], self._reach)
        if peak is not None:
            targets[i], values[i], self._ramp[i] = peak.q, peak.S, peak.ramp
            # keep the tracked peak in the population, with mutants of it so that it climbs
            if isinstance(search, OneStepGA):
                search.seed(peak.q, neighbours=self._neighbours)
            else:
                search.seed(peak.q)
        else:  # nothing feasible this frame: no pull from this arm (its last target is kept for the log)
            self._ramp[i] = 0.0
            if self._last is not None:
                targets[i], values[i] = self._last[0][i], self._last[1][i]


@dataclass(frozen=True)
class _Best:
    """A search's best candidate as the tracker reads it."""

    q: Array
    S: float


class RoutePoints:
    """Where the route planned toward the imaginary arms' peaks puts the arm at the preview times.

    Every camera frame the searches run a generation; their positive peaks are the planner's goals (once the
    searches have run ``settle_frames`` generations). The targets are the plan's configurations
    ``q_plan(t + i t̃)`` at every cycle (beyond the plan's end, its last configuration: the reached peak), at
    full weight from the first frame (the plans made before the searches settle are the planner's own best
    motions, so there is nothing to ramp in). Their differences to the arm are plain: the plan is unwrapped along
    its motion.

    Args:
        robot: the arm.
        arms: the imaginary arms.
        planner: the planner toward their peaks.
        settle_frames: generations before the peaks become goals.
    """

    name = "route"

    def __init__(self, robot: Robot, arms: ImaginaryArms, planner: PeakPlanner, settle_frames: int) -> None:
        self.robot, self.arms, self.planner, self.settle_frames = robot, arms, planner, settle_frames

    def targets(self, state: ControlState) -> Targets:
        """The plan's configurations at the preview times."""
        if self.arms.update(state):
            self.planner.peaks = self.arms.levels()
        self.planner.update(state, settled=self.arms.frames >= self.settle_frames)
        return plan_points(self.planner.planner, state.t, self.arms.preview_time, len(self.arms))


def plan_points(planner: WindowPlanner, t: float, preview_time: float, count: int) -> Targets:
    """The plan's configurations at the preview times ``t + i t̃``, ``i = 1..count`` [s], as targets at full weight
    whose differences to the arm are plain (the plan is unwrapped along its motion)."""
    q, S = planner.configurations(t + np.arange(1.0, count + 1.0) * preview_time)
    return Targets(q, S, ramp=np.ones(count), keep=tuple(range(planner.robot.nv)))
