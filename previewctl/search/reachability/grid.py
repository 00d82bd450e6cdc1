"""The grid model: the gene axes, the copies of ``q_(n-1)``, the flat cell index and the per-step bounds.

A *cell* is a gene grid point on one elbow branch (flat index ``branch * C + gene``, ``C`` the gene grid's
size); a *state* is a cell and a representative ``m`` of ``q_(n-1) = a + 2π m`` (flat index
``row * M + m`` within a layer). The model also holds the constants of the transition model: the joint
bounds per step ``δ_j``, the gene cells per step ``r_a`` and the sweep radii ``ρ_jl`` (see
:mod:`previewctl.search.reachability` for every definition).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.robot.model import Robot
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability.options import PlanarOnlyError, ReachOptions
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array, BoolArray, IntArray


@dataclass(frozen=True)
class GridModel:
    """Grid and transition-model constants."""

    axes: tuple[Array, ...]  # the DP's gene axes [rad], over the joint limits when they are finite
    shape: tuple[int, ...]  # (n_1, ..., n_g) of the DP's gene grid
    cells: int  # C = n_1 ... n_g
    periodic: BoolArray  # (g,) genes without finite limits: axis over [0, 2 pi), wrapped
    h: float  # grid step [rad]
    delta: Array  # (n,) per-step joint bound [rad]
    r: IntArray  # (g,) gene cells per step
    rho: Array  # (n, L) sweep radii [m]
    offsets: IntArray  # (K, g) gene offsets of one step
    offset_sweep: Array  # (K, L) Σ_a |o_a| h ρ_al [m]
    strides: IntArray  # (g,) of the flat gene index
    q1_periodic: bool  # q_(n-1) without finite limits: compared modulo 2 pi, one representative
    reps: IntArray  # (M,) shifts m of the representatives a + 2 pi m of q_(n-1) (a in [-pi, pi))
    q1_limits: tuple[float, float]  # [rad]
    elbow_offset: float  # c: q_n = beta + c along every motion from q0 [rad]
    qn_limits: tuple[float, float]  # [rad]

    @property
    def M(self) -> int:  # noqa: N802 -- the number of representatives, as in the docstring
        return int(self.reps.size)


@dataclass(frozen=True)
class Start:
    """The start configuration ``q0`` as the grid sees it.

    Attributes:
        q: ``(n,)`` ``q0`` [rad].
        grid_q: ``(n,)`` ``q0`` with its periodic genes wrapped like the grid's (bounded genes and the last
            two joints: ``q0``'s own values) [rad].
        beta: its signed elbow angle [rad].
        branch: its elbow branch.
    """

    q: Array
    grid_q: Array
    beta: float
    branch: int


MAX_GRID_NODES = 2**25
"""Most nodes (cells x branches x layers) of one reachability grid: its per-node arrays stay within a few
hundred MB (the default 2 deg grid of planar4 with 50 steps has 3.3 million)."""


def grid_model(robot: Robot, red: PlanarRedundancy, opts: ReachOptions, dt: float,
               q0: Array) -> tuple[GridModel, Start]:
    """The grid and transition model of steps of ``dt`` [s] from ``q0``, and ``q0`` on it.

    Raises:
        ConfigurationError: the time step lets a gene move less than one grid step, or more than
            :data:`MAX_GRID_NODES` nodes.
    """
    g, n = red.g, red.n
    h = math.radians(opts.resolution_deg)
    delta, r = _joint_steps(robot, opts, dt, g)
    axes, periodic = gene_axes(red, h)
    shape = tuple(len(a) for a in axes)
    total = grid_nodes(red, opts)
    if total > MAX_GRID_NODES:
        raise ConfigurationError(
            f"resolution_deg = {opts.resolution_deg:g} and steps = {opts.steps} make {total:,} grid nodes "
            f"({' x '.join(map(str, shape))} cells x {red.branches} branches x {opts.steps + 1} layers), more than "
            f"{MAX_GRID_NODES:,}: use a coarser resolution or fewer steps")
    offsets = (np.array(list(np.ndindex(*(2 * r + 1))), dtype=np.int64) - r if g
               else np.zeros((1, 0), dtype=np.int64))
    rho = sweep_radii(robot)
    genes0, branch0 = red.genes_of(q0[None, :])
    beta0 = float(signed_elbow(red, q0[None, :], branch0)[0])
    lower, upper = robot.lower_limits, robot.upper_limits
    lo1, hi1 = float(lower[n - 2]), float(upper[n - 2])
    q1_periodic = not bounded(lo1, hi1)
    model = GridModel(
        axes=axes, shape=shape, cells=int(np.prod(shape)) if g else 1, periodic=periodic, h=h, delta=delta, r=r,
        rho=rho, offsets=offsets,
        offset_sweep=(np.abs(offsets) * h) @ rho[:g] if g else np.zeros((1, rho.shape[1])),
        strides=np.array([int(np.prod(shape[a + 1 :])) for a in range(g)], dtype=np.int64),
        q1_periodic=q1_periodic, reps=_representatives(lo1, hi1, q1_periodic), q1_limits=(lo1, hi1),
        elbow_offset=float(q0[n - 1] - beta0), qn_limits=(float(lower[n - 1]), float(upper[n - 1])),
    )
    grid_q = np.concatenate([np.where(periodic, genes0[0], q0[:g]), q0[g:]])  # bounded genes: q0's own values
    return model, Start(q=q0, grid_q=grid_q, beta=beta0, branch=int(branch0[0]))


def _joint_steps(robot: Robot, opts: ReachOptions, dt: float, g: int) -> tuple[Array, IntArray]:
    """The per-step joint bounds ``δ_j = v_j Δt`` ``(n,)`` [rad] (``inf``: no limit) and the gene cells per
    step ``r_a`` ``(g,)``.

    Raises:
        ConfigurationError: some ``r_a < 1`` (the message says which joint and what to change).
    """
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
            f"step {opts.resolution_deg:g} deg: use fewer steps (now {opts.steps}) or a finer resolution")
    return delta, r


def _representatives(lo: float, hi: float, periodic: bool) -> IntArray:
    """The shifts ``m`` such that ``a + 2π m`` lies within ``[lo, hi]`` for some ``a`` in ``[-π, π)`` (one,
    ``0``, for a joint without finite limits)."""
    if periodic:
        return np.zeros(1, dtype=np.int64)
    return np.arange(math.ceil((lo - np.pi) / TWO_PI), math.floor((hi + np.pi) / TWO_PI) + 1, dtype=np.int64)


def signed_elbow(red: PlanarRedundancy, Q: Array, branch: NDArray[np.integer[Any]]) -> Array:
    """Signed elbow angle ``β`` [rad] of configurations ``(B, n)`` on ``branch`` ``(B,)``: ``|β|`` in [0, π],
    positive on branch 0 and negative on branch 1 (``q_n = β + α_1 - α_2`` modulo 2π)."""
    magnitude = np.abs(wrap_angle(Q[:, red.n - 1] - red.alpha1 + red.alpha2))
    return np.where(branch == 0, magnitude, -magnitude)


def sweep_radii(robot: Robot) -> Array:
    """``ρ`` ``(n, L)`` [m]: an upper bound on the distance from joint ``j`` to any point of guarded capsule
    ``l`` (0 when joint ``j`` does not move it), whatever the configuration."""
    chain = robot.planar
    if chain is None:  # pragma: no cover - checked by the caller
        raise PlanarOnlyError(f"robot {robot.name!r} is not planar")
    lengths = np.hypot(chain.offsets[:, 0], chain.offsets[:, 1])  # |offset_k|: joint k-1 -> joint k
    rho = np.zeros((robot.nq, len(chain.link_joints)))
    for l_idx, (carrier, segment, radius) in enumerate(
        zip(chain.link_joints, chain.link_segments, chain.link_radii, strict=True)
    ):
        reach = float(np.max(np.hypot(segment[:, 0], segment[:, 1]))) + float(radius)
        for j in range(carrier + 1):
            rho[j, l_idx] = float(np.sum(lengths[j + 1 : carrier + 1])) + reach
    return rho


def bounded(lo: float, hi: float) -> bool:
    """Whether both limits are finite."""
    return bool(np.isfinite(lo) and np.isfinite(hi))


def fast_enough(robot: Robot, opts: ReachOptions, duration: float, share: float) -> ReachOptions:
    """``opts`` with enough steps over ``duration`` [s] that a gene may move at ``share`` of its joint speed limit
    (``max_step_cells · h / Δt >= share · v_a``; never fewer steps than ``opts.steps``), on the finest grid of
    ``h``, ``2h``, ``4h``, ... whose nodes fit :data:`MAX_GRID_NODES` (the coarsest tried is 90°)."""
    red = PlanarRedundancy(robot)
    limits = robot.velocity_limits[: red.g] * opts.velocity_scale * share
    speed = float(np.max(limits[np.isfinite(limits)], initial=0.0))
    resolution = opts.resolution_deg
    while True:
        steps = max(opts.steps, math.ceil(duration * speed / (opts.max_step_cells * math.radians(resolution)) - 1e-9))
        candidate = replace(opts, resolution_deg=resolution, steps=steps)
        if grid_nodes(red, candidate) <= MAX_GRID_NODES or 2 * resolution > 90:
            return candidate
        resolution *= 2


def grid_nodes(red: PlanarRedundancy, opts: ReachOptions) -> int:
    """The nodes (cells x branches x layers) of the grid of ``opts`` (at most :data:`MAX_GRID_NODES` may be built)."""
    cells = int(np.prod([len(axis) for axis in gene_axes(red, math.radians(opts.resolution_deg))[0]]))
    return cells * int(red.branches) * (opts.steps + 1)


def gene_axes(red: PlanarRedundancy, h: float) -> tuple[tuple[Array, ...], BoolArray]:
    """The DP's gene axes [rad]: over the joint limits when they are finite (so a gene's value along a
    motion is the joint's own value, limits included), else periodic over ``[0, 2π)``."""
    axes: list[Array] = []
    periodic: list[bool] = []
    for lo, hi in zip(red.lower[: red.g], red.upper[: red.g], strict=True):
        if bounded(lo, hi):
            count = int(np.floor((hi - lo) / h + 1e-9)) + 1
            axes.append(lo + np.arange(count) * h)
            periodic.append(False)
        else:
            count = max(1, round(TWO_PI / h))
            axes.append(np.arange(count, dtype=np.float64) * (TWO_PI / count))
            periodic.append(True)
    return tuple(axes), np.array(periodic, dtype=bool)


def targets(model: GridModel, gene_index: IntArray, offset: IntArray) -> tuple[IntArray, BoolArray]:
    """Flat gene index of ``gene_index + offset`` and whether it lies on the grid: ``gene_index`` ``(m, g)``
    with one offset ``(g,)`` gives ``(m,)``, with ``K`` offsets ``(K, g)`` it gives ``(K, m)``."""
    offset = np.asarray(offset, dtype=np.int64)
    shape = offset.shape[:-1] + gene_index.shape[:1]
    flat = np.zeros(shape, dtype=np.int64)
    ok = np.ones(shape, dtype=bool)
    for a, size in enumerate(model.shape):
        index = gene_index[:, a] + offset[..., a, None]
        if model.periodic[a]:
            index %= size
        else:
            ok &= (index >= 0) & (index < size)
            np.clip(index, 0, size - 1, out=index)
        flat += index * model.strides[a]
    return flat, ok
