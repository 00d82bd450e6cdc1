"""The figures' view: S maps over ``[0, 2π)`` per gene, like the paper's Fig. 8, and states folded onto them.

The DP's gene axes run over the joint limits (planar4: ``[-360°, 360°]``) and its states carry a
representative of ``q_(n-1)``; the figures show one cell per angle modulo 2π, so a cell of the figures is
set when some state of the DP at that angle is.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.search.reachability.grid import GridModel
from previewctl.search.reachability.layers import Layer, solve_whole_grid
from previewctl.search.reachability.problem import Problem
from previewctl.types import Array, BoolArray, IntArray


def map_axes(g: int, h: float) -> tuple[Array, ...]:
    """The figures' axes: ``[0, 2π)`` per gene, like the paper's maps."""
    count = max(1, round(TWO_PI / h))
    return tuple(np.arange(count, dtype=np.float64) * (TWO_PI / count) for _ in range(g))


def map_shape(axes: tuple[Array, ...]) -> tuple[int, ...]:
    """The figures' grid shape ``(2, n_1, ..., n_g)``: both branches over ``axes``."""
    return (2, *(len(a) for a in axes))


def map_layers(problem: Problem, count: int) -> tuple[int, ...]:
    """The layers whose whole S map the figures keep: ``count`` of them spread over the times, or every
    layer when the whole grid is evaluated anyway (arms with fewer than two genes)."""
    N = problem.N
    if not problem.lazy:
        return tuple(range(N + 1))
    if count <= 0:
        return ()
    return tuple(sorted({round(float(k)) for k in np.linspace(0, N, min(count, N + 1))}))


def s_maps(problem: Problem, axes: tuple[Array, ...], layers: tuple[int, ...]) -> NDArray[np.float32]:
    """S ``(len(layers), 2, n_1, ..., n_g)`` on the figures' grid at those layers (``collision_value``
    where unreachable)."""
    maps = [_whole_map(problem, axes, k) for k in layers]
    stacked = np.stack(maps) if maps else np.zeros(0, np.float32)
    return stacked.reshape((len(layers), *map_shape(axes))).astype(np.float32)


def _whole_map(problem: Problem, axes: tuple[Array, ...], k: int) -> NDArray[np.float32]:
    """S ``(2 C_f,)`` on the figures' grid at layer ``k``."""
    t = problem.times[k]
    Q, reach = solve_whole_grid(problem.red, axes, np.asarray(problem.path.position(t), float))
    S = np.full(Q.shape[0], problem.evaluator.potential.collision_value)
    if reach.any():
        S[reach] = problem.evaluator(Q[reach], float(t)).S
    return S.astype(np.float32)


def fold_states(model: GridModel, axes: tuple[Array, ...], layers: list[Layer], masks: list[BoolArray],
                n_layers: int) -> BoolArray:
    """``(n_layers, 2, n_1, ..., n_g)`` over the figures' ``axes``: the cells some state of which is in
    ``masks[k - 1]`` (over the states of ``layers[k - 1]``, layer ``k``); layer 0 and the layers past
    ``len(layers)`` are empty."""
    fold = _fold_index(model, axes)
    shape = map_shape(axes)
    C_f = int(np.prod(shape[1:]))
    out = np.zeros((n_layers, int(np.prod(shape))), dtype=bool)
    for k, (layer, mask) in enumerate(zip(layers, masks, strict=True), start=1):
        rows = np.flatnonzero(mask.reshape(-1, model.M).any(axis=1))
        cells = layer.cells[rows]
        out[k, (cells // model.cells) * C_f + fold[cells % model.cells]] = True
    return out.reshape((n_layers, *shape))


def _fold_index(model: GridModel, axes: tuple[Array, ...]) -> IntArray:
    """For each flat gene index of the DP grid, the flat index of the figures' cell (over ``axes``) holding
    its angle."""
    if not model.axes:
        return np.zeros(1, dtype=np.int64)
    per_axis = []
    for axis, target in zip(model.axes, axes, strict=True):
        step = TWO_PI / len(target)
        per_axis.append(np.rint(np.mod(axis, TWO_PI) / step).astype(np.int64) % len(target))
    mesh = np.meshgrid(*per_axis, indexing="ij")
    return np.ravel_multi_index(tuple(m.ravel() for m in mesh), tuple(len(a) for a in axes)).astype(np.int64)
