"""What :func:`~previewctl.search.reachability.reach_over_time` answers: the best motion, the families
and the whole result, with its JSON-ready summary (every definition is in :mod:`previewctl.search.reachability`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from previewctl.errors import TrajectoryError
from previewctl.search.reachability.options import ReachOptions
from previewctl.types import Array, BoolArray, IntArray


@dataclass(frozen=True)
class ReachMotion:
    """A motion through the grid, one sample per layer (``K + 1`` samples, ``q0`` first).

    Attributes:
        times: ``(K + 1,)`` [s].
        q: ``(K + 1, n)`` configurations [rad], unwrapped along the motion (consecutive samples differ
            by at most the per-step bounds, so linear interpolation is the motion the DP checked).
        S: ``(K + 1,)`` AMSIP of the samples (``S[0]`` is that of ``q0``).
        branch: ``(K + 1,)`` elbow branch (0: ``β >= 0``, 1: ``β < 0``).
        cells: ``(K + 1,)`` flat index ``branch * C + gene index`` of each sample in the DP's grid (``-1``
            for ``q0``).
        min_S: ``min S[1:]``, the bottleneck the DP maximised.
        total_S: ``Σ S[1:]``, the tie-break it maximised next.
    """

    times: Array
    q: Array
    S: Array
    branch: IntArray
    cells: IntArray
    min_S: float  # noqa: N815 -- the paper's symbol S
    total_S: float  # noqa: N815 -- the paper's symbol S

    def __post_init__(self) -> None:
        """Refuse a motion that :meth:`sample`'s compiled loop could not read: no sample, or a row count of ``q``
        or ``S`` that is not the number of times."""
        if not self.times.size or self.q.shape[0] != self.times.size or self.S.shape != self.times.shape:
            raise TrajectoryError(f"a motion needs at least one sample and one row of q and one S per time: got "
                                  f"{self.times.size} times, q of shape {self.q.shape}, S of shape {self.S.shape}")

    def to_json(self) -> dict[str, Any]:
        """The motion as strict JSON values: finite floats (``json`` writes them so that they read back exactly),
        and ``None`` for a NaN (the S of a motion that holds ``q``)."""
        def number(v: float) -> float | None:
            return None if math.isnan(v) else v

        return {"times": self.times.tolist(), "q": self.q.tolist(), "S": [number(v) for v in self.S.tolist()],
                "branch": self.branch.tolist(), "cells": self.cells.tolist(), "min_S": number(self.min_S),
                "total_S": self.total_S}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ReachMotion:
        """The motion :meth:`to_json` wrote (``None`` back to NaN)."""
        min_S = data["min_S"]
        return cls(times=np.array(data["times"], dtype=float), q=np.array(data["q"], dtype=float),
                   S=np.array(data["S"], dtype=float), branch=np.array(data["branch"], dtype=np.int64),
                   cells=np.array(data["cells"], dtype=np.int64), min_S=math.nan if min_S is None else float(min_S),
                   total_S=float(data["total_S"]))

    def at(self, t: float) -> Array:
        """Configuration [rad] at time ``t`` [s], linear between samples, held outside."""
        return self.sample(np.array([t], dtype=float))[0][0]

    def sample(self, times: Array) -> tuple[Array, Array]:
        """Configurations ``(T, n)`` [rad] and S ``(T,)`` at the times ``(T,)`` [s]: linear between samples, held
        outside (S as ``np.interp`` takes it). One compiled call for all the times (a loop's plan points each cycle)."""
        query = np.asarray(times, dtype=float).reshape(-1)
        q, S = np.empty((query.size, self.q.shape[1])), np.empty(query.size)
        _sample(self.times, self.q, self.S, query, q, S)
        return q, S

    def velocity(self, t: float) -> Array:
        """Joint velocity [rad/s] of the linear interpolation at ``t`` [s] (0 outside the motion)."""
        if self.times.size < 2 or t < self.times[0] or t >= self.times[-1]:
            return np.zeros(self.q.shape[1])
        k = min(max(int(np.searchsorted(self.times, t, side="right")) - 1, 0), self.times.size - 2)
        return np.asarray((self.q[k + 1] - self.q[k]) / (self.times[k + 1] - self.times[k]), dtype=float)


@numba.njit(cache=True, nogil=True)
def _sample(times: Array, q: Array, S: Array, query: Array, out_q: Array, out_S: Array) -> None:  # pragma: no cover
    """:meth:`ReachMotion.sample` into ``out_q`` and ``out_S``, compiled: each joint as ``np.interp`` takes it at the
    time held within the motion, S at the time itself (the same bits; a test checks them against ``np.interp``)."""
    for i in range(query.size):
        t = held = query[i]
        if times[0] > held:  # min(max(t, times[0]), times[-1]) as Python's builtins take it
            held = times[0]
        if times[-1] < held:
            held = times[-1]
        for j in range(q.shape[1]):
            out_q[i, j] = _interp(held, times, q[:, j])
        out_S[i] = _interp(t, times, S)


@numba.njit(cache=True, nogil=True)
def _interp(x: float, xp: Array, fp: Array) -> float:  # pragma: no cover - compiled
    """``np.interp(x, xp, fp)`` for one ``x``, with numpy's arithmetic and its special cases (held outside, a sample's
    own value at its time, NaN slopes retried from the right)."""
    n = xp.size
    if n == 1:
        return fp[0]
    if x != x:
        return x
    j = np.searchsorted(xp, x, side="right") - 1
    if j < 0:
        return fp[0]
    if j >= n - 1:
        return fp[n - 1]
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    y = slope * (x - xp[j]) + fp[j]
    if y != y:
        y = slope * (x - xp[j + 1]) + fp[j + 1]
        if y != y and fp[j] == fp[j + 1]:
            y = fp[j]
    return y


@dataclass(frozen=True)
class Family:
    """A connected component of feasible cells in one layer, and its fate over time.

    Attributes:
        label: its number (1-based, by decreasing size).
        cells: how many grid cells it holds.
        peak_genes: ``(g,)`` genes [rad] of its best cell.
        peak_branch: branch of its best cell.
        peak_S: S of its best cell.
        alive_until: start families: the last time [s] its forward reachable set is non-empty.
        finishes: start families: whether that set reaches the last layer.
        shared_until: the last time [s] some cell is reachable from (start families) or leads to (end
            families) this family and another one too; ``None`` if never.
        best_min_S: end families: the best bottleneck ``min S`` of a motion from ``q0`` ending in it.
        holds_q0: start families: whether ``q0``'s nearest grid cell belongs to it.
    """

    label: int
    cells: int
    peak_genes: Array
    peak_branch: int
    peak_S: float  # noqa: N815 -- the paper's symbol S
    alive_until: float | None = None
    finishes: bool | None = None
    shared_until: float | None = None
    best_min_S: float | None = None  # noqa: N815 -- the paper's symbol S
    holds_q0: bool | None = None


@dataclass(frozen=True)
class ReachResult:
    """The answer of :func:`~previewctl.search.reachability.reach_over_time` (see the package docstring,
    :mod:`previewctl.search.reachability`, for every definition).

    Attributes:
        times: ``(N + 1,)`` layer times [s].
        axes: the DP's gene axes [rad], one per gene (over the joint limits when they are finite).
        map_axes: the figures' axes, ``[0, 2π)`` per gene like the paper's maps.
        shape: the figures' grid shape ``(2, n_1, ..., n_g)`` over ``map_axes``.
        map_layers: the layers whose whole S map is kept (see ``ReachOptions.map_times``).
        S_maps: ``(len(map_layers), 2, n_1, ..., n_g)`` AMSIP at those layers over ``map_axes``
            (float32; ``collision_value`` where unreachable).
        reachable: ``(N + 1, 2, n_1, ...)`` over ``map_axes``: cells some state of which (a representative
            of the joint values, see the package docstring) is reachable from ``q0`` (layer 0: none).
        viable: ``(N + 1, 2, n_1, ...)`` likewise for the states from which the motion can still be
            continued to ``t_K`` (the end, or the dead end).
        exists: whether a collision-free motion from ``q0`` to ``t_N`` exists (in the DP's model).
        dead_end: when it does not, the last time [s] the arm can still be at (``t_0``: not even one
            step); ``None`` when it does.
        best_min_S: ``S*``: the best minimum S over ``t_1 .. t_K`` (``nan`` if no step is possible).
        motion: the best motion (to ``t_K``, the dead end when no motion exists); with goals, the best
            motion to the chosen goal (see ``goal``).
        q0_S: AMSIP of ``q0`` at ``t_0``.
        end_families: components at ``t_K`` reachable from ``q0`` (``t_K``: the end, or the dead end).
        commit_time: the last time [s] at which the arm can still reach two end families
            (``None`` with fewer than two). It counts every end family, small ones too; the
            families' own ``shared_until`` say when each one's options close.
        best_family: the label of the end family the best motion ends in (``None`` without a step).
        start_families: components of the feasible cells at ``t_0`` (only with
            ``ReachOptions.start_families``).
        dt: time step [s].
        joint_step: ``(n,)`` per-step joint bound ``δ_j`` [rad] (``inf``: no limit).
        gene_cells: ``(g,)`` gene cells per step ``r_a``.
        edges: number of allowed transitions between states per step ``(K,)``.
        timings: wall-clock seconds per stage (``maps``: evaluating S on the layers; ``edges``: the
            transitions; ``dp``: the passes, families and commit time; ``extras``: the figures' whole maps
            and the start families) and in all (``total``), and the process CPU seconds (``cpu``; on a
            shared machine the fairer figure).
        options: the options used.
        goal: ``(level, index)`` of the goal the motion ends at (:mod:`~previewctl.search.reachability.goals`;
            ``None``: no goals were given, or none is reached, and the motion is the best one).
    """

    times: Array
    axes: tuple[Array, ...]
    map_axes: tuple[Array, ...]
    shape: tuple[int, ...]
    map_layers: tuple[int, ...]
    S_maps: NDArray[np.float32]
    reachable: BoolArray
    viable: BoolArray
    exists: bool
    dead_end: float | None
    best_min_S: float  # noqa: N815 -- the paper's symbol S
    motion: ReachMotion
    q0_S: float  # noqa: N815 -- the paper's symbol S
    end_families: tuple[Family, ...]
    commit_time: float | None
    best_family: int | None
    start_families: tuple[Family, ...]
    dt: float
    joint_step: Array
    gene_cells: IntArray
    edges: IntArray
    timings: dict[str, float] = field(default_factory=dict)
    options: ReachOptions = field(default_factory=ReachOptions)
    goal: tuple[int, int] | None = None

    @property
    def gene_speed(self) -> Array:
        """The largest gene speed [rad/s] the transition model allows, ``r_a h / Δt``, per gene."""
        return np.asarray(self.gene_cells * math.radians(self.options.resolution_deg) / self.dt, dtype=float)

    def summary(self) -> dict[str, Any]:
        """The figures of merit as plain JSON-ready values (angles in degrees, times in seconds)."""
        return {
            "verdict": self.verdict(),
            "exists": self.exists,
            "dead_end": self.dead_end,
            "best_min_S": None if not np.isfinite(self.best_min_S) else self.best_min_S,
            "q0_S": self.q0_S,
            "commit_time": self.commit_time,
            "best_family": self.best_family,
            "end_families": [_family_summary(f) for f in self.end_families],
            "start_families": [_family_summary(f) for f in self.start_families],
            "motion": _motion_summary(self.motion),
            "grid": self._grid_summary(),
            "edges": int(self.edges.sum()),
            "timings_s": {key: round(value, 4) for key, value in self.timings.items()},
        }

    def _grid_summary(self) -> dict[str, Any]:
        """The grid and transition model of :meth:`summary` (degrees, seconds)."""
        return {
            "resolution_deg": self.options.resolution_deg,
            "gene_axes_deg": [[round(math.degrees(float(a[0])), 4), round(math.degrees(float(a[-1])), 4), len(a)]
                              for a in self.axes],
            "map_shape": list(self.shape),
            "steps": len(self.times) - 1,
            "dt": self.dt,
            "joint_step_deg": [None if not np.isfinite(v) else round(math.degrees(v), 4) for v in self.joint_step],
            "gene_cells_per_step": [int(r) for r in self.gene_cells],
            "gene_speed_deg_s": [round(math.degrees(v), 4) for v in self.gene_speed],
            "s_min": self.options.s_min,
            "velocity_scale": self.options.velocity_scale,
        }

    def verdict(self) -> str:
        """One line: whether a motion exists, else where the arm gets stuck."""
        if self.exists:
            return f"a collision-free tracking motion exists from q0 to t = {self.times[-1]:g} s"
        if self.dead_end is None or self.dead_end <= self.times[0]:
            return "no collision-free step from q0 at all"
        return f"no collision-free tracking motion from q0: every motion is stuck by t = {self.dead_end:g} s"


def _family_summary(f: Family) -> dict[str, Any]:
    """A family as JSON-ready values for :meth:`ReachResult.summary` (the fields that are set)."""
    row: dict[str, Any] = {
        "label": f.label,
        "cells": f.cells,
        "peak_genes_deg": [round(float(v), 3) for v in np.degrees(f.peak_genes)],
        "peak_branch": f.peak_branch,
        "peak_S": f.peak_S,
    }
    for key in ("alive_until", "finishes", "shared_until", "best_min_S", "holds_q0"):
        value = getattr(f, key)
        if value is not None:
            row[key] = value
    return row


def _motion_summary(motion: ReachMotion) -> dict[str, Any]:
    """A motion as JSON-ready values for :meth:`ReachResult.summary` (degrees, seconds)."""
    switches = np.flatnonzero(np.diff(motion.branch) != 0)
    return {
        "times": [float(t) for t in motion.times],
        "q_deg": np.round(np.degrees(motion.q), 4).tolist(),
        "S": [float(v) for v in motion.S],
        "branch": [int(b) for b in motion.branch],
        "min_S": None if not np.isfinite(motion.min_S) else motion.min_S,
        "total_S": motion.total_S,
        "elbow_switch_times": [float(0.5 * (motion.times[k] + motion.times[k + 1])) for k in switches],
    }
