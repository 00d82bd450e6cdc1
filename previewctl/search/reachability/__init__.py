"""Reachability over time: dynamic programming over the planar redundancy grid x time (the global reference).

The paper's section 5.1 asks "whether the current configuration is reachable to the future optimal
configuration" and answers by looking at the AMSIP maps at ten times (Fig. 8, Table 1). This module
answers it exactly on a grid, for planar arms, offline and non-causally (it reads the whole future):

* **Space.** The redundancy grid of :class:`~previewctl.planar.redundancy.PlanarRedundancy`: the
  genes ``q_1 .. q_(n-2)`` on a ``h``-degree grid x the two elbow branches; the last two joints in
  closed form, so every cell puts the hand on the path. Joint limits hold along every motion: a
  gene's grid runs over its joint limits (planar4: ``[-360°, 360°]``, so a grid value *is* the joint
  value; only a gene without finite limits gets a periodic ``[0, 360)`` axis), ``q_n = β + c`` with the
  signed elbow angle ``β`` in ``[-π, π]`` never wraps, and ``q_(n-1)``, which the closed form gives
  modulo 2π as ``a`` in ``[-π, π)``, is carried by a *state* ``(cell, m)``: the arm is at ``a + 2π m``,
  and only the representatives within the joint's limits exist. (Without this a motion can wind a
  ``±2π`` joint past its limit: the first version's best motion on ``paper_planar`` took ``q_3`` to
  ``-400°``, and a controller following it was stopped by the limit.)
* **Time.** ``N`` steps of ``Δt = duration / N`` [s]; layer ``k`` holds the cells at ``t_k = t_0 + k Δt``
  with the obstacles and the hand target of that time. Layer 0 of the dynamic programme is the
  start configuration ``q0`` itself (not a grid cell); the grid at ``t_0`` is only used for the
  start families and the figures.
* **Feasible cells.** ``S > s_min`` (AMSIP, eq. 18; ``S < 0`` when colliding or unreachable).
* **Transitions** ``c -> c'`` from layer ``k`` to ``k + 1`` (all conditions, each conservative):

  1. joint speed (every joint, the closed-form last two included): ``|Δq_j| <= δ_j = v_j Δt``
     with ``v_j`` the URDF speed limit x ``velocity_scale`` [rad/s]. Genes move by whole cells,
     ``|Δi_a| <= r_a = min(floor(δ_a / h), max_step_cells)``: the cap ``max_step_cells`` bounds the
     work, and it is a further (reported) restriction when ``r_a h < δ_a``. ``q_(n-1)`` moves the
     short way, ``Δ = wrap(a' - a)``, ``|Δ| <= δ_(n-1)``, its representative following (``m' = m``, or
     ``m ± 1`` when the short way crosses ``±π``), and the new state must exist (within the limits).
     The elbow is compared through ``β`` (branch 0: ``β >= 0``, branch 1: ``β < 0``) *without*
     wrapping, so an elbow switch can only pass the stretched wrist ``β = 0``
     (``|β| + |β'| <= δ_n``), never the folded one (``β = ±π``).
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

The programme, over stored edge lists (one per step, built once, between states):

Every quantity below is per state (cell and representative); the figures fold states onto cells
over ``[0, 360)``. Layer ``k + 1`` is evaluated only at the cells one step away from the states
reachable at layer ``k`` (a lazy forward sweep: the DP from ``q0`` never needs the rest).

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

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.planar.redundancy import PlanarRedundancy
from previewctl.robot.joints import FULL_TURN as TWO_PI
from previewctl.robot.model import Robot
from previewctl.search.reachability.dp import best_states, forward
from previewctl.search.reachability.families import MAX_FAMILY_BITS, end_families, start_families
from previewctl.search.reachability.grid import GridModel, grid_model, signed_elbow
from previewctl.search.reachability.motion import motion_through
from previewctl.search.reachability.options import PlanarOnlyError, ReachOptions
from previewctl.search.reachability.problem import make_problem
from previewctl.search.reachability.result import Family, ReachMotion, ReachResult
from previewctl.types import Array, BoolArray, IntArray

__all__ = [
    "MAX_FAMILY_BITS",
    "Family",
    "PlanarOnlyError",
    "ReachMotion",
    "ReachOptions",
    "ReachResult",
    "reach_over_time",
    "signed_elbow",
]



# ------------------------------------------------------------------------------------- model


def _map_axes(g: int, h: float) -> tuple[Array, ...]:
    """The figures' axes: ``[0, 2π)`` per gene, like the paper's maps."""
    count = max(1, round(TWO_PI / h))
    return tuple(np.arange(count, dtype=np.float64) * (TWO_PI / count) for _ in range(g))


# ------------------------------------------------------------------------------------ families


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
        q0: start configuration ``(n,)`` [rad] at ``t_start`` (within the joint limits).
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
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ConfigurationError(f"duration must be a positive number of seconds, got {duration!r}")
    Q0, _ = robot.check_configurations(q0)
    q0 = Q0[0]
    lower, upper = robot.lower_limits, robot.upper_limits
    outside = np.flatnonzero((q0 < lower - 1e-9) | (q0 > upper + 1e-9))
    if outside.size:
        j = int(outside[0])
        raise ConfigurationError(f"q0: joint {j + 1} = {q0[j]:.6g} rad is outside its limits "
                                 f"[{lower[j]:.6g}, {upper[j]:.6g}] rad")
    N = opts.steps
    dt = duration / N
    h = math.radians(opts.resolution_deg)
    model, start0 = grid_model(robot, red, opts, dt, q0)
    axes, delta, r = model.axes, model.delta, model.r
    M = model.M
    times: Array = t_start + np.arange(N + 1, dtype=np.float64) * dt
    lazy = g == 2  # one or two-link arms: the whole grid is cheap, evaluate it all
    ev0 = evaluator(q0[None, :], float(times[0]))
    q0_S = float(ev0.S[0])
    problem = make_problem(red, evaluator, path, model, times, opts)
    clock = problem.clock

    # ---- (a) forward max-min from q0; a layer is evaluated only where the previous one can step to
    fwd = forward(problem, start0, ev0.link_distances[0])
    K, layers, hops, start = fwd.K, fwd.layers, fwd.hops, fwd.start
    exists = K == N

    # ---- (c) best motion: max min S, then max total S
    s_star, states_path = best_states(fwd, M)
    motion = motion_through(model, layers, times, start0, q0_S, states_path)

    # ---- (b) end families (at t_K: the end, or the dead end), viable tube, commit time
    reachable = fwd.reachable()
    ends = end_families(fwd, model, times, states_path[-1] if states_path else -1,
                        math.radians(opts.cross_adjacency_deg))
    viable, commit_time, best_family = ends.viable, ends.commit_time, ends.best_family
    t_dp = time.perf_counter()

    # ---- the figures' S maps (over [0, 360) per gene) and the start families (both need whole grids)
    map_axes = _map_axes(g, h)
    map_layers = tuple(range(N + 1)) if not lazy else _spread(N, opts.map_times)
    S_maps = np.stack([_whole_map(red, evaluator, map_axes, np.asarray(path.position(times[k]), float),
                                  float(times[k])) for k in map_layers]) if map_layers else np.zeros(0, np.float32)
    start_fams: tuple[Family, ...] = ()
    if opts.start_families:
        start_fams = start_families(problem, start0, math.radians(opts.cross_adjacency_deg))
    t_extras = time.perf_counter()

    fold = _fold_index(model, axes, map_axes)
    folded_shape = (2, *(len(a) for a in map_axes))

    def folded(masks: list[BoolArray]) -> BoolArray:
        out = np.zeros((N + 1, int(np.prod(folded_shape))), dtype=bool)
        C_f = int(np.prod(folded_shape[1:]))
        for k, (layer, mask) in enumerate(zip(layers, masks, strict=True), start=1):
            rows = np.flatnonzero(mask.reshape(-1, M).any(axis=1))
            cells = layer.cells[rows]
            out[k, (cells // model.cells) * C_f + fold[cells % model.cells]] = True
        return out.reshape((N + 1, *folded_shape))

    return ReachResult(
        times=times,
        axes=axes,
        map_axes=map_axes,
        shape=folded_shape,
        map_layers=map_layers,
        S_maps=S_maps.reshape((len(map_layers), *folded_shape)).astype(np.float32),
        reachable=folded(reachable),
        viable=folded(viable),
        exists=exists,
        dead_end=None if exists else float(times[K]),
        best_min_S=s_star,
        motion=motion,
        q0_S=q0_S,
        end_families=ends.families,
        commit_time=commit_time,
        best_family=best_family,
        start_families=start_fams,
        dt=dt,
        joint_step=delta,
        gene_cells=r,
        edges=np.array([start.size, *(e.size for e in hops)], dtype=np.int64),
        timings={
            "maps": clock["maps"],
            "edges": clock["edges"],
            "dp": t_dp - started - clock["maps"] - clock["edges"],
            "extras": t_extras - t_dp,
            "total": time.perf_counter() - started,
            "cpu": time.process_time() - cpu_started,
        },
        options=opts,
    )


def _spread(N: int, count: int) -> tuple[int, ...]:
    """``count`` layer indices spread evenly over ``0 .. N`` (the paper's Fig. 8 shows ten times)."""
    if count <= 0:
        return ()
    return tuple(sorted({round(float(k)) for k in np.linspace(0, N, min(count, N + 1))}))


def _whole_map(red: PlanarRedundancy, evaluator: Evaluator, axes: tuple[Array, ...], target: Array,
               t: float) -> NDArray[np.float32]:
    """S ``(2 C_f,)`` on the figures' grid at time ``t`` [s] (``collision_value`` where unreachable)."""
    if axes:
        Q, reach = red.solve_grid(axes, target)
    else:
        Q, reach = red.solve(np.zeros((2, 0)), np.array([0, 1]), target)
    S = np.full(Q.shape[0], evaluator.potential.collision_value)
    if reach.any():
        S[reach] = evaluator(Q[reach], t).S
    return S.astype(np.float32)


def _fold_index(model: GridModel, axes: tuple[Array, ...], map_axes: tuple[Array, ...]) -> IntArray:
    """For each flat gene index of the DP grid, the flat index of the figures' cell holding its angle."""
    if not axes:
        return np.zeros(1, dtype=np.int64)
    per_axis = []
    for axis, target in zip(axes, map_axes, strict=True):
        step = TWO_PI / len(target)
        per_axis.append(np.rint(np.mod(axis, TWO_PI) / step).astype(np.int64) % len(target))
    mesh = np.meshgrid(*per_axis, indexing="ij")
    return np.ravel_multi_index(tuple(m.ravel() for m in mesh), tuple(len(a) for a in map_axes)).astype(np.int64)
