"""Scoring genes: solve them on the self-motion manifold and evaluate AMSIP (eq. 18) on the reachable ones."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.index.evaluator import POTENTIAL_ONLY, Evaluator
from previewctl.search.redundancy import RedundancyMap
from previewctl.types import Array


@dataclass(frozen=True)
class Scored:
    """Genes solved and scored.

    Attributes:
        Q: ``(B, nq)`` configurations.
        reachable: ``(B,)`` whether the hand is on the target.
        S: ``(B,)`` AMSIP; ``collision_value`` (< 0) where unreachable.
        collision: ``(B,)`` whether a reachable configuration collides, with an obstacle or with itself (False where
            unreachable).
    """

    Q: Array
    reachable: NDArray[np.bool_]
    S: Array
    collision: NDArray[np.bool_]


def score(
    evaluator: Evaluator,
    redundancy: RedundancyMap,
    genes: Array,
    branch: NDArray[np.int_],
    target: object,
    t: float = 0.0,
    q_seed: Array | None = None,
) -> Scored:
    """Solve genes for ``target`` and evaluate AMSIP at time ``t`` [s]; only reachable rows are evaluated."""
    Q, reachable = redundancy.solve(genes, branch, target, q_seed)
    return score_configurations(evaluator, Q, reachable, t)


def score_configurations(evaluator: Evaluator, Q: Array, reachable: NDArray[np.bool_], t: float = 0.0) -> Scored:
    """Score solved configurations ``(B, nq)``: AMSIP at time ``t`` [s] where reachable, else ``collision_value``."""
    S = np.full(Q.shape[0], evaluator.potential.collision_value)
    collision = np.zeros(Q.shape[0], dtype=bool)
    if reachable.any():
        ev = evaluator(Q[reachable], t, exact_below=POTENTIAL_ONLY)
        S[reachable] = ev.S
        collision[reachable] = ev.collision | ev.self_collision
    return Scored(Q, reachable, S, collision)
