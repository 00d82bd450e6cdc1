"""The ``reach`` controller (Fig. 3): a route of peaks through the future that the arm can move through."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from previewctl.control.base import ControlInfo, ControlState
from previewctl.control.gradient import GradientController
from previewctl.control.oracle import OracleController
from previewctl.control.params import ControllerParams
from previewctl.control.preview import SearchLike, preview_pull, step_searches, wrapped_difference
from previewctl.control.tracking import effective_velocity_limits, gain_vector, track
from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.search.genes import joint_distance
from previewctl.search.reachability.goals import Goals
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array


@dataclass(frozen=True)
class Route:
    """The chosen sequence of peaks of :class:`ReachController`, one per preview time.

    Attributes:
        nodes: ``(len, nq)`` configurations, level 1 first.
        S: ``(len,)`` their AMSIP values.
        complete: whether it reaches the last preview time (otherwise the longest feasible prefix).
        lead: ``(nq,)`` the planned configuration one sweep step ahead on the move to ``nodes[0]``.
    """

    nodes: Array
    S: Array
    complete: bool
    lead: Array


class ReachController:
    """``reach``: the reachability sequence of the paper's Fig. 3; with ``blend``, coherent ``multi``: eq. 21 on it.

    At each camera frame every imaginary arm ``i`` (at ``t_i* = t + i t̃``) runs one GA generation;
    its top-K distinct peaks with ``S > 0`` are the nodes of level ``i`` (a negative future node is
    dropped, and every route through it with it). The current configuration is level 0. An edge
    from node ``a`` (level ``i-1``, time ``t_a``) to node ``b`` (level ``i``, time ``t_a + t̃``) is
    *feasible* when the arm can move from one to the other while its hand follows the path:

    1. ``sweep_samples`` intermediate times ``tau`` split the move; at each, the genes are
       interpolated between ``a``'s and ``b``'s (angles the short way round) and solved onto the
       hand target ``r_d(tau)`` by the redundancy map; the elbow branch switches from ``a``'s to
       ``b``'s at the middle sample (a switch is only continuous through a stretched elbow, so a
       switch elsewhere fails the speed test below);
    2. every such configuration is reachable and collision-free (``S >= 0``) with the scene at
       ``tau``;
    3. consecutive configurations differ by at most ``v_max_j (tau_k+1 - tau_k) velocity_scale``
       per joint (the joint speed limits).

    The route (one node per level) with the best total S over feasible edges is found by dynamic
    programming (Viterbi); if no route reaches the last level, the one reaching furthest is taken.
    The arm then follows the planned move toward the route's first node: ``v = (q_lead ⊖ q) / dtau``,
    ``q_lead`` being the move's first sample (``dtau = t̃ / (sweep_samples + 1)`` ahead), re-planned
    at every frame (receding horizon). If not even level 1 is reachable, eq. 21 on the imaginary
    arms' best candidates is used, as in ``multi``.

    Unlike plain eq. 21, whose targets are each time's own best (possibly on different, mutually
    unreachable peaks) and whose null-space pull toward a configuration on the other elbow branch
    does not lead through the stretched elbow, the arm here follows a move that was checked to be
    on the path, collision-free and within the speed limits.

    **Coherent mode on planar arms of up to 4 joints** (the default there): the moves are planned by the
    reachability DP over the preview window instead of straight sweeps, so a route may bend around an
    obstacle or through the stretched wrist. Every ``replan_period`` (default ``t̃ / 2``) the DP of
    :class:`~previewctl.control.oracle.OracleController` (``horizon``'s grid) runs from ``q`` over
    ``[t, t + plan_window]`` (default ``p t̃``) with the imaginary arms' positive peaks as goals
    (:mod:`~previewctl.search.reachability.goals`): the goal is the best peak that some collision-free motion
    reaches, and can go on from to the window's end, at the latest preview time that has one (a peak near the
    last goal gets the ``hysteresis`` bonus), and the arm follows the DP's best motion to it as ``horizon``
    follows its plan (from ``plan_latency`` after the plan was made, if set). With no peak reached, it
    follows the DP's best motion over the window (``horizon``'s plan); so do the plans made before the searches
    have run ``settle_frames`` generations (their peaks are not worth heading for yet). The GA runs one generation per
    camera frame; only the plans are periodic.

    **Coherent mode on spatial arms**: the same, with the sampled forward search of
    :mod:`previewctl.search.roadmap` in place of the DP (``horizon``'s search on a spatial arm); a peak is reached
    when a node of the search comes within ``goal_radius`` of it. On the held-out Panda bench scenes (scene seeds 1
    and 2, 40 scenes, QP execution, 6 s window) this took ``reach`` from 34 to 37 of 40 at 1 mm. The straight
    sweeps remain the routes of the paper-literal mode (``coherent = false``).

    **Coherent ``multi``** (``blend=True``, where the moves are planned: :meth:`plans`) runs the same plans and does
    not follow them: its imaginary arms are where the plan puts the arm at the preview times, ``q_plan(t + i t̃)``
    (beyond the plan's end, its last configuration, the reached peak), and eq. 21 pulls the arm toward them:
    ``v = K_v Σ k_i (q_plan(t + i t̃) ⊖ q)``, at full weight from the first frame (the plans made before the GA
    settles are the DP's own best motions, so there is nothing to ramp in; with the ramp, the arm fell behind the
    first plans and the replans from there led elsewhere). This is the paper's
    multi-preview control as its Fig. 3 describes it (the sequence of future configurations is chosen by its
    reachability, then eq. 21 controls the arm toward it). Eq. 21 on the tracked peaks alone
    (:class:`~previewctl.control.preview.PreviewController`, :mod:`~previewctl.control.peaks`) never changes basin:
    on 30 held-out planar bench scenes (scene seed 6, QP, 1 mm) it finished 24, the blended route 29 (``reach``
    29).
    """

    def __init__(
        self,
        robot: Robot,
        params: ControllerParams,
        evaluator: Evaluator,
        searches: Sequence[SearchLike],
        redundancy: Any,
        *,
        sweep_samples: int = 6,
        blend: bool = False,
    ) -> None:
        self.robot, self.params, self.evaluator, self.redundancy = robot, params, evaluator, redundancy
        self.name = "multi" if blend else "reach"
        self.weights = np.array(params.preview_weights("multi"))
        if len(searches) != len(self.weights):
            raise ConfigurationError(
                f"{self.name} needs {len(self.weights)} searches (one per preview time), got {len(searches)}"
            )
        self.searches = tuple(searches)
        self.sweep_samples = sweep_samples
        self._gain = gain_vector(params.gain, robot.nv, "gain")
        self._speed = effective_velocity_limits(robot, params.velocity_scale)
        self._sweep_step = params.preview_time / (sweep_samples + 1)
        self._route: Route | None = None
        self._fallback: tuple[Array, Array] | None = None
        self._frames = 0
        coherent = params.coherent and robot.planar is not None
        # coherent: the planar elbow joint's steps are never wrapped (an elbow change goes through the
        # stretched wrist), and a node near the last route's node of its level keeps its identity unless
        # another route beats it by the hysteresis margin
        self._keep = (robot.nv - 1,) if coherent else ()
        # coherent, planar arms of up to 2 genes: the moves are planned by the reachability DP over the window;
        # coherent, spatial arms: by the sampled search
        self._planner = OracleController.horizon(robot, params, evaluator) if self.plans(robot, params) else None
        if blend and self._planner is None:
            raise ConfigurationError("ReachController(blend=True) needs coherent mode on an arm whose moves are "
                                     "planned (see ReachController.plans)")
        self._local = GradientController(robot, evaluator, params) if blend and params.with_gradient else None
        self._peaks: list[tuple[float, Array, Array]] = []  # the last frame's (t_i [s], peaks, their S) per level
        self._goal: tuple[int, Array, float] | None = None  # (level, configuration, S) of the last planned goal

    @staticmethod
    def plans(robot: Robot, params: ControllerParams) -> bool:
        """Whether the moves are planned over a window (coherent mode on a spatial arm, or a planar arm of up to 4
        joints, whose genes the reachability DP's grid holds) rather than taken as straight sweeps."""
        return params.coherent and (robot.planar is None or robot.nq <= 4)

    @property
    def route(self) -> Route | None:
        """The straight-sweep route chosen at the last frame (``None`` before the first, when none was feasible,
        or when the DP plans the moves)."""
        return self._route

    @property
    def planner(self) -> OracleController | None:
        """The reachability DP that plans the moves (coherent mode on planar arms of up to 4 joints), or ``None``."""
        return self._planner

    @property
    def goal(self) -> tuple[int, Array, float] | None:
        """``(level, configuration, S)`` of the peak the DP's last plan heads for (``None``: no plan yet, or no
        peak reached: the plan is then the DP's best motion over the window)."""
        return self._goal

    def _edges(self, starts: Array, ends: Array, t0: float, path: HandPath) -> tuple[NDArray[np.bool_], Array]:
        """Feasibility ``(len(starts), len(ends))`` of the moves between two levels starting at ``t0`` [s],
        and each move's first sample ``(len(starts), len(ends), nq)`` (its configuration at ``t0 + dtau``)."""
        red = self.redundancy
        genes_a, branch_a = red.genes_of(starts)
        genes_b, branch_b = red.genes_of(ends)
        delta = genes_b[None, :, :] - genes_a[:, None, :]
        delta = np.where(red.periodic, wrap_angle(delta), delta)
        feasible = np.ones(delta.shape[:2], bool)
        pairs = np.argwhere(feasible)
        dtau = self.params.preview_time / (self.sweep_samples + 1)
        previous = starts[pairs[:, 0]]
        ok = np.ones(len(pairs), bool)
        first = np.empty((len(starts), len(ends), starts.shape[1]))
        for k in range(1, self.sweep_samples + 2):
            tau = t0 + k * dtau
            genes = genes_a[pairs[:, 0]] + (k / (self.sweep_samples + 1)) * delta[pairs[:, 0], pairs[:, 1]]
            if k == self.sweep_samples + 1:
                Q, reachable = ends[pairs[:, 1]], np.ones(len(pairs), bool)
            else:
                branch = branch_a[pairs[:, 0]] if 2 * k <= self.sweep_samples + 1 else branch_b[pairs[:, 1]]
                Q, reachable = red.solve(genes, branch, np.asarray(path.position(tau), float))
                ok &= reachable & (self.evaluator(Q, tau).S >= 0.0)
            steps = np.array(
                [wrapped_difference(self.robot, a, b, keep=self._keep) for a, b in zip(previous, Q, strict=True)]
            )
            ok &= np.all(np.abs(steps) <= self._speed * dtau, axis=1)
            if k == 1:
                first[pairs[:, 0], pairs[:, 1]] = Q
            previous = Q
        feasible[pairs[~ok, 0], pairs[~ok, 1]] = False
        return feasible, first

    def _choose(self, t: float, q: Array, levels: list[tuple[Array, Array]], path: HandPath) -> Route | None:
        """Viterbi over the levels: the feasible route with the best total S (or the longest prefix)."""
        total = np.zeros(1)
        nodes_prev = q[None, :]
        back: list[NDArray[np.int_]] = []
        reached: list[Array] = []
        for i, (nodes, values) in enumerate(levels):
            if not len(nodes):
                break
            feasible, first = self._edges(nodes_prev, nodes, t + i * self.params.preview_time, path)
            if i == 0:
                leads = first[0]
            values = values * (1.0 + self.params.hysteresis * self._continues(i, nodes))
            score = np.where(feasible, total[:, None] + values[None, :], -np.inf)
            best_prev = score.argmax(axis=0)
            best = score.max(axis=0)
            if not np.isfinite(best).any():
                break
            back.append(best_prev)
            reached.append(best)
            total, nodes_prev = best, nodes
        if not back:
            return None
        last = int(np.argmax(reached[-1]))
        chain = [last]
        for pointers in reversed(back[1:]):
            chain.append(int(pointers[chain[-1]]))
        chain.reverse()
        nodes = np.stack([levels[i][0][k] for i, k in enumerate(chain)])
        S = np.array([levels[i][1][k] for i, k in enumerate(chain)])
        return Route(nodes, S, complete=len(chain) == len(levels), lead=leads[chain[0]])

    def _continues(self, level: int, nodes: Array) -> NDArray[np.bool_]:
        """Which ``nodes`` of ``level`` continue the last route's node there (coherent mode only)."""
        route = self._route
        keeps = self.params.coherent and route is not None and level < len(route.nodes)
        return self._near(route.nodes[level] if keeps and route is not None else None, nodes)

    def _near(self, reference: Array | None, nodes: Array) -> NDArray[np.bool_]:
        """Which ``nodes`` lie within ``track_radius`` of ``reference`` (none without a reference)."""
        if reference is None or not len(nodes):
            return np.zeros(len(nodes), dtype=bool)
        angles = self.robot.angles_of(np.vstack([reference[None], nodes]))
        distance = joint_distance(angles[1:], angles[:1], self.robot.joints.full_turn)[:, 0]
        return np.asarray(distance <= self.params.track_radius)

    def _update(self, t: float, q: Array, path: HandPath) -> tuple[Array, Array]:
        if self._fallback is None:
            for search in self.searches:
                search.seed(np.array(q, dtype=float))
        levels: list[tuple[Array, Array]] = []
        best_q, best_S = np.empty((len(self.searches), self.robot.nq)), np.empty(len(self.searches))
        times = [t + (i + 1) * self.params.preview_time for i in range(len(self.searches))]
        for i, (search, best) in enumerate(zip(self.searches, step_searches(self.searches, path, times), strict=True)):
            best_q[i], best_S[i] = np.asarray(best.q, dtype=float), float(best.S)
            peaks = [c for c in search.peaks() if c.S > 0]
            levels.append((np.array([c.q for c in peaks]).reshape(-1, self.robot.nq), np.array([c.S for c in peaks])))
        self._fallback = (best_q, best_S)
        if self._planner is None:
            self._route = self._choose(t, q, levels, path)
        else:
            self._peaks = [(t_i, nodes, values) for t_i, (nodes, values) in zip(times, levels, strict=True)]
        return self._fallback

    def _goals(self) -> list[Goals]:
        """The last frame's peaks as the DP's goals, those near the last planned goal with the hysteresis bonus."""
        goal = self._goal
        return [Goals(t_i, nodes, values * (1.0 + self.params.hysteresis
                                            * self._near(goal[1] if goal and goal[0] == i else None, nodes)))
                for i, (t_i, nodes, values) in enumerate(self._peaks)]

    def _planned(self, t: float, q: Array, state: ControlState, targets: Array,
                 values: Array) -> tuple[Array, ControlInfo]:
        """Follow the DP's move toward the best reached peak (replanned every ``replan_period``)."""
        planner = self._planner
        assert planner is not None
        if planner.motion is None or planner.due(t):
            settled = self._frames >= self.params.settle_frames  # before: the peaks are not worth heading for
            planner.plan(t, q, state, goals=self._goals() if settled else ())
            pick = planner.goal
            if pick is None:
                self._goal = None
            else:
                _, nodes, peak_S = self._peaks[pick[0]]
                self._goal = (pick[0], nodes[pick[1]], float(peak_S[pick[1]]))
        if self.name == "multi":
            return self._blended(t, q, state, planner)
        targets, values = targets.copy(), values.copy()
        if self._goal is not None:
            level, goal, S = self._goal
            targets[level], values[level] = goal, S
        return planner.follow(t, q, state, targets, values)

    def _blended(self, t: float, q: Array, state: ControlState, planner: OracleController) -> tuple[Array, ControlInfo]:
        """``multi``: eq. 21 with the imaginary arms where the plan puts the arm at the preview times,
        ``v = K_v Σ k_i (q_plan(t + i t̃) ⊖ q)`` (beyond its end the plan holds its last configuration: the reached
        peak), plus the local term with ``with_gradient``."""
        planner.arrive(t)
        points = [planner.point(t + (i + 1) * self.params.preview_time) for i in range(len(self.weights))]
        arms = np.array([arm for arm, _, _ in points])
        pull = preview_pull(self.robot, q, arms, self.weights, keep=tuple(range(self.robot.nv)))
        v = self._gain * pull
        if self._local is not None:
            v = v + self._local.null_space_input(q, t)
        return track(self.robot, t, q, state, v, self.params, arms, np.array([S for _, _, S in points]))

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]."""
        if state.frame_due or self._fallback is None:
            targets, values = self._update(t, q, state.path)
            self._frames += 1
        else:
            targets, values = self._fallback
        if self._planner is not None:
            return self._planned(t, q, state, targets, values)
        if self._route is not None:
            n = len(self._route.nodes)
            targets, values = targets.copy(), values.copy()
            targets[:n], values[:n] = self._route.nodes, self._route.S
            v = wrapped_difference(self.robot, q, self._route.lead, keep=self._keep) / self._sweep_step
        else:
            v = self._gain * preview_pull(self.robot, q, targets, self.weights, keep=self._keep)
        if self.params.coherent:  # ramp in while the searches settle
            v = v * min(1.0, self._frames / self.params.settle_frames)
        return track(self.robot, t, q, state, v, self.params, targets.copy(), values.copy())
