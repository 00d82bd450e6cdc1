"""From grid states to joint values: the best motion as a :class:`~previewctl.search.reachability.result.ReachMotion`.

A state fixes a cell and a representative of ``q_(n-1)``; its joint values follow: bounded genes take
their axis values, ``q_(n-1)`` its representative ``a + 2π m``, ``q_n = β + c``; the joints without
finite limits are unwrapped along the motion (each sample the short way from the previous one).
"""

from __future__ import annotations

import numpy as np

from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.search.reachability.grid import GridModel, Start
from previewctl.search.reachability.layers import Layer
from previewctl.search.reachability.result import ReachMotion
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array


def motion_through(model: GridModel, layers: list[Layer], times: Array, start: Start, q0_S: float,
                   states: list[int]) -> ReachMotion:
    """The motion from ``start`` (of AMSIP ``q0_S``) through ``states``, one per layer ``1 .. K``
    (``layers[k - 1]`` is layer ``k``)."""
    K = len(states)
    q = np.empty((K + 1, start.q.size))
    q[0] = start.q
    S = np.empty(K + 1)
    S[0] = q0_S
    branch = np.empty(K + 1, dtype=np.int64)
    branch[0] = start.branch
    cells = np.full(K + 1, -1, dtype=np.int64)
    for k, state in enumerate(states, start=1):
        layer = layers[k - 1]
        row, m = divmod(state, model.M)
        q[k] = _joint_values(model, layer, row, m, q[k - 1])
        S[k] = layer.S[row]
        branch[k] = layer.branch[row]
        cells[k] = layer.cells[row]
    return ReachMotion(times=times[: K + 1].copy(), q=q, S=S, branch=branch, cells=cells,
                       min_S=float(S[1:].min()) if K else float("nan"),
                       total_S=float(S[1:].sum()) if K else 0.0)


def _joint_values(model: GridModel, layer: Layer, row: int, m: int, previous: Array) -> Array:
    """The joint values ``(n,)`` [rad] of representative ``m`` of ``layer``'s cell ``row``, the periodic
    joints unwrapped from ``previous``."""
    g = model.periodic.size
    q = np.empty(previous.size)
    genes = layer.genes[row]
    for a in range(g):
        q[a] = previous[a] + float(wrap_angle(genes[a] - previous[a])) if model.periodic[a] else genes[a]
    if model.q1_periodic:
        q[g] = previous[g] + float(wrap_angle(layer.q1[row] - previous[g]))
    else:
        q[g] = layer.q1[row] + TWO_PI * model.reps[m]
    q[g + 1] = layer.beta[row] + model.elbow_offset
    return q
