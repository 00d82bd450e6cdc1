"""Reachability over time: dynamic programming over the planar redundancy grid x time (the global reference).

The paper's section 5.1 asks "whether the current configuration is reachable to the future optimal
configuration" and answers by looking at the AMSIP maps at ten times (Fig. 8, Table 1). This module
answers it exactly on a grid, for planar arms, offline and non-causally (it reads the whole future):

* **Space.** The redundancy grid of :class:`~previewctl.planar.redundancy.PlanarRedundancy`: the
  genes ``q_1 .. q_(n-2)`` on a ``h``-degree grid (periodic genes over ``[0, 360)``) x the two elbow
  branches; the last two joints in closed form, so every cell puts the hand on the path.
* **Time.** ``N`` steps of ``Δt = duration / N`` [s]; layer ``k`` holds the cells at ``t_k = t_0 + k Δt``
  with the obstacles and the hand target of that time. Layer 0 of the dynamic programme is the
  start configuration ``q0`` itself (not a grid cell); the grid at ``t_0`` is only used for the
  start families and the figures.
* **Feasible cells.** ``S > s_min`` (AMSIP, eq. 18; ``S < 0`` when colliding or unreachable).
* **Transitions** ``c -> c'`` from layer ``k`` to ``k + 1`` (all conditions, each conservative):

  1. joint speed (every joint, the closed-form last two included): ``|Δq_j| <= δ_j = v_j Δt``
     with ``v_j`` the URDF speed limit x ``velocity_scale`` [rad/s]. Genes move by whole cells,
     ``|Δi_a| <= r_a = min(floor(δ_a / h), max_step_cells)``: the cap ``max_step_cells`` bounds the
     work, and it is a further (reported) restriction when ``r_a h < δ_a``. ``q_(n-1)`` is compared
     modulo 2π when its joint turns a full circle. The elbow is compared through its signed
     angle ``β`` (branch 0: ``β >= 0``, branch 1: ``β < 0``; ``q_n = β + const``) *without* wrapping,
     so an elbow switch can only pass the stretched wrist ``β = 0`` (``|β| + |β'| <= δ_n``), never
     the folded one (``β = ±π``).
  2. the continuous motion between the samples: the arm is taken to move linearly in joint space
     from ``c`` at ``t_k`` to ``c'`` at ``t_(k+1)``. A point of guarded capsule ``l`` then moves by at most
     ``B_l = Σ_j |Δq_j| ρ_jl`` [m], with ``ρ_jl`` the largest distance from joint ``j`` to that capsule
     (link lengths along the chain + capsule end + radius: a bound independent of the
     configuration). The obstacles move by at most ``m = v_obs Δt`` (``v_obs`` estimated from
     ``obstacle_substeps`` samples of their motion; 0 for static ones). The step is collision-free
     if ``d_l(c) + d_l(c') > B_l + m`` for every guarded capsule ``l``, ``d_l`` the capsule-obstacle
     distance [m]: at a fraction ``s`` of the step the clearance is at least
     ``max(d_l(c) - s (B_l + m), d_l(c') - (1 - s)(B_l + m)) > 0``. The hand leaves the path between
     samples by a little (the path is not linear in joint space); a tracking controller such as
     :class:`~previewctl.control.oracle.OracleController` keeps it on the path and uses the motion
     as a reference.

  So a motion the DP returns is, as sampled and linearly interpolated, within the speed limits
  and collision-free for the guarded links. A "no" is relative to the grid, the time step and the
  step cap: the DP is resolution-complete, not complete.

The programme, over stored edge lists (one per step, built once):

* **(a) existence.** ``W_k(c)`` = the best bottleneck ``max over motions q0 -> c of min_(1<=i<=k) S_i``
  (forward max-min; ``-inf`` when ``c`` is not reachable). A motion to the end exists iff some
  ``W_N > -inf``. Otherwise the *dead end* is ``t_K`` with ``K`` the last layer that can be reached.
* **(c) the best motion.** ``S* = max W_K`` (the best minimum S over ``t_1 .. t_K``; ``q0`` is given and
  its own S reported apart). Among the motions whose every sample has ``S >= S*``, the one with the
  largest total ``Σ_k S_k`` (a backward max-sum DP on the cells with ``W_k >= S*``, then a forward
  read-out): the exact lexicographic optimum (max min S, then max total S).
* **(b) the commit time.** The *end families* are the connected components (8-neighbour grid
  adjacency within a branch; the two branches of a cell are adjacent where ``|β| <= cross_adjacency``)
  of the cells at ``t_K`` that ``q0`` reaches (``K = N`` when a motion exists; otherwise the families
  that last longest). A backward OR of family bit masks gives, for every
  reachable cell, the set of end families still reachable from it; the *viable tube* is the reachable
  cells with a non-empty set. The **commit time** is the last ``t_k`` at which some cell of the viable
  tube (or ``q0`` at ``t_0``) can still reach two or more end families: until then the arm can keep
  its options open; from ``t_(k+1)`` on every viable configuration leads to exactly one family. With
  one end family there is nothing to commit to (``None``).
* **Start families** (the paper's view of Fig. 8): the components of the feasible cells at ``t_0``.
  A forward OR of their bits gives each family's *lifetime* (the last ``t_k`` at which its forward
  reachable set is non-empty; the paper's peak 4 dies at 15 s), whether it reaches ``t_N``, and the
  last time its reachable set shares a cell with another family's (after that, the family's tube is
  separate from the others).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.planar.redundancy import PlanarRedundancy
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Scene
from previewctl.search.redundancy import TWO_PI, wrap_angle
from previewctl.types import Array

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

MAX_FAMILY_BITS = 63
"""Families tracked with their own bit; smaller components beyond that share the last bit."""


class PlanarOnlyError(ConfigurationError):
    """Reachability over time is built for planar arms (closed-form redundancy grid) only."""


@dataclass(frozen=True)
class ReachOptions:
    """Grid, time step and transition model of :func:`reach_over_time`.

    Attributes:
        resolution_deg: gene grid step ``h`` [deg] (periodic genes: ``round(360 / h)`` cells).
        steps: number of time steps ``N`` (``N + 1`` layers); ``Δt = duration / N`` [s].
        max_step_cells: cap on the gene cells moved per step (the work grows as ``(2 r + 1)^g``).
        s_min: feasible cells have ``S > s_min`` (0: collision-free and reachable).
        velocity_scale: fraction of the URDF joint speed limits the motion may use, in (0, 1].
        obstacle_substeps: samples per step used to bound the obstacles' speed.
        cross_adjacency_deg: the two elbow branches of one grid cell count as adjacent (one family)
            where the elbow angle ``|β|`` is at most this [deg] (the stretched wrist).
    """

    resolution_deg: float = 2.0
    steps: int = 50
    max_step_cells: int = 3
    s_min: float = 0.0
    velocity_scale: float = 1.0
    obstacle_substeps: int = 8
    cross_adjacency_deg: float = 10.0

    def __post_init__(self) -> None:
        """Validate every field.

        Raises:
            ConfigurationError: a bad value (the message names the field and the value).
        """
        if not (isinstance(self.resolution_deg, (int, float)) and math.isfinite(self.resolution_deg)
                and 0 < self.resolution_deg <= 90):
            raise ConfigurationError(f"resolution_deg must lie in (0, 90] [deg], got {self.resolution_deg!r}")
        for name, low in (("steps", 1), ("max_step_cells", 1), ("obstacle_substeps", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigurationError(f"{name} must be an integer >= {low}, got {value!r}")
        if not (isinstance(self.s_min, (int, float)) and math.isfinite(self.s_min) and self.s_min >= 0):
            raise ConfigurationError(f"s_min must be a finite number >= 0, got {self.s_min!r}")
        if not (isinstance(self.velocity_scale, (int, float)) and 0 < self.velocity_scale <= 1):
            raise ConfigurationError(f"velocity_scale must lie in (0, 1], got {self.velocity_scale!r}")
        if not (isinstance(self.cross_adjacency_deg, (int, float)) and 0 <= self.cross_adjacency_deg <= 180):
            raise ConfigurationError(
                f"cross_adjacency_deg must lie in [0, 180] [deg], got {self.cross_adjacency_deg!r}")


@dataclass(frozen=True)
class ReachMotion:
    """A motion through the grid, one sample per layer (``K + 1`` samples, ``q0`` first).

    Attributes:
        times: ``(K + 1,)`` [s].
        q: ``(K + 1, n)`` configurations [rad], unwrapped along the motion (consecutive samples differ
            by at most the per-step bounds, so linear interpolation is the motion the DP checked).
        S: ``(K + 1,)`` AMSIP of the samples (``S[0]`` is that of ``q0``).
        branch: ``(K + 1,)`` elbow branch (0: ``β >= 0``, 1: ``β < 0``).
        cells: ``(K + 1,)`` flat grid index of each sample (``-1`` for ``q0``).
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

    def at(self, t: float) -> Array:
        """Configuration [rad] at time ``t`` [s], linear between samples, held outside."""
        t = float(np.clip(t, self.times[0], self.times[-1]))
        return np.array([np.interp(t, self.times, column) for column in self.q.T])

    def velocity(self, t: float) -> Array:
        """Joint velocity [rad/s] of the linear interpolation at ``t`` [s] (0 outside the motion)."""
        if self.times.size < 2 or t < self.times[0] or t >= self.times[-1]:
            return np.zeros(self.q.shape[1])
        k = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, self.times.size - 2))
        return np.asarray((self.q[k + 1] - self.q[k]) / (self.times[k + 1] - self.times[k]), dtype=float)


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
    """The answer of :func:`reach_over_time` (see the module docstring for every definition).

    Attributes:
        times: ``(N + 1,)`` layer times [s].
        axes: one ``(n_a,)`` axis [rad] per gene.
        shape: grid shape ``(2, n_1, ..., n_g)``.
        S_maps: ``(N + 1, 2, n_1, ..., n_g)`` AMSIP per layer (float32; ``collision_value`` where
            unreachable).
        reachable: ``(N + 1, 2, n_1, ...)`` cells reachable from ``q0`` (layer 0: none; ``q0`` is layer 0).
        viable: ``(N + 1, 2, n_1, ...)`` reachable cells from which the motion can still be continued
            to ``t_K`` (the end, or the dead end).
        exists: whether a collision-free motion from ``q0`` to ``t_N`` exists (in the DP's model).
        dead_end: when it does not, the last time [s] the arm can still be at (``t_0``: not even one
            step); ``None`` when it does.
        best_min_S: ``S*``: the best minimum S over ``t_1 .. t_K`` (``nan`` if no step is possible).
        motion: the best motion (to ``t_K``, the dead end when no motion exists).
        q0_S: AMSIP of ``q0`` at ``t_0``.
        end_families: components at ``t_K`` reachable from ``q0`` (``t_K``: the end, or the dead end).
        commit_time: the last time [s] at which the arm can still reach two end families
            (``None`` with fewer than two).
        start_families: components of the feasible cells at ``t_0``.
        dt: time step [s].
        joint_step: ``(n,)`` per-step joint bound ``δ_j`` [rad] (``inf``: no limit).
        gene_cells: ``(g,)`` gene cells per step ``r_a``.
        edges: number of allowed transitions per step ``(N,)``.
        timings: wall-clock seconds per stage (``maps``, ``edges``, ``dp``, ``families``) and in all
            (``total``), and the process CPU seconds (``cpu``; on a shared machine the fairer figure).
        options: the options used.
    """

    times: Array
    axes: tuple[Array, ...]
    shape: tuple[int, ...]
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
    start_families: tuple[Family, ...]
    dt: float
    joint_step: Array
    gene_cells: IntArray
    edges: IntArray
    timings: dict[str, float] = field(default_factory=dict)
    options: ReachOptions = field(default_factory=ReachOptions)

    @property
    def gene_speed(self) -> Array:
        """The largest gene speed [rad/s] the transition model allows, ``r_a h / Δt``, per gene."""
        return np.asarray(self.gene_cells * math.radians(self.options.resolution_deg) / self.dt, dtype=float)

    def verdict(self) -> str:
        """One line: whether a motion exists, else where the arm gets stuck."""
        if self.exists:
            return f"a collision-free tracking motion exists from q0 to t = {self.times[-1]:g} s"
        if self.dead_end is None or self.dead_end <= self.times[0]:
            return "no collision-free step from q0 at all"
        return f"no collision-free tracking motion from q0: every motion is stuck by t = {self.dead_end:g} s"


# ------------------------------------------------------------------------------------- layers


@dataclass(frozen=True)
class _Layer:
    """The feasible cells of one layer, compactly (``m`` cells)."""

    t: float
    S_map: NDArray[np.float32]  # (2 C,)
    cells: IntArray  # (m,) flat indices, increasing
    lut: NDArray[np.int32]  # (2 C,) rank of a flat index among ``cells``, -1 if infeasible
    gene_index: IntArray  # (m, g)
    branch: NDArray[np.int32]  # (m,)
    q: Array  # (m, n)
    q1: Array  # (m,) q_(n-1) [rad], contiguous
    beta: Array  # (m,)
    d_t: Array  # (L, m) capsule distances [m], one contiguous row per capsule
    S: Array  # (m,)
    beta_map: Array  # (2 C,) signed elbow angle where reachable, nan elsewhere


@dataclass(frozen=True)
class _Model:
    """Transition model constants."""

    shape: tuple[int, ...]  # (n_1, ..., n_g)
    cells: int  # C
    periodic: BoolArray  # (g,)
    h: float  # [rad]
    delta: Array  # (n,) per-step joint bound [rad]
    r: IntArray  # (g,)
    rho: Array  # (n, L)
    wrap_elbow1: bool  # q_(n-1) compared modulo 2 pi
    offsets: IntArray  # (K, g)
    offset_sweep: Array  # (K, L) Σ_a |o_a| h ρ_al
    neighbours: NDArray[np.int32]  # (K, C) gene-flat index of cell + offset (-1 off a non-periodic edge)


def signed_elbow(red: PlanarRedundancy, Q: Array, branch: IntArray) -> Array:
    """Signed elbow angle ``β`` [rad] of configurations ``(B, n)`` on ``branch`` ``(B,)``: ``|β|`` in [0, π],
    positive on branch 0 and negative on branch 1 (``q_n = β + α_1 - α_2``)."""
    magnitude = np.abs(wrap_angle(Q[:, red.n - 1] - red.alpha1 + red.alpha2))
    return np.where(branch == 0, magnitude, -magnitude)


def _sweep_radii(robot: Robot) -> Array:
    """``ρ`` ``(n, L)`` [m]: an upper bound on the distance from joint ``j`` to any point of guarded capsule
    ``l`` (0 when joint ``j`` does not move it), whatever the configuration."""
    chain = robot.planar
    assert chain is not None  # checked by the caller
    n = robot.nq
    lengths = np.hypot(chain.offsets[:, 0], chain.offsets[:, 1])  # |offset_k|: joint k-1 -> joint k
    rho = np.zeros((n, len(chain.link_joints)))
    for l_idx, (carrier, segment, radius) in enumerate(
        zip(chain.link_joints, chain.link_segments, chain.link_radii, strict=True)
    ):
        reach = float(np.max(np.hypot(segment[:, 0], segment[:, 1]))) + float(radius)
        for j in range(carrier + 1):
            rho[j, l_idx] = float(np.sum(lengths[j + 1 : carrier + 1])) + reach
    return rho


def _neighbour_table(shape: tuple[int, ...], periodic: BoolArray, offsets: IntArray) -> NDArray[np.int32]:
    """``(K, C)`` flat gene index of every cell moved by every offset (periodic genes wrap; ``-1`` where a
    non-periodic gene leaves its range)."""
    C = int(np.prod(shape)) if shape else 1
    if not shape:
        return np.zeros((len(offsets), 1), dtype=np.int32)
    index = np.stack(np.unravel_index(np.arange(C), shape), axis=1)  # (C, g)
    moved = index[None, :, :] + offsets[:, None, :]  # (K, C, g)
    valid = np.ones(moved.shape[:2], dtype=bool)
    for a, size in enumerate(shape):
        if periodic[a]:
            moved[..., a] %= size
        else:
            valid &= (moved[..., a] >= 0) & (moved[..., a] < size)
            np.clip(moved[..., a], 0, size - 1, out=moved[..., a])
    flat = np.ravel_multi_index(tuple(moved[..., a] for a in range(len(shape))), shape)
    return np.where(valid, flat, -1).astype(np.int32)


def _grid_axes(red: PlanarRedundancy, h: float) -> tuple[Array, ...]:
    axes: list[Array] = []
    for lo, hi, per in zip(red.gene_lower, red.gene_upper, red.periodic, strict=True):
        if per:
            count = max(1, round(TWO_PI / h))
            axes.append(np.arange(count, dtype=np.float64) * (TWO_PI / count))
        else:
            count = max(1, int(np.floor((hi - lo) / h + 1e-9)) + 1)
            axes.append(lo + np.arange(count) * h)
    return tuple(axes)


def _layer(red: PlanarRedundancy, evaluator: Evaluator, axes: tuple[Array, ...], target: Array, t: float,
           s_min: float) -> _Layer:
    """Solve and score the whole grid at time ``t`` [s]; keep the cells with ``S > s_min``."""
    if axes:
        Q, reach = red.solve_grid(axes, target)
    else:  # a two-link arm: one cell per branch
        Q, reach = red.solve(np.zeros((2, 0)), np.array([0, 1]), target)
    total = Q.shape[0]
    C = total // 2
    S = np.full(total, evaluator.potential.collision_value)
    L = len(evaluator.robot.guarded_links)
    d = np.full((total, L), -np.inf)
    if reach.any():
        ev = evaluator(Q[reach], t)
        S[reach], d[reach] = ev.S, ev.link_distances
    branch_all = np.repeat(np.arange(2), C)
    beta_map = np.where(reach, signed_elbow(red, Q, branch_all), np.nan)
    feasible = reach & (s_min < S)
    cells = np.flatnonzero(feasible).astype(np.int64)
    lut = np.full(total, -1, dtype=np.int32)
    lut[cells] = np.arange(cells.size, dtype=np.int32)
    shape = tuple(len(a) for a in axes)
    gene_index = (np.stack(np.unravel_index(cells % C, shape), axis=1).astype(np.int64) if axes
                  else np.zeros((cells.size, 0), dtype=np.int64))
    return _Layer(
        t=float(t), S_map=S.astype(np.float32), cells=cells, lut=lut, gene_index=gene_index,
        branch=(cells // C).astype(np.int32), q=Q[cells], q1=np.ascontiguousarray(Q[cells, red.n - 2]),
        beta=beta_map[cells], d_t=np.ascontiguousarray(d[cells].T), S=S[cells],
        beta_map=beta_map,
    )


def _obstacle_travel(scene: Scene, t0: float, t1: float, substeps: int) -> float:
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


# -------------------------------------------------------------------------------------- edges


def _step_ok(model: _Model, dst: _Layer, d_rows: IntArray, gene_sweep: Array, src_q1: Array, src_beta: Array,
             src_d: Array, travel: float) -> BoolArray:
    """The joint-speed and sweep conditions of ``P`` candidate steps into rows ``d_rows`` of ``dst``.

    Args:
        model: the transition model.
        dst: the destination layer.
        d_rows: ``(P,)`` destination rows.
        gene_sweep: ``(P, L)`` [m], the genes' share of the sweep bound ``B_l``.
        src_q1: ``(P,)`` the sources' ``q_(n-1)`` [rad].
        src_beta: ``(P,)`` the sources' signed elbow angles [rad].
        src_d: ``(L, P)`` the sources' capsule distances [m] (a source may be ``q0``).
        travel: bound [m] on the obstacles' motion during the step.
    """
    g = model.periodic.size
    d_q1 = dst.q1[d_rows] - src_q1
    if model.wrap_elbow1:
        d_q1 -= TWO_PI * np.rint(d_q1 * (1.0 / TWO_PI))
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
    return ok


@dataclass(frozen=True)
class _Edges:
    """The allowed transitions of one step, in groups (one per gene offset and branch choice) within
    which every source row and every destination row occurs at most once, so a group is applied with
    plain fancy indexing (``out[dst] = max(out[dst], value[src])``) instead of the slower ``ufunc.at``."""

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


def _grid_edges(model: _Model, src: _Layer, dst: _Layer, travel: float) -> _Edges:
    """Allowed transitions from the feasible cells of ``src`` to those of ``dst``, one group per gene offset
    (same branch) and per gene offset and elbow switch (sources near the stretched wrist)."""
    g = model.periodic.size
    C = model.cells
    gene_flat = (src.cells % C).astype(np.int32)
    near = np.flatnonzero(np.abs(src.beta) <= model.delta[g + 1]).astype(np.int32)
    sources = [(np.arange(src.cells.size, dtype=np.int32), src.branch * C)]
    if near.size:
        sources.append((near, (1 - src.branch[near]) * C))
    out_s: list[NDArray[np.int32]] = []
    out_d: list[NDArray[np.int32]] = []
    for candidates, base in sources:
        flat_genes = gene_flat[candidates]
        for k in range(len(model.offsets)):
            target = model.neighbours[k][flat_genes]
            d_rows = dst.lut[base + target]
            hit = d_rows >= 0
            if not model.periodic.all():
                hit &= target >= 0
            rows = candidates[hit]
            d_rows = d_rows[hit]
            sweep = np.broadcast_to(model.offset_sweep[k], (rows.size, model.rho.shape[1]))
            ok = _step_ok(model, dst, d_rows, sweep, src.q1[rows], src.beta[rows], src.d_t[:, rows], travel)
            out_s.append(rows[ok])
            out_d.append(d_rows[ok])
    sizes = np.array([0] + [x.size for x in out_s], dtype=np.int64)
    return _Edges(np.concatenate(out_s), np.concatenate(out_d), np.cumsum(sizes))


def _start_edges(model: _Model, axes: tuple[Array, ...], q0: Array, beta0: float, d0: Array, dst: _Layer,
                 travel: float) -> NDArray[np.int32]:
    """Destination rows of ``dst`` reachable from ``q0`` in one step."""
    g = model.periodic.size
    rows = np.arange(dst.cells.size, dtype=np.int64)
    gene_sweep = np.zeros((rows.size, model.rho.shape[1]))
    ok = np.ones(rows.size, dtype=bool)
    for a in range(g):
        value = axes[a][dst.gene_index[:, a]]
        diff = value - q0[a]
        diff = np.abs(wrap_angle(diff) if model.periodic[a] else diff)
        ok &= diff <= model.r[a] * model.h + 1e-12
        gene_sweep += diff[:, None] * model.rho[a]
    ok &= _step_ok(model, dst, rows, gene_sweep, np.full(rows.size, q0[g]), np.full(rows.size, beta0),
                   np.repeat(np.asarray(d0, dtype=float)[:, None], rows.size, axis=1), travel)
    return rows[ok].astype(np.int32)


# ------------------------------------------------------------------------------------ families


def _components(layer: _Layer, mask: BoolArray, model: _Model, cross_beta: float) -> IntArray:
    """Connected components of the layer's cells selected by ``mask`` ``(m,)``.

    Adjacency: the 3^g - 1 grid neighbours within a branch (periodic genes wrap), and the two
    branches of one grid cell where ``|β| <= cross_beta`` on both. Returns labels ``(m,)``: ``-1``
    outside the mask, else ``0 .. K - 1`` by decreasing component size.
    """
    g = model.periodic.size
    C = model.cells
    rows = np.flatnonzero(mask)
    labels = np.full(mask.size, -1, dtype=np.int64)
    if rows.size == 0:
        return labels
    selected = np.full(layer.lut.size, -1, dtype=np.int64)
    selected[layer.cells[rows]] = rows
    strides = np.array([int(np.prod(model.shape[a + 1 :])) for a in range(g)], dtype=np.int64)
    us: list[IntArray] = []
    vs: list[IntArray] = []
    for offset in np.ndindex(*(3,) * g):
        shift = np.array(offset, dtype=np.int64) - 1
        nonzero = np.flatnonzero(shift)
        if nonzero.size == 0 or shift[nonzero[0]] < 0:  # one of each opposite pair
            continue
        valid = np.ones(rows.size, dtype=bool)
        flat = np.zeros(rows.size, dtype=np.int64)
        for a in range(g):
            index = layer.gene_index[rows, a] + shift[a]
            if model.periodic[a]:
                index %= model.shape[a]
            else:
                valid &= (index >= 0) & (index < model.shape[a])
                index = np.clip(index, 0, model.shape[a] - 1)
            flat += index * strides[a]
        other = selected[layer.branch[rows] * C + flat]
        keep = valid & (other >= 0)
        us.append(rows[keep])
        vs.append(other[keep])
    straight = rows[(layer.branch[rows] == 0) & (np.abs(layer.beta[rows]) <= cross_beta)]
    partner = selected[layer.cells[straight] + C]
    keep = partner >= 0
    keep[keep] &= np.abs(layer.beta[partner[keep]]) <= cross_beta
    us.append(straight[keep])
    vs.append(partner[keep])
    u, v = np.concatenate(us), np.concatenate(vs)
    parent = np.arange(mask.size, dtype=np.int64)
    while True:  # hook roots onto the smaller root, then jump pointers to the roots
        ru, rv = parent[u], parent[v]
        differ = ru != rv
        if not differ.any():
            break
        lo, hi = np.minimum(ru[differ], rv[differ]), np.maximum(ru[differ], rv[differ])
        np.minimum.at(parent, hi, lo)
        while True:
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped
    roots = parent[rows]
    unique, inverse, counts = np.unique(roots, return_inverse=True, return_counts=True)
    order = np.argsort(-counts, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels[rows] = rank[inverse]
    del unique
    return labels


def _bits(labels: IntArray) -> NDArray[np.uint64]:
    """One bit per label (labels beyond :data:`MAX_FAMILY_BITS` - 1 share the last bit); 0 for -1."""
    capped = np.minimum(labels, MAX_FAMILY_BITS - 1)
    return np.where(labels >= 0, np.left_shift(np.uint64(1), np.maximum(capped, 0).astype(np.uint64)),
                    np.uint64(0)).astype(np.uint64)


# --------------------------------------------------------------------------------------- main


def reach_over_time(
    robot: Robot,
    evaluator: Evaluator,
    path: HandPath,
    q0: Array,
    duration: float,
    options: ReachOptions | None = None,
    *,
    t_start: float = 0.0,
) -> ReachResult:
    """Reachability over the redundancy grid x time from ``q0`` (see the module docstring).

    Args:
        robot: a planar arm with at most 2 genes (2 to 4 joints).
        evaluator: AMSIP evaluator (robot, scene, index, potential) -- the scene and hand target at
            each layer time are read from it and from ``path``.
        path: the desired hand path.
        q0: start configuration ``(n,)`` [rad] at ``t_start``.
        duration: horizon [s]; layers at ``t_start + k duration / N``.
        options: grid and transition model.
        t_start: start time [s].

    Returns:
        The verdict, the best motion, the families and commit time, and the maps.

    Raises:
        PlanarOnlyError: a spatial arm, or a planar arm with more than 2 genes.
        ConfigurationError: a bad option, duration or ``q0``; a time step too short for the grid.
    """
    started, cpu_started = time.perf_counter(), time.process_time()
    opts = options or ReachOptions()
    if robot.planar is None:
        raise PlanarOnlyError(f"reach-map: planar arms only (robot {robot.name!r} is spatial)")
    red = PlanarRedundancy(robot)
    g, n = red.g, red.n
    if g > 2:
        raise PlanarOnlyError(f"reach-map: planar arms of 2 to 4 joints only (robot {robot.name!r} has {n} joints, "
                              f"{g} genes: the grid would have {g} dimensions)")
    if not (math.isfinite(duration) and duration > 0):
        raise ConfigurationError(f"duration must be a positive number of seconds, got {duration!r}")
    Q0, _ = robot.check_configurations(q0)
    q0 = Q0[0]
    N = opts.steps
    dt = duration / N
    h = math.radians(opts.resolution_deg)
    limits = np.asarray(robot.velocity_limits, dtype=float)
    limits = np.where(np.isfinite(limits) & (limits > 0), limits * opts.velocity_scale, np.inf)
    delta = limits * dt
    r = np.array([min(opts.max_step_cells, math.floor(delta[a] / h + 1e-9)) if np.isfinite(delta[a])
                  else opts.max_step_cells for a in range(g)], dtype=np.int64)
    if np.any(r < 1):
        a = int(np.flatnonzero(r < 1)[0])
        raise ConfigurationError(
            f"time step {dt:.4g} s lets joint {a + 1} move only {math.degrees(delta[a]):.3g} deg, less than the grid "
            f"step {opts.resolution_deg:g} deg: use fewer steps (now {N}) or a finer resolution")
    axes = _grid_axes(red, h)
    shape = tuple(len(a) for a in axes)
    offsets = (np.array(list(np.ndindex(*(2 * r + 1))), dtype=np.int64) - r if g
               else np.zeros((1, 0), dtype=np.int64))
    rho = _sweep_radii(robot)
    model = _Model(
        shape=shape, cells=int(np.prod(shape)) if g else 1, periodic=np.asarray(red.periodic, dtype=bool), h=h,
        delta=delta, r=r, rho=rho,
        wrap_elbow1=bool(red.upper[g] - red.lower[g] >= TWO_PI - 1e-9), offsets=offsets,
        offset_sweep=(np.abs(offsets) * h) @ rho[:g] if g else np.zeros((1, rho.shape[1])),
        neighbours=_neighbour_table(shape, np.asarray(red.periodic, dtype=bool), offsets),
    )
    times: Array = t_start + np.arange(N + 1, dtype=np.float64) * dt
    scene = evaluator.scene

    # ---- maps
    layers = [_layer(red, evaluator, axes, np.asarray(path.position(t), float), float(t), opts.s_min) for t in times]
    t_maps = time.perf_counter()

    # ---- edges
    ev0 = evaluator(q0[None, :], float(times[0]))
    q0_S = float(ev0.S[0])
    genes0, branch0 = red.genes_of(q0[None, :])
    beta0 = float(signed_elbow(red, q0[None, :], branch0)[0])
    travel = [_obstacle_travel(scene, float(times[k]), float(times[k + 1]), opts.obstacle_substeps) for k in range(N)]
    start_rows = _start_edges(model, axes, np.concatenate([genes0[0], q0[g:]]), beta0, ev0.link_distances[0],
                              layers[1], travel[0])
    grid0_edges = _grid_edges(model, layers[0], layers[1], travel[0])
    edges = [grid0_edges] + [_grid_edges(model, layers[k], layers[k + 1], travel[k]) for k in range(1, N)]
    # edges[0] is from the grid at t_0 (start families); q0 -> layer 1 is ``start_rows``
    t_edges = time.perf_counter()

    # ---- (a) forward max-min from q0
    W: list[Array] = [np.array([np.inf])]
    first = np.full(layers[1].cells.size, -np.inf)
    first[start_rows] = layers[1].S[start_rows]
    W.append(first)
    for k in range(1, N):
        W.append(np.minimum(edges[k].push_max(W[k], layers[k + 1].cells.size), layers[k + 1].S))
    reached = [bool(np.any(w > -np.inf)) for w in W]
    K = max(k for k in range(N + 1) if reached[k])
    exists = K == N

    # ---- (c) best motion: max min S, then max total S
    if K >= 1:
        s_star = float(np.max(W[K]))
        Z: list[Array] = [np.zeros(0)] * (K + 1)
        Z[K] = np.where(W[K] >= s_star, layers[K].S, -np.inf)
        for k in range(K - 1, 0, -1):
            best = edges[k].pull_max(Z[k + 1], layers[k].cells.size)
            Z[k] = np.where(W[k] >= s_star, layers[k].S + best, -np.inf)
        path_rows = [int(start_rows[int(np.argmax(Z[1][start_rows]))])]
        for k in range(1, K):
            out = edges[k].dst[edges[k].src == path_rows[-1]]
            path_rows.append(int(out[int(np.argmax(Z[k + 1][out]))]))
    else:
        s_star = float("nan")
        path_rows = []
    motion = _motion(model, layers, times, q0, q0_S, beta0, int(branch0[0]), path_rows)
    t_dp = time.perf_counter()

    # ---- (b) end families (at t_K: the end, or the dead end), viable tube, commit time
    reachable_masks = [np.zeros(0, dtype=bool)] + [w > -np.inf for w in W[1:]]
    viable_masks = [np.zeros(layer.cells.size, dtype=bool) for layer in layers]
    end_families: list[Family] = []
    commit_time: float | None = None
    if K >= 1:
        labels = _components(layers[K], reachable_masks[K], model, math.radians(opts.cross_adjacency_deg))
        A: list[NDArray[np.uint64]] = [np.zeros(0, dtype=np.uint64)] * (K + 1)
        A[K] = _bits(labels)
        for k in range(K - 1, 0, -1):
            A[k] = np.where(reachable_masks[k], edges[k].pull_or(A[k + 1], layers[k].cells.size), np.uint64(0))
        q0_bits = np.bitwise_or.reduce(A[1][start_rows])
        counts = [np.bitwise_count(a) for a in A]
        many = [False] + [bool(np.any(counts[k] >= 2)) for k in range(1, K + 1)]
        many[0] = int(np.bitwise_count(q0_bits)) >= 2
        commit_time = float(times[max(k for k in range(K + 1) if many[k])]) if any(many) else None
        for k in range(1, K + 1):
            viable_masks[k] = A[k] != 0
        for label in range(int(labels.max()) + 1):
            members = np.flatnonzero(labels == label)
            bit = np.uint64(1) << np.uint64(min(label, MAX_FAMILY_BITS - 1))
            when = [k for k in range(1, K + 1) if np.any(((A[k] & bit) != 0) & (counts[k] >= 2))]
            if not when and many[0]:
                when = [0]
            end_families.append(_family_of(label + 1, layers[K], members, axes,
                                           shared_until=float(times[max(when)]) if when else None,
                                           best_min_S=float(np.max(W[K][members]))))

    # ---- start families: components at t_0 and their fate
    start_labels = _components(layers[0], np.ones(layers[0].cells.size, dtype=bool), model,
                               math.radians(opts.cross_adjacency_deg))
    start_families: list[Family] = []
    if layers[0].cells.size:
        F = _bits(start_labels)
        alive = np.zeros(N + 1, dtype=np.uint64)
        shared = np.zeros(N + 1, dtype=np.uint64)
        alive[0] = np.bitwise_or.reduce(F)
        for k in range(N):
            F = edges[k].push_or(F, layers[k + 1].cells.size)
            alive[k + 1] = np.bitwise_or.reduce(F) if F.size else np.uint64(0)
            multi = F[np.bitwise_count(F) >= 2]
            shared[k + 1] = np.bitwise_or.reduce(multi) if multi.size else np.uint64(0)
        home = _nearest_cell(model, axes, genes0[0], int(branch0[0]))
        home_row = int(layers[0].lut[home])
        home_label = int(start_labels[home_row]) if home_row >= 0 else -1
        for label in range(int(start_labels.max()) + 1 if start_labels.size else 0):
            members = np.flatnonzero(start_labels == label)
            bit = np.uint64(1) << np.uint64(min(label, MAX_FAMILY_BITS - 1))
            alive_k = [k for k in range(N + 1) if alive[k] & bit]
            shared_k2 = [k for k in range(1, N + 1) if shared[k] & bit]
            start_families.append(_family_of(
                label + 1, layers[0], members, axes, alive_until=float(times[max(alive_k)]),
                finishes=max(alive_k) == N, shared_until=float(times[max(shared_k2)]) if shared_k2 else None,
                holds_q0=label == home_label))
    t_families = time.perf_counter()

    full = (N + 1, 2, *shape)

    def grid_of(masks: list[BoolArray]) -> BoolArray:
        out = np.zeros((N + 1, 2 * model.cells), dtype=bool)
        for k, (layer, mask) in enumerate(zip(layers, masks, strict=True)):
            if mask.size:
                out[k, layer.cells[mask]] = True
        return out.reshape(full)

    return ReachResult(
        times=times,
        axes=axes,
        shape=(2, *shape),
        S_maps=np.stack([layer.S_map for layer in layers]).reshape(full),
        reachable=grid_of(reachable_masks),
        viable=grid_of(viable_masks),
        exists=exists,
        dead_end=None if exists else float(times[K]),
        best_min_S=s_star,
        motion=motion,
        q0_S=q0_S,
        end_families=tuple(end_families),
        commit_time=commit_time,
        start_families=tuple(start_families),
        dt=dt,
        joint_step=delta,
        gene_cells=r,
        edges=np.array([start_rows.size, *(e.size for e in edges[1:])], dtype=np.int64),
        timings={
            "maps": t_maps - started,
            "edges": t_edges - t_maps,
            "dp": t_dp - t_edges,
            "families": t_families - t_dp,
            "total": time.perf_counter() - started,
            "cpu": time.process_time() - cpu_started,
        },
        options=opts,
    )


def _nearest_cell(model: _Model, axes: tuple[Array, ...], genes: Array, branch: int) -> int:
    """Flat index of the grid cell nearest to ``genes`` on ``branch``."""
    flat = 0
    for a, axis in enumerate(axes):
        if model.periodic[a]:
            index = round(float(np.mod(genes[a] - axis[0], TWO_PI)) / model.h) % len(axis)
        else:
            index = int(np.clip(round((genes[a] - axis[0]) / model.h), 0, len(axis) - 1))
        flat = flat * len(axis) + index
    return branch * model.cells + flat


def _family_of(label: int, layer: _Layer, members: IntArray, axes: tuple[Array, ...], **extra: object) -> Family:
    best = int(members[int(np.argmax(layer.S[members]))])
    genes = np.array([axes[a][layer.gene_index[best, a]] for a in range(len(axes))], dtype=float)
    return Family(label=label, cells=int(members.size), peak_genes=genes, peak_branch=int(layer.branch[best]),
                  peak_S=float(layer.S[best]), **extra)  # type: ignore[arg-type]


def _motion(model: _Model, layers: list[_Layer], times: Array, q0: Array, q0_S: float,
            beta0: float, branch0: int, rows: list[int]) -> ReachMotion:
    """The motion through ``rows`` (one per layer 1..K), unwrapped from ``q0``."""
    g = model.periodic.size
    K = len(rows)
    q = np.empty((K + 1, q0.size))
    q[0] = q0
    S = np.empty(K + 1)
    S[0] = q0_S
    branch = np.empty(K + 1, dtype=np.int64)
    branch[0] = branch0
    cells = np.full(K + 1, -1, dtype=np.int64)
    beta_prev = beta0
    for k, row in enumerate(rows, start=1):
        layer = layers[k]
        target = layer.q[row]
        step = target - q[k - 1]
        for a in range(g):
            if model.periodic[a]:
                step[a] = float(wrap_angle(step[a]))
        if model.wrap_elbow1:
            step[g] = float(wrap_angle(step[g]))
        step[g + 1] = layer.beta[row] - beta_prev
        beta_prev = float(layer.beta[row])
        q[k] = q[k - 1] + step
        S[k] = layer.S[row]
        branch[k] = layer.branch[row]
        cells[k] = layer.cells[row]
    return ReachMotion(times=times[: K + 1].copy(), q=q, S=S, branch=branch, cells=cells,
                       min_S=float(S[1:].min()) if K else float("nan"),
                       total_S=float(S[1:].sum()) if K else 0.0)
