"""Families and their fate: the end families, the viable tube and the commit time (b), the start families.

A family is a connected component of states in one layer (:mod:`~previewctl.search.reachability.components`),
tracked through the steps as one bit of a ``uint64``: a backward OR of the end families' bits says which
of them each state still leads to, a forward OR of the start families' bits which of them reach each
state. Definitions in :mod:`previewctl.search.reachability`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.search.reachability.components import components
from previewctl.search.reachability.dp import Forward
from previewctl.search.reachability.grid import GridModel, Start
from previewctl.search.reachability.layers import Layer
from previewctl.search.reachability.problem import Problem
from previewctl.search.reachability.result import Family
from previewctl.types import Array, BoolArray, IntArray

MAX_FAMILY_BITS = 63
"""Families tracked with their own bit; smaller components beyond that share the last bit."""

Bits = NDArray[np.uint64]


@dataclass(frozen=True)
class EndFamilies:
    """The end families of a forward pass and what they say about the states before them.

    Attributes:
        families: the components at ``t_K`` reachable from ``q0``, by decreasing size.
        commit_time: the last time [s] at which some viable state (or ``q0``) still leads to two end
            families (``None``: never).
        best_family: the label of the family the best motion ends in (``None`` without a step).
        viable: ``[k - 1]``: the states of layer ``k`` that lead to some end family, ``k = 1 .. K``.
    """

    families: tuple[Family, ...]
    commit_time: float | None
    best_family: int | None
    viable: list[BoolArray]


def end_families(fwd: Forward, model: GridModel, times: Array, last_state: int, cross_beta: float) -> EndFamilies:
    """(b) The end families at ``t_K`` (the end, or the dead end), the viable tube and the commit time;
    ``last_state`` is the best motion's state at ``t_K``, ``cross_beta`` [rad] the cross-branch adjacency."""
    K = fwd.K
    if K < 1:
        return EndFamilies(families=(), commit_time=None, best_family=None, viable=[])
    reachable = fwd.reachable()
    labels = components(fwd.layers[K - 1], reachable[K - 1], model, cross_beta)
    A = _leads_to(fwd, reachable, bits(labels))
    shared = [np.uint64(0)] + [_shared_bits(A[k]) for k in range(1, K + 1)]
    q0_many = bool(two_or_more(np.bitwise_or.reduce(A[1][fwd.start], keepdims=True))[0])
    many = [q0_many] + [bool(shared[k]) for k in range(1, K + 1)]
    families = []
    for label in range(int(labels.max()) + 1):
        when = [k for k in range(1, K + 1) if shared[k] & family_bit(label)]
        if not when and q0_many:
            when = [0]
        members = np.flatnonzero(labels == label)
        families.append(family_of(label + 1, fwd.layers[K - 1], model, members,
                                  shared_until=float(times[max(when)]) if when else None,
                                  best_min_S=float(np.max(fwd.W[K][members]))))
    return EndFamilies(families=tuple(families),
                       commit_time=float(times[max(k for k in range(K + 1) if many[k])]) if any(many) else None,
                       best_family=int(labels[last_state]) + 1, viable=[A[k] != 0 for k in range(1, K + 1)])


def _leads_to(fwd: Forward, reachable: list[BoolArray], end_bits: Bits) -> list[Bits]:
    """``A[k]``: the end families (bits) each reachable state of layer ``k`` leads to, by a backward OR from
    ``A[K] = end_bits``; ``A[0]`` unused."""
    K = fwd.K
    A: list[Bits] = [np.zeros(0, dtype=np.uint64)] * (K + 1)
    A[K] = end_bits
    for k in range(K - 1, 0, -1):
        A[k] = np.where(reachable[k - 1], fwd.hops[k - 1].pull_or(A[k + 1], fwd.layers[k - 1].states), np.uint64(0))
    return A


def start_families(problem: Problem, start: Start, cross_beta: float) -> tuple[Family, ...]:
    """The components of the feasible states at ``t_0`` and their fate: how long each one's forward
    reachable set lives, whether it finishes, until when it shares a state with another one, and which one
    holds ``q0``."""
    model, N, times = problem.model, problem.N, problem.times
    first = problem.layer(0, None)
    if first.cells.size == 0:
        return ()
    labels = components(first, first.valid.reshape(-1), model, cross_beta)
    alive, shared = _forward_fate(problem, first, bits(labels))
    home = _home_state(model, first, start)
    home_label = int(labels[home]) if home >= 0 else -1
    out = []
    for label in range(int(labels.max()) + 1):
        members = np.flatnonzero(labels == label)
        bit = family_bit(label)
        alive_k = [k for k in range(N + 1) if alive[k] & bit]
        shared_k = [k for k in range(1, N + 1) if shared[k] & bit]
        out.append(family_of(label + 1, first, model, members, alive_until=float(times[max(alive_k)]),
                             finishes=max(alive_k) == N, holds_q0=label == home_label,
                             shared_until=float(times[max(shared_k)]) if shared_k else None))
    return tuple(out)


def _forward_fate(problem: Problem, first: Layer, F: Bits) -> tuple[Bits, Bits]:
    """A forward OR of the start families' bits ``F`` over the whole grid: per layer, the families whose
    reachable set is non-empty (``alive``) and those that share a state with another one (``shared``)."""
    N = problem.N
    alive = np.zeros(N + 1, dtype=np.uint64)
    shared = np.zeros(N + 1, dtype=np.uint64)
    alive[0] = np.bitwise_or.reduce(F)
    src = first
    for k in range(N):
        dst = problem.layer(k + 1, None)
        F = problem.edges(src, dst, k, None).push_or(F, dst.states)
        alive[k + 1] = np.bitwise_or.reduce(F) if F.size else np.uint64(0)
        shared[k + 1] = _shared_bits(F)
        src = dst
    return alive, shared


def _shared_bits(F: Bits) -> np.uint64:
    """The OR of the states that hold two or more families: the families that share a state."""
    multi = F[two_or_more(F)]
    return np.bitwise_or.reduce(multi) if multi.size else np.uint64(0)


def _home_state(model: GridModel, layer: Layer, start: Start) -> int:
    """The state of ``layer`` nearest to ``start`` on its branch (its grid cell and ``q_(n-1)``'s
    representative), or -1 if that cell is not feasible."""
    g, start_q = model.periodic.size, start.grid_q
    flat = 0
    for a in range(g):
        if model.periodic[a]:
            index = round(float(np.mod(start_q[a], TWO_PI)) / model.h) % model.shape[a]
        else:
            index = int(np.clip(round((start_q[a] - model.axes[a][0]) / model.h), 0, model.shape[a] - 1))
        flat += index * int(model.strides[a])
    row = np.flatnonzero(layer.cells == start.branch * model.cells + flat)
    if row.size == 0:
        return -1
    m = 0 if model.q1_periodic else int(np.rint((start_q[g] - layer.q1[row[0]]) / TWO_PI)) - int(model.reps[0])
    return int(row[0]) * model.M + m if 0 <= m < model.M and layer.valid[row[0], m] else -1


def bits(labels: IntArray) -> Bits:
    """One bit per label (labels beyond :data:`MAX_FAMILY_BITS` - 1 share the last bit); 0 for -1."""
    capped = np.minimum(labels, MAX_FAMILY_BITS - 1)
    return np.where(labels >= 0, np.left_shift(np.uint64(1), np.maximum(capped, 0).astype(np.uint64)),
                    np.uint64(0)).astype(np.uint64)


def two_or_more(F: Bits) -> BoolArray:
    """Whether each entry has two or more bits set (``x & (x - 1)`` clears the lowest one; numpy 1.x has no
    ``bitwise_count``)."""
    return (F & (F - np.uint64(1))) != 0


def family_bit(label: int) -> np.uint64:
    """The bit of family ``label`` (0-based) in :func:`bits`."""
    return np.uint64(1) << np.uint64(min(label, MAX_FAMILY_BITS - 1))


def family_of(label: int, layer: Layer, model: GridModel, members: IntArray, **extra: object) -> Family:
    """A family from its member states."""
    rows = members // model.M
    best = int(rows[int(np.argmax(layer.S[rows]))])
    return Family(label=label, cells=int(members.size), peak_genes=layer.genes[best].copy(),
                  peak_branch=int(layer.branch[best]), peak_S=float(layer.S[best]), **extra)  # type: ignore[arg-type]
