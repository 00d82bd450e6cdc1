"""Single- and multi-preview control (eqs. 20-21): the arm is pulled toward imaginary arms' optima at future times."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np
import pinocchio as pin

from previewctl.control.base import ControlInfo, ControlState
from previewctl.control.gradient import GradientController
from previewctl.control.params import ControllerParams
from previewctl.control.peaks import PeakTracker
from previewctl.control.tracking import effective_velocity_limits, gain_vector, track
from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.robot.joints import FULL_TURN
from previewctl.robot.model import Robot
from previewctl.search.ga import OneStepGA, step_together
from previewctl.search.planar import PlanarRedundancy
from previewctl.types import Array


@runtime_checkable
class SearchLike(Protocol):
    """The interface of :class:`previewctl.search.ga.OneStepGA` that the preview controller uses."""

    def step(self, target: Array, t: float) -> Any:
        """Run one generation against hand target ``target`` at time ``t`` [s]; return the best candidate."""
        ...

    def peaks(self) -> tuple[Any, ...]:
        """The distinct peaks currently held."""
        ...

    def seed(self, q: Array) -> None:
        """Put configuration ``q`` into the population."""
        ...


def step_searches(searches: Sequence[SearchLike], path: HandPath, times: Sequence[float]) -> list[Any]:
    """One generation of ``searches[i]`` toward the hand target ``path.position(times[i])`` at
    ``times[i]`` [s]; their best candidates. 1-step GAs run through
    :func:`previewctl.search.ga.step_together` (same result, one shared Newton projection)."""
    targets = [np.asarray(path.position(t_i), dtype=float) for t_i in times]

    if all(isinstance(search, OneStepGA) for search in searches):
        return step_together([s for s in searches if isinstance(s, OneStepGA)], targets, times)
    return [search.step(target, t_i) for search, target, t_i in zip(searches, targets, times, strict=True)]


def wrapped_difference(robot: Robot, q: Array, target: Array, *, keep: tuple[int, ...] = ()) -> Array:
    """``target ⊖ q`` ``(nv,)`` [rad or m], the full-turn angles wrapped into [−π, π), except the
    velocity indices in ``keep`` (their plain difference is kept).

    Continuous joints need no wrapping: ``pin.difference`` already returns their angle.
    """
    diff = np.asarray(pin.difference(robot.model, q, target), dtype=np.float64)
    wrap = robot.joints.full_turn & ~robot.joints.continuous
    wrap[list(keep)] = False
    return np.where(wrap, (diff + np.pi) % FULL_TURN - np.pi, diff)


def preview_pull(robot: Robot, q: Array, targets: Array, weights: Array, *, keep: tuple[int, ...] = ()) -> Array:
    """``Σ_i k_i (q̃_i ⊖ q)`` ``(nv,)`` [rad]: the blend of eq. 21 (eq. 20 with one target), each difference as
    :func:`wrapped_difference` takes it (``keep`` every index: plain differences, for targets unwrapped along a
    plan)."""
    pull = np.zeros(robot.nv)
    for k, target in zip(weights, targets, strict=True):
        pull += k * wrapped_difference(robot, q, target, keep=keep)
    return pull


class PreviewController:
    """``single`` (eq. 20) and ``multi`` (eq. 21) preview control on the imaginary arms' own optima: ``single``
    always; ``multi`` in the paper-literal mode, with ``imaginary_arms = "peaks"``, and on planar arms of more than 4
    joints (otherwise coherent ``multi`` blends the configurations of a planned route:
    :class:`~previewctl.control.reach.ReachController`).

    One search (an imaginary arm) per preview time ``t_i* = t + i t̃``, ``i = 1..p``. When a camera
    frame is due (and at the first call), each search runs one generation against the hand target
    ``r_d(t_i*)`` and the scene at ``t_i*``. The target ``q̃_i`` is its tracked peak, ramped in
    (coherent mode, the default: :mod:`previewctl.control.peaks`), or its best candidate
    (``coherent=False``, the paper's literal rule). Between frames the last targets are kept. Then
    ``v = K_v Σ k_i r_i (q̃_i ⊖ q)`` drives eq. 19 (``r_i`` the ramp, 1 in the literal mode).

    Args:
        robot: the arm.
        params: gains and weights.
        mode: ``"single"`` or ``"multi"`` (``"reach"`` is :class:`ReachController`).
        searches: one search per preview time (``p = 1`` for single, ``len(weights)`` for multi),
            each with ``step(target, t)``, ``peaks()`` and ``seed(q)``.
        evaluator: the AMSIP evaluator of the local term (needed with ``params.with_gradient``).

    Raises:
        ConfigurationError: wrong number of searches, unknown mode, ``with_gradient`` without evaluator.
    """

    def __init__(
        self,
        robot: Robot,
        params: ControllerParams,
        mode: str,
        searches: Sequence[SearchLike],
        evaluator: Evaluator | None = None,
    ) -> None:
        if mode not in ("single", "multi"):
            raise ConfigurationError(f"unknown preview mode {mode!r}; valid: single, multi, reach")
        self.name = mode
        self.robot, self.params, self.mode = robot, params, mode
        self.weights = np.array(params.preview_weights(mode))
        if len(searches) != len(self.weights):
            raise ConfigurationError(
                f"{mode} preview control needs {len(self.weights)} searches (one per preview time), got {len(searches)}"
            )
        self.searches = tuple(searches)
        self._gain = gain_vector(params.gain, robot.nv, "gain")
        self._local: GradientController | None = None
        if params.with_gradient:
            if evaluator is None:
                raise ConfigurationError("with_gradient needs the AMSIP evaluator: pass evaluator=")
            self._local = GradientController(robot, evaluator, params)
        self._targets: Array | None = None
        self._target_amsip: Array | None = None
        self._ramp = np.ones(len(self.searches))
        self._coherent = params.coherent
        self._trackers = [
            PeakTracker(
                robot.angles_of, robot.joints.full_turn,
                track_radius=params.track_radius, settle_frames=params.settle_frames,
            )
            for _ in self.searches
        ]
        # [rad] how far each joint can move between two preview times: the chain of imaginary arms' reach
        self._reach = effective_velocity_limits(robot, params.velocity_scale) * params.preview_time
        self._branches = PlanarRedundancy(robot) if params.coherent and robot.planar is not None else None
        # The planar elbow joint is never wrapped: within one branch its plain difference is the way that
        # does not pass through the unreachable folded wrist (q_n = ±π).
        self._keep = (robot.nv - 1,) if self._branches is not None else ()
        self._neighbours = params.neighbours(planar=robot.planar is not None)

    @property
    def preview_times(self) -> Array:
        """Offsets ``i t̃`` [s] of the preview times, ``(p,)``."""
        return np.asarray(self.params.preview_time * np.arange(1, len(self.weights) + 1), dtype=np.float64)

    def _update_targets(self, t: float, q: Array, path: HandPath) -> tuple[Array, Array]:
        if self._targets is None:
            for search in self.searches:
                search.seed(np.array(q, dtype=float))
        if self._branches is not None:
            branch = int(self._branches.genes_of(np.asarray(q, dtype=float)[None])[1][0])
            for search in self.searches:
                if isinstance(search, OneStepGA):
                    search.branch_lock = branch
        targets, values = np.empty((len(self.searches), self.robot.nq)), np.empty(len(self.searches))
        times = [t + float(offset) for offset in self.preview_times]
        for i, best in enumerate(step_searches(self.searches, path, times)):
            targets[i], values[i] = np.asarray(best.q, dtype=float), float(best.S)
            if self._coherent:
                self._track(i, best, q, targets, values)
        self._targets, self._target_amsip = targets, values
        return targets, values

    def _track(self, i: int, best: Any, q: Array, targets: Array, values: Array) -> None:
        """Replace imaginary arm ``i``'s argmax by its tracked peak (coherent mode); arm ``i - 1``'s target (the
        arm ``q`` for ``i = 0``) must already be in ``targets``: it is the link before ``i`` in the chain."""
        search = self.searches[i]
        if isinstance(search, OneStepGA):
            Q, S = search.population_q, search.population_S
        else:  # a stand-in search: its best and peaks
            options = [best, *search.peaks()]
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
            if self._targets is not None and self._target_amsip is not None:
                targets[i], values[i] = self._targets[i], self._target_amsip[i]

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]."""
        if state.frame_due or self._targets is None or self._target_amsip is None:
            targets, values = self._update_targets(t, q, state.path)
        else:
            targets, values = self._targets, self._target_amsip
        v = self._gain * preview_pull(self.robot, q, targets, self.weights * self._ramp, keep=self._keep)
        if self._local is not None:
            v = v + self._local.null_space_input(q, t)
        return track(self.robot, t, q, state, v, self.params, targets.copy(), values.copy())


SearchFactory = Callable[[int, np.random.Generator], SearchLike]
