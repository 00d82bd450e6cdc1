"""The dynamic programme from ``q0``: (a) the forward max-min over the layers, (c) the best motion.

``W_k`` is the best bottleneck ``min S`` over the motions from ``q0`` to each state of layer ``k``;
the best motion maximises the bottleneck, then the total S (a backward max-sum over the states with
``W_k >= S*``, then a forward read-out). Definitions in :mod:`previewctl.search.reachability`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from previewctl.search.reachability.grid import Start
from previewctl.search.reachability.layers import Layer, dilate, start_box
from previewctl.search.reachability.problem import Problem
from previewctl.search.reachability.transitions import Edges
from previewctl.types import Array, BoolArray, IntArray


@dataclass(frozen=True)
class Forward:
    """What the forward pass reached, up to its last reachable layer ``K``.

    Attributes:
        layers: ``layers[k - 1]`` is layer ``k``, ``k = 1 .. K``.
        hops: ``hops[k - 1]``: the edges from layer ``k`` to ``k + 1``, ``k = 1 .. K - 1``.
        W: ``W[k]`` ``(states of layer k,)``: the best bottleneck from ``q0`` (``-inf``: not reachable);
            ``W[0] = [inf]``, ``q0`` itself.
        start: the states of layer 1 that ``q0`` reaches in one step.
    """

    layers: list[Layer]
    hops: list[Edges]
    W: list[Array]
    start: IntArray

    @property
    def K(self) -> int:  # noqa: N802 -- the last reachable layer, as in the docstring
        return len(self.layers)

    def reachable(self) -> list[BoolArray]:
        """``[k - 1]``: the states of layer ``k`` reachable from ``q0``, ``k = 1 .. K``."""
        return [self.W[k] > -np.inf for k in range(1, self.K + 1)]


def forward(problem: Problem, start: Start, q0_distances: Array) -> Forward:
    """(a) The forward max-min from ``start`` (capsule distances ``q0_distances`` [m]); a layer is evaluated
    only where the previous one can step to, and the pass stops at the first layer it cannot reach."""
    model, M = problem.model, problem.model.M
    layers = [problem.layer(1, start_box(model, start.grid_q))]
    first = problem.first_step(start, q0_distances, layers[0])
    W: list[Array] = [np.array([np.inf]), np.full(layers[0].states, -np.inf)]
    W[1][first] = np.repeat(layers[0].S, M)[first]
    hops: list[Edges] = []
    for k in range(1, problem.N):
        reached = W[k] > -np.inf
        if not reached.any():
            break
        src = layers[k - 1]
        dst = problem.layer(k + 1, dilate(model, src, np.flatnonzero(reached.reshape(-1, M).any(axis=1))))
        step = problem.edges(src, dst, k, reached)
        layers.append(dst)
        hops.append(step)
        W.append(np.minimum(step.push_max(W[k], dst.states), np.repeat(dst.S, M)))
    K = max(k for k in range(len(W)) if np.any(W[k] > -np.inf))
    return Forward(layers=layers[:K], hops=hops[: max(K - 1, 0)], W=W[: K + 1], start=first)


def best_states(fwd: Forward, M: int, end: tuple[int, int] | None = None) -> tuple[float, list[int]]:
    """(c) ``S*`` and the best motion's states (one per layer ``1 .. K``): max min S, then max total S
    (``nan`` and no state when ``q0`` cannot make a step). With ``end = (k, state)``: the best motion to
    that state of layer ``k`` (``S*`` its bottleneck ``W_k``), one state per layer ``1 .. k``."""
    if fwd.K < 1:
        return float("nan"), []
    K, target = (fwd.K, None) if end is None else end
    s_star = float(np.max(fwd.W[K])) if target is None else float(fwd.W[K][target])
    return s_star, _read_out(fwd, _best_totals(fwd, M, s_star, K, target), K)


def _best_totals(fwd: Forward, M: int, s_star: float, K: int, target: int | None) -> list[Array]:
    """``Z[k]``: the largest ``Σ S`` from each state of layer ``k`` to ``t_K`` (to its state ``target`` when
    given) through states with ``W >= S*`` (``-inf`` elsewhere); ``Z[0]`` unused."""
    W, layers, hops = fwd.W, fwd.layers, fwd.hops
    Z: list[Array] = [np.zeros(0)] * (K + 1)
    Z[K] = np.where(W[K] >= s_star, np.repeat(layers[K - 1].S, M), -np.inf)
    if target is not None:
        Z[K][np.arange(Z[K].size) != target] = -np.inf
    for k in range(K - 1, 0, -1):
        best = hops[k - 1].pull_max(Z[k + 1], layers[k - 1].states)
        Z[k] = np.where(W[k] >= s_star, np.repeat(layers[k - 1].S, M) + best, -np.inf)
    return Z


def _read_out(fwd: Forward, Z: list[Array], K: int) -> list[int]:
    """The states of the best motion to layer ``K``: from ``q0``'s best first step, each time the best edge onward."""
    states = [int(fwd.start[int(np.argmax(Z[1][fwd.start]))])]
    for k in range(1, K):
        out = fwd.hops[k - 1].dst[fwd.hops[k - 1].src == states[-1]]
        states.append(int(out[int(np.argmax(Z[k + 1][out]))]))
    return states
