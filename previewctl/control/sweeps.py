"""Straight sweeps between the imaginary arms' peaks: ``reach``'s routes where no window planner plans its moves.

The nodes of level ``i`` are imaginary arm ``i``'s positive peaks (at ``t + i t̃``); level 0 is the arm. An edge from
node ``a`` (level ``i-1``, time ``t_a``) to node ``b`` (level ``i``, time ``t_a + t̃``) is *feasible* when the arm can
move from one to the other while its hand follows the path:

1. ``sweep_samples`` intermediate times ``tau`` split the move; at each, the genes are interpolated between ``a``'s
   and ``b``'s (angles the short way round) and solved onto the hand target ``r_d(tau)`` by the redundancy map; the
   elbow branch switches from ``a``'s to ``b``'s at the middle sample (a switch is only continuous through a
   stretched elbow, so a switch elsewhere fails the speed test below);
2. every such configuration is reachable and collision-free (``S >= 0``) with the scene at ``tau``;
3. consecutive configurations differ by at most ``v_max_j (tau_k+1 - tau_k) velocity_scale`` per joint.

The route (one node per level) with the best total S over feasible edges is found by dynamic programming (Viterbi);
if no route reaches the last level, the one reaching furthest is taken. In coherent mode a node near the last
route's node of its level keeps its identity unless another route beats it by the ``hysteresis`` margin.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from previewctl.control.nullspace import wrapped_difference
from previewctl.control.params import ControllerParams
from previewctl.control.peaks import near
from previewctl.control.tracking import effective_velocity_limits
from previewctl.index.evaluator import POTENTIAL_ONLY, Evaluator
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array


@dataclass(frozen=True)
class Route:
    """The chosen sequence of peaks of :class:`SweepRoutes`, one per preview time.

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


class SweepRoutes:
    """Chooses a route of peaks through the preview times whose straight sweeps the arm can move through.

    Args:
        robot: the arm.
        params: ``preview_time``, ``velocity_scale``, ``hysteresis``, ``track_radius``, ``coherent``.
        evaluator: the AMSIP evaluator (the sweeps' collision test).
        redundancy: the arm's redundancy map (genes, branches, ``solve``).
        keep: velocity indices whose steps are never wrapped (the planar elbow in coherent mode: an elbow change
            goes through the stretched wrist).
        sweep_samples: intermediate samples of each move.

    Attributes:
        route: the route chosen last (``None`` before the first, or when none was feasible).
    """

    def __init__(self, robot: Robot, params: ControllerParams, evaluator: Evaluator, redundancy: Any, *,
                 keep: tuple[int, ...], sweep_samples: int = 6) -> None:
        self.robot, self.params, self.evaluator, self.redundancy = robot, params, evaluator, redundancy
        self.sweep_samples, self._keep = sweep_samples, keep
        self._speed = effective_velocity_limits(robot, params.velocity_scale)
        self.step = params.preview_time / (sweep_samples + 1)
        """[s] the time between two samples of a move: the lead is this far ahead."""
        self.route: Route | None = None

    def edges(self, starts: Array, ends: Array, t0: float, path: HandPath) -> tuple[NDArray[np.bool_], Array]:
        """Feasibility ``(len(starts), len(ends))`` of the moves between two levels starting at ``t0`` [s],
        and each move's first sample ``(len(starts), len(ends), nq)`` (its configuration at ``t0 + dtau``)."""
        red = self.redundancy
        genes_a, branch_a = red.genes_of(starts)
        genes_b, branch_b = red.genes_of(ends)
        delta = genes_b[None, :, :] - genes_a[:, None, :]
        delta = np.where(red.periodic, wrap_angle(delta), delta)
        feasible = np.ones(delta.shape[:2], bool)
        pairs = np.argwhere(feasible)
        dtau = self.step
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
                ok &= reachable & (self.evaluator(Q, tau, exact_below=POTENTIAL_ONLY).S >= 0.0)
            steps = np.array(
                [wrapped_difference(self.robot, a, b, keep=self._keep) for a, b in zip(previous, Q, strict=True)]
            )
            ok &= np.all(np.abs(steps) <= self._speed * dtau, axis=1)
            if k == 1:
                first[pairs[:, 0], pairs[:, 1]] = Q
            previous = Q
        feasible[pairs[~ok, 0], pairs[~ok, 1]] = False
        return feasible, first

    def choose(self, q: Array, t: float, levels: list[tuple[Array, Array]], path: HandPath) -> Route | None:
        """Viterbi over the levels: the feasible route with the best total S (or the longest prefix)."""
        total = np.zeros(1)
        nodes_prev = q[None, :]
        back: list[NDArray[np.int_]] = []
        reached: list[Array] = []
        for i, (nodes, values) in enumerate(levels):
            if not len(nodes):
                break
            feasible, first = self.edges(nodes_prev, nodes, t + i * self.params.preview_time, path)
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
            self.route = None
            return None
        last = int(np.argmax(reached[-1]))
        chain = [last]
        for pointers in reversed(back[1:]):
            chain.append(int(pointers[chain[-1]]))
        chain.reverse()
        nodes = np.stack([levels[i][0][k] for i, k in enumerate(chain)])
        S = np.array([levels[i][1][k] for i, k in enumerate(chain)])
        self.route = Route(nodes, S, complete=len(chain) == len(levels), lead=leads[chain[0]])
        return self.route

    def _continues(self, level: int, nodes: Array) -> NDArray[np.bool_]:
        """Which ``nodes`` of ``level`` continue the last route's node there (coherent mode only)."""
        route = self.route
        keeps = self.params.coherent and route is not None and level < len(route.nodes)
        reference = route.nodes[level] if keeps and route is not None else None
        return near(self.robot, reference, nodes, self.params.track_radius)
