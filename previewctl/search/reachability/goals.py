"""Goals: given configurations at future times (the imaginary arms' peaks), which the DP reaches from ``q0``.

A goal configuration ``q`` at time ``t_i`` is *reached* when a state of the layer nearest ``t_i`` that the
forward pass reached, and from which some motion goes on to the last layer it reached (a *viable* state:
a goal that is a dead end before the window's end is no goal), lies within one grid step ``h`` of ``q``'s
genes (modulo a full turn), on ``q``'s elbow branch (the one with the best bottleneck when several are).
The chosen goal is the best (largest score) reached one at the latest time that has any: the arm heads for
the furthest future it can be sure to get to, and to go on from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability.dp import Forward
from previewctl.search.reachability.grid import GridModel
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array, BoolArray


@dataclass(frozen=True)
class Goals:
    """Candidate configurations at one future time.

    Attributes:
        t: the time [s].
        q: ``(k, n)`` configurations [rad] (each with the hand on the path at ``t``).
        score: ``(k,)`` how much each is wanted (the imaginary arm's S, with any bonus); the best reached wins.
    """

    t: float
    q: Array
    score: Array


@dataclass(frozen=True)
class Pick:
    """The chosen goal: ``goals[level].q[index]``, reached as state ``state`` of DP layer ``layer``."""

    level: int
    index: int
    layer: int
    state: int


def pick_goal(red: PlanarRedundancy, model: GridModel, fwd: Forward, viable: list[BoolArray], times: Array,
              goals: list[Goals]) -> Pick | None:
    """The best reached goal at the latest level that has one (``None``: no goal is reached); ``viable[k - 1]``:
    the states of layer ``k`` from which a motion reaches the last layer ``fwd.K``."""
    picks: list[tuple[Pick, float]] = []  # (pick, score)
    for level, goal in enumerate(goals):
        k = int(np.argmin(np.abs(times - goal.t)))
        if k < 1 or k > fwd.K or not len(goal.q):
            continue
        for index in np.argsort(-np.asarray(goal.score)):
            state = _reached_state(red, model, fwd, viable[k - 1], k, np.asarray(goal.q[index], dtype=float))
            if state is not None:
                picks.append((Pick(level, int(index), k, state), float(goal.score[index])))
                break
    if not picks:
        return None
    return max(picks, key=lambda p: (p[0].layer, p[1]))[0]


def _reached_state(red: PlanarRedundancy, model: GridModel, fwd: Forward, viable: BoolArray, k: int,
                   q: Array) -> int | None:
    """The reached, ``viable`` state of layer ``k`` within one grid step of ``q``'s genes (angles compared modulo a
    full turn: the same physical configuration) on its elbow branch, with the best bottleneck ``W_k``."""
    layer, M, g = fwd.layers[k - 1], model.M, model.periodic.size
    W = np.where(viable, fwd.W[k], -np.inf).reshape(-1, M)
    genes, branch = red.genes_of(q[None, :])
    rows = np.flatnonzero(np.isfinite(W).any(axis=1) & (layer.branch == int(branch[0])))
    if g and rows.size:
        rows = rows[np.all(np.abs(wrap_angle(layer.genes[rows] - genes[0][None, :])) <= model.h + 1e-9, axis=1)]
    if not rows.size:
        return None
    best = np.unravel_index(int(np.argmax(W[rows])), (rows.size, M))
    return int(rows[best[0]]) * M + int(best[1])
