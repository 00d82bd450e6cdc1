"""Transitions: the allowed steps between the states of two consecutive layers.

A step ``c -> c'`` is allowed when every joint keeps within its speed bound and the swept capsules stay
clear of the (moving) obstacles, conditions 1 and 2 of :mod:`previewctl.search.reachability`. The steps of
one time step are stored once as :class:`Edges` and then read by every pass of the DP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Scene
from previewctl.search.reachability.grid import GridModel, Start, targets
from previewctl.search.reachability.layers import Layer, lut
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array, BoolArray, IntArray


def obstacle_travel(scene: Scene, t0: float, t1: float, substeps: int) -> float:
    """Upper estimate [m] of how far any obstacle moves within ``[t0, t1]`` (its largest sampled speed x
    ``t1 - t0``; 0 for static obstacles)."""
    worst = 0.0
    taus = np.linspace(t0, t1, substeps + 1)
    for obstacle in scene.obstacles:
        if isinstance(obstacle.motion, Static):
            continue
        positions = np.asarray(obstacle.motion.positions(taus), dtype=float)
        speed = float(np.max(np.linalg.norm(np.diff(positions, axis=0), axis=1))) / max(taus[1] - taus[0], 1e-300)
        worst = max(worst, speed * (t1 - t0))
    return worst


def _step_ok(model: GridModel, dst: Layer, d_rows: IntArray, gene_sweep: Array, src_q1: Array, src_beta: Array,
             src_d: Array, travel: float) -> tuple[BoolArray, NDArray[np.int8]]:
    """The joint-speed and sweep conditions of ``P`` candidate steps into rows ``d_rows`` of ``dst``.

    Args:
        model: the transition model.
        dst: the destination layer.
        d_rows: ``(P,)`` destination rows.
        gene_sweep: ``(P, L)`` [m], the genes' share of the sweep bound ``B_l``.
        src_q1: ``(P,)`` the sources' ``q_(n-1)`` [rad] (wrapped, or a start value).
        src_beta: ``(P,)`` the sources' signed elbow angles [rad].
        src_d: ``(L, P)`` the sources' capsule distances [m] (a source may be ``q0``).
        travel: bound [m] on the obstacles' motion during the step.

    Returns:
        ``ok`` ``(P,)`` and the representative shift ``(P,)`` of each step: ``q_(n-1)`` moves the short
        way, ``u' = u + wrap(a' - a)``, so representative ``m`` of the source goes to ``m + shift``.
    """
    g = model.periodic.size
    a_dst = dst.q1[d_rows]
    d_q1 = wrap_angle(a_dst - src_q1)
    shift = np.zeros(d_rows.size, dtype=np.int8)
    if not model.q1_periodic:
        shift = np.rint((src_q1 + d_q1 - a_dst) * (1.0 / TWO_PI)).astype(np.int8)
    np.abs(d_q1, out=d_q1)
    d_beta = np.abs(dst.beta[d_rows] - src_beta)
    ok = (d_q1 <= model.delta[g]) & (d_beta <= model.delta[g + 1])
    for l_idx in range(model.rho.shape[1]):
        bound = gene_sweep[:, l_idx] + travel
        if model.rho[g, l_idx]:
            bound = bound + d_q1 * model.rho[g, l_idx]
        if model.rho[g + 1, l_idx]:
            bound = bound + d_beta * model.rho[g + 1, l_idx]
        ok &= src_d[l_idx] + dst.d_t[l_idx, d_rows] > bound
    return ok, shift


@dataclass(frozen=True)
class Edges:
    """The allowed transitions of one step between *states* (``row * M + m``), in groups within which every
    source and every destination occurs at most once, so a group is applied with plain fancy indexing
    (``out[dst] = max(out[dst], value[src])``) instead of the slower ``ufunc.at``."""

    src: NDArray[np.int32]
    dst: NDArray[np.int32]
    bounds: IntArray  # group i is [bounds[i], bounds[i + 1])

    @property
    def size(self) -> int:
        return int(self.src.size)

    def groups(self) -> list[tuple[NDArray[np.int32], NDArray[np.int32]]]:
        """``(src, dst)`` of each non-empty group."""
        return [(self.src[a:b], self.dst[a:b]) for a, b in zip(self.bounds[:-1], self.bounds[1:], strict=True) if b > a]

    def push_max(self, value: Array, size: int) -> Array:
        """``out[c'] = max over edges c -> c' of value[c]`` (``-inf`` without an incoming edge)."""
        out = np.full(size, -np.inf)
        for s, d in self.groups():
            out[d] = np.maximum(out[d], value[s])
        return out

    def pull_max(self, value: Array, size: int) -> Array:
        """``out[c] = max over edges c -> c' of value[c']`` (``-inf`` without an outgoing edge)."""
        out = np.full(size, -np.inf)
        for s, d in self.groups():
            out[s] = np.maximum(out[s], value[d])
        return out

    def push_or(self, bits: NDArray[np.uint64], size: int) -> NDArray[np.uint64]:
        """``out[c'] = OR over edges c -> c' of bits[c]``."""
        out = np.zeros(size, dtype=np.uint64)
        for s, d in self.groups():
            out[d] |= bits[s]
        return out

    def pull_or(self, bits: NDArray[np.uint64], size: int) -> NDArray[np.uint64]:
        """``out[c] = OR over edges c -> c' of bits[c']``."""
        out = np.zeros(size, dtype=np.uint64)
        for s, d in self.groups():
            out[s] |= bits[d]
        return out


def _expand(model: GridModel, src: Layer, dst: Layer, rows: IntArray, d_rows: IntArray, shift: NDArray[np.int8],
            offset: IntArray, src_states: BoolArray | None) -> tuple[IntArray, IntArray, IntArray]:
    """Physical steps ``rows -> d_rows`` by gene offset number ``offset`` as state edges
    ``(row, m) -> (d_row, m + shift)``, both representatives valid (and the source state in ``src_states`` when
    given), with their group ``offset · M + m``: within a group no source and no destination repeats."""
    M = model.M
    src_out, dst_out, group_out = [], [], []
    for m in range(M):
        m_dst = m + shift.astype(np.int64)
        ok = src.valid[rows, m] & (m_dst >= 0) & (m_dst < M)
        ok[ok] &= dst.valid[d_rows[ok], m_dst[ok]]
        s_state = rows * M + m
        if src_states is not None:
            ok &= src_states[s_state]
        src_out.append(s_state[ok])
        dst_out.append(d_rows[ok] * M + m_dst[ok])
        group_out.append(offset[ok] * M + m)
    return np.concatenate(src_out), np.concatenate(dst_out), np.concatenate(group_out)


def grid_edges(model: GridModel, src: Layer, dst: Layer, travel: float, src_states: BoolArray | None) -> Edges:
    """Allowed transitions from the states of ``src`` (those in ``src_states``, or all) to those of ``dst``: one
    group per gene offset (same branch) and per gene offset and elbow switch (sources near the stretched
    wrist), split by source representative. Every offset of a kind is checked at once."""
    g = model.periodic.size
    C = model.cells
    row_of = lut(dst, C)
    every = (np.arange(src.cells.size, dtype=np.int64) if src_states is None
             else np.flatnonzero(src_states.reshape(-1, model.M).any(axis=1)))
    near = every[np.abs(src.beta[every]) <= model.delta[g + 1]]
    sources = [(every, src.branch[every].astype(np.int64) * C)]
    if near.size:
        sources.append((near, (1 - src.branch[near].astype(np.int64)) * C))
    kinds = []
    for candidates, base in sources:
        flat, on_grid = targets(model, src.gene_index[candidates], model.offsets)  # (K, m)
        d_rows = row_of[base + flat].astype(np.int64)
        offset, column = np.nonzero((d_rows >= 0) & on_grid)
        rows, d_rows = candidates[column], d_rows[offset, column]
        ok, shift = _step_ok(model, dst, d_rows, model.offset_sweep[offset], src.q1[rows], src.beta[rows],
                             src.d_t[:, rows], travel)
        kinds.append(_expand(model, src, dst, rows[ok], d_rows[ok], shift[ok], offset[ok], src_states))
    return _pack(kinds, len(model.offsets) * model.M)


def _pack(kinds: list[tuple[IntArray, IntArray, IntArray]], groups: int) -> Edges:
    """The edges of each kind (``(src, dst, group)``, ``groups`` groups per kind) as one :class:`Edges`, ordered by
    kind, then group, then as given (empty groups kept: they cost nothing)."""
    group = np.concatenate([g + i * groups for i, (_, _, g) in enumerate(kinds)])
    order = np.argsort(group, kind="stable")
    sizes = np.bincount(group, minlength=len(kinds) * groups)
    return Edges(np.concatenate([s for s, _, _ in kinds])[order].astype(np.int32),
                 np.concatenate([d for _, d, _ in kinds])[order].astype(np.int32),
                 np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64))


def start_states(model: GridModel, start: Start, d0: Array, dst: Layer, travel: float) -> IntArray:
    """States of ``dst`` reachable in one step from ``start``, whose capsule distances are ``d0`` ``(L,)`` [m]
    (its genes, as the grid sees them, and its ``q_(n-1)`` are its own unwrapped values)."""
    g = model.periodic.size
    q0, beta0 = start.grid_q, start.beta
    rows = np.arange(dst.cells.size, dtype=np.int64)
    gene_sweep = np.zeros((rows.size, model.rho.shape[1]))
    ok = np.ones(rows.size, dtype=bool)
    for a in range(g):
        diff = dst.genes[:, a] - q0[a]
        diff = np.abs(wrap_angle(diff) if model.periodic[a] else diff)
        ok &= diff <= model.r[a] * model.h + 1e-12
        gene_sweep += diff[:, None] * model.rho[a]
    step_ok, _ = _step_ok(model, dst, rows, gene_sweep, np.full(rows.size, q0[g]), np.full(rows.size, beta0),
                          np.repeat(np.asarray(d0, dtype=float)[:, None], rows.size, axis=1), travel)
    ok &= step_ok
    rows = rows[ok]
    if model.q1_periodic:
        return rows
    u = q0[g] + wrap_angle(dst.q1[rows] - q0[g])  # the short way from q0's own value
    m = np.rint((u - dst.q1[rows]) / TWO_PI).astype(np.int64) - int(model.reps[0])
    inside = (m >= 0) & (m < model.M)
    inside[inside] &= dst.valid[rows[inside], m[inside]]
    return rows[inside] * model.M + m[inside]
