"""Connected components of the states of one layer: the *families* of :mod:`previewctl.search.reachability`.

Two states are adjacent when their cells are grid neighbours within a branch, or the two branches of one
cell near the stretched wrist, and ``q_(n-1)`` takes the short way between them. The components are found
by a vectorised union-find (hook each root onto the smaller one, then jump pointers to the roots).
"""

from __future__ import annotations

import numpy as np

from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.search.reachability.grid import GridModel, targets
from previewctl.search.reachability.layers import Layer
from previewctl.search.redundancy import wrap_angle
from previewctl.types import BoolArray, IntArray

Pairs = list[tuple[IntArray, IntArray]]
"""Adjacent states ``(u, v)``, in chunks."""


def components(layer: Layer, states: BoolArray, model: GridModel, cross_beta: float) -> IntArray:
    """Connected components of the layer's ``states`` ``(m M,)`` (a mask over ``row * M + m``).

    Two states are adjacent when their cells are grid neighbours (the 3^g - 1 of them, within a branch)
    or the two branches of one cell with ``|β| <= cross_beta`` on both, and ``q_(n-1)`` takes the short way
    between them (the same representative rule as a step). Returns labels ``(m M,)``: ``-1`` outside the
    mask, else ``0 .. K - 1`` by decreasing component size.
    """
    labels = np.full(states.size, -1, dtype=np.int64)
    chosen = np.flatnonzero(states)
    if chosen.size == 0:
        return labels
    pairs = _adjacent_states(layer, states, model, cross_beta, np.unique(chosen // model.M))
    u, v = np.concatenate([a for a, _ in pairs]), np.concatenate([b for _, b in pairs])
    roots = _roots(u, v, states.size)
    _, inverse, counts = np.unique(roots[chosen], return_inverse=True, return_counts=True)
    order = np.argsort(-counts, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels[chosen] = rank[inverse]
    return labels


def _adjacent_states(layer: Layer, states: BoolArray, model: GridModel, cross_beta: float, rows: IntArray) -> Pairs:
    """The adjacent pairs among ``states`` whose cells are the layer's ``rows``: grid neighbours within a
    branch (one of each opposite pair of offsets), then the two branches of a cell near the stretched wrist."""
    C, g = model.cells, model.periodic.size
    row_of = np.full(2 * C, -1, dtype=np.int64)
    row_of[layer.cells[rows]] = rows
    pairs: Pairs = []
    for offset in np.ndindex(*(3,) * g):
        step = np.array(offset, dtype=np.int64) - 1
        nonzero = np.flatnonzero(step)
        if nonzero.size == 0 or step[nonzero[0]] < 0:  # one of each opposite pair
            continue
        flat, on_grid = targets(model, layer.gene_index[rows], step)
        other = row_of[layer.branch[rows].astype(np.int64) * C + flat]
        hit = on_grid & (other >= 0)
        pairs += _state_links(layer, model, states, rows[hit], other[hit])
    straight = rows[(layer.branch[rows] == 0) & (np.abs(layer.beta[rows]) <= cross_beta)]
    partner = row_of[layer.cells[straight] + C]
    hit = partner >= 0
    hit[hit] &= np.abs(layer.beta[partner[hit]]) <= cross_beta
    pairs += _state_links(layer, model, states, straight[hit], partner[hit])
    return pairs


def _state_links(layer: Layer, model: GridModel, states: BoolArray, a_rows: IntArray, b_rows: IntArray) -> Pairs:
    """The state pairs of adjacent cells ``a_rows``, ``b_rows``: representative ``m`` of ``a`` with the one of
    ``b`` that ``q_(n-1)`` reaches the short way, both in ``states``; one chunk per ``m``."""
    M = model.M
    shift = np.zeros(a_rows.size, dtype=np.int64)
    if not model.q1_periodic:
        a, b = layer.q1[a_rows], layer.q1[b_rows]
        shift = np.rint((a + wrap_angle(b - a) - b) / TWO_PI).astype(np.int64)
    pairs: Pairs = []
    for m in range(M):
        m_b = m + shift
        ok = (m_b >= 0) & (m_b < M)
        u, v = a_rows[ok] * M + m, b_rows[ok] * M + m_b[ok]
        keep = states[u] & states[v]
        pairs.append((u[keep], v[keep]))
    return pairs


def _roots(u: IntArray, v: IntArray, size: int) -> IntArray:
    """The root of every node ``0 .. size - 1`` of the graph with edges ``u - v``: the smallest node of its
    component (hook roots onto the smaller root, then jump pointers to the roots, until no edge differs)."""
    parent = np.arange(size, dtype=np.int64)
    while True:
        ru, rv = parent[u], parent[v]
        differ = ru != rv
        if not differ.any():
            return parent
        lo, hi = np.minimum(ru[differ], rv[differ]), np.maximum(ru[differ], rv[differ])
        np.minimum.at(parent, hi, lo)
        while True:
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped
