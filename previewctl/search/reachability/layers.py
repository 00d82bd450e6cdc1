"""Layer evaluation: the feasible cells of the grid at one time, and which cells to evaluate.

A layer holds the cells that put the hand on the path at its time with ``S > s_min``, ``q_n`` within its
limits and some representative of ``q_(n-1)`` within its own (see :mod:`previewctl.search.reachability`).
The DP evaluates only the cells one step away from what it has reached (:func:`dilate`, and
:func:`start_box` from ``q0``); the figures and the start families evaluate the whole grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.index.evaluator import Evaluator
from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability.grid import GridModel, signed_elbow, targets
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array, BoolArray, IntArray


@dataclass(frozen=True)
class Layer:
    """The feasible physical cells of one layer (``m`` of them) and which representatives are valid."""

    t: float
    cells: IntArray  # (m,) flat physical index b * C + gene, increasing
    gene_index: IntArray  # (m, g)
    branch: NDArray[np.int32]  # (m,)
    genes: Array  # (m, g) gene values [rad] (the axis values: unwrapped for bounded genes)
    q1: Array  # (m,) q_(n-1) wrapped to [-pi, pi) [rad]
    beta: Array  # (m,) signed elbow angle [rad]
    d_t: Array  # (L, m) capsule distances [m]
    S: Array  # (m,)
    valid: BoolArray  # (m, M) representative m of q_(n-1) within the joint limits

    @property
    def states(self) -> int:
        return int(self.valid.size)


def solve_whole_grid(red: PlanarRedundancy, axes: tuple[Array, ...], target: Array) -> tuple[Array, BoolArray]:
    """Configurations ``(2 C, n)`` [rad] of every cell of the grid over ``axes`` (branch-major) with the hand
    at ``target``, and whether each is reachable (an arm without genes: its two branches)."""
    if axes:
        return red.solve_grid(axes, target)
    return red.solve(np.zeros((2, 0)), np.array([0, 1]), target)


def evaluate_layer(red: PlanarRedundancy, evaluator: Evaluator, model: GridModel, target: Array, t: float,
                   s_min: float, candidates: IntArray | None) -> Layer:
    """Solve and score the ``candidates`` (flat physical indices; ``None``: the whole grid) at ``t`` [s]; keep
    the feasible ones: reachable, ``S > s_min``, ``q_n`` and some representative of ``q_(n-1)`` within limits."""
    C, axes = model.cells, model.axes
    if candidates is None:
        index = np.arange(2 * C, dtype=np.int64)
        Q, reach = solve_whole_grid(red, axes, target)
    else:
        index = np.asarray(candidates, dtype=np.int64)
        genes = (np.stack([axes[a][i] for a, i in enumerate(np.unravel_index(index % C, model.shape))], axis=1)
                 if axes else np.zeros((index.size, 0)))
        Q, reach = red.solve(genes, index // C, target)
    S = np.full(index.size, evaluator.potential.collision_value)
    d = np.full((index.size, len(evaluator.robot.guarded_links)), -np.inf)
    if reach.any():
        ev = evaluator(Q[reach], t)
        S[reach], d[reach] = ev.S, ev.link_distances
    branch_all = (index // C).astype(np.int32)
    beta = signed_elbow(red, Q, branch_all)
    q1 = wrap_angle(Q[:, red.n - 2])
    valid = _valid_representatives(model, q1)
    ok = reach & (s_min < S) & _elbow_within_limits(model, beta) & valid.any(axis=1)
    keep = np.flatnonzero(ok)
    cells = index[keep]
    gene_index = (np.stack(np.unravel_index(cells % C, model.shape), axis=1).astype(np.int64) if axes
                  else np.zeros((cells.size, 0), dtype=np.int64))
    genes = (np.stack([axes[a][gene_index[:, a]] for a in range(len(axes))], axis=1) if axes
             else np.zeros((cells.size, 0)))
    return Layer(t=float(t), cells=cells, gene_index=gene_index, branch=branch_all[keep], genes=genes,
                 q1=q1[keep], beta=beta[keep], d_t=np.ascontiguousarray(d[keep].T), S=S[keep], valid=valid[keep])


def _elbow_within_limits(model: GridModel, beta: Array) -> BoolArray:
    """Whether ``q_n = β + c`` lies within its joint limits, per signed elbow angle ``β`` [rad]."""
    lo_n, hi_n = model.qn_limits
    return np.asarray((beta + model.elbow_offset >= lo_n - 1e-9) & (beta + model.elbow_offset <= hi_n + 1e-9))


def _valid_representatives(model: GridModel, q1: Array) -> BoolArray:
    """``(B, M)``: whether representative ``m`` of ``q_(n-1)``, ``a + 2π m`` for each ``a`` of ``q1``, lies
    within the joint's limits (one, always valid, for a joint without finite limits)."""
    if model.q1_periodic:
        return np.ones((q1.size, 1), dtype=bool)
    lo, hi = model.q1_limits
    u = q1[:, None] + TWO_PI * model.reps[None, :]
    return np.asarray((u >= lo - 1e-9) & (u <= hi + 1e-9))


def lut(layer: Layer, C: int) -> NDArray[np.int32]:
    """Row of each flat physical index in ``layer`` (``-1``: not a feasible cell)."""
    table = np.full(2 * C, -1, dtype=np.int32)
    table[layer.cells] = np.arange(layer.cells.size, dtype=np.int32)
    return table


def dilate(model: GridModel, layer: Layer, rows: IntArray) -> IntArray:
    """Flat physical indices (both branches) within one step's gene offsets of ``layer``'s ``rows``."""
    C = model.cells
    mask = np.zeros(C, dtype=bool)
    flat, ok = targets(model, layer.gene_index[rows], model.offsets)
    mask[flat[ok]] = True
    genes = np.flatnonzero(mask)
    return np.concatenate([genes, genes + C])


def start_box(model: GridModel, start_q: Array) -> IntArray:
    """Flat physical indices (both branches) of the cells whose genes are within one step's gene bound of
    ``start_q``."""
    C, axes = model.cells, model.axes
    if not axes:
        return np.arange(2 * C, dtype=np.int64)
    keep = []
    for a, axis in enumerate(axes):
        diff = axis - start_q[a]
        diff = np.abs(wrap_angle(diff) if model.periodic[a] else diff)
        keep.append(np.flatnonzero(diff <= model.r[a] * model.h + 1e-12))
    if any(k.size == 0 for k in keep):
        return np.zeros(0, dtype=np.int64)
    mesh = np.meshgrid(*keep, indexing="ij")
    genes = np.ravel_multi_index(tuple(m.ravel() for m in mesh), model.shape).astype(np.int64)
    return np.concatenate([genes, genes + C])
