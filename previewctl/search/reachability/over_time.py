"""The entry point :func:`reach_over_time`: check the inputs, run the passes in order, assemble the result.

(a) the forward max-min from ``q0`` (:mod:`~previewctl.search.reachability.dp`), (c) the best motion,
(b) the end families and the commit time (:mod:`~previewctl.search.reachability.families`), then what
only the figures need: the whole S maps (:mod:`~previewctl.search.reachability.maps`) and, on request,
the start families. Definitions in :mod:`previewctl.search.reachability`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability.dp import best_states, forward
from previewctl.search.reachability.families import end_families, start_families
from previewctl.search.reachability.goals import Goals, pick_goal
from previewctl.search.reachability.grid import grid_model
from previewctl.search.reachability.maps import fold_states, map_axes, map_layers, map_shape, s_maps
from previewctl.search.reachability.motion import motion_through
from previewctl.search.reachability.options import PlanarOnlyError, ReachOptions
from previewctl.search.reachability.problem import make_problem
from previewctl.search.reachability.result import ReachResult
from previewctl.types import Array


def reach_over_time(
    robot: Robot,
    evaluator: Evaluator,
    path: HandPath,
    q0: Array,
    duration: float,
    options: ReachOptions | None = None,
    *,
    t_start: float = 0.0,
    goals: Sequence[Goals] = (),
) -> ReachResult:
    """Reachability over the redundancy grid x time from ``q0`` (see :mod:`previewctl.search.reachability`).

    Args:
        robot: a planar arm with at most 2 genes (2 to 4 joints).
        evaluator: AMSIP evaluator (robot, scene, index, potential) -- the scene and hand target at
            each layer time are read from it and from ``path``.
        path: the desired hand path.
        q0: start configuration ``(n,)`` [rad] at ``t_start`` (within the joint limits).
        duration: horizon [s]; layers at ``t_start + k duration / N``.
        options: grid and transition model.
        t_start: start time [s].
        goals: candidate end configurations at future times (:mod:`~previewctl.search.reachability.goals`):
            when one is reached (and viable: a motion goes on from it to the last layer reached), the
            result's motion is the best motion to the best reached goal at the latest time instead of the best
            motion overall.

    Returns:
        The verdict, the best motion, the families and commit time, and the maps.

    Raises:
        PlanarOnlyError: a spatial arm, or a planar arm with more than 2 genes.
        ConfigurationError: a bad option, duration or ``q0``; a time step too short for the grid.
    """
    started, cpu_started = time.perf_counter(), time.process_time()
    opts = options or ReachOptions()
    red, q0 = _checked(robot, duration, q0)
    N, dt = opts.steps, duration / opts.steps
    model, start = grid_model(robot, red, opts, dt, q0)
    times: Array = t_start + np.arange(N + 1, dtype=np.float64) * dt
    ev0 = evaluator(q0[None, :], float(times[0]))
    q0_S = float(ev0.S[0])
    problem = make_problem(red, evaluator, path, model, times, opts)
    cross_beta = math.radians(opts.cross_adjacency_deg)
    fwd = forward(problem, start, ev0.link_distances[0])
    s_star, states = best_states(fwd, model.M)
    motion = motion_through(model, fwd.layers, times, start, q0_S, states)
    ends = end_families(fwd, model, times, states[-1] if states else -1, cross_beta)
    pick = pick_goal(red, model, fwd, ends.viable, times, list(goals)) if goals else None
    if pick is not None:
        _, to_goal = best_states(fwd, model.M, end=(pick.layer, pick.state))
        motion = motion_through(model, fwd.layers, times, start, q0_S, to_goal)
    t_dp = time.perf_counter()
    axes = map_axes(red.g, model.h)
    shown = map_layers(problem, opts.map_times)
    maps = s_maps(problem, axes, shown)
    starts = start_families(problem, start, cross_beta) if opts.start_families else ()
    t_extras = time.perf_counter()
    return ReachResult(
        times=times, axes=model.axes, map_axes=axes, shape=map_shape(axes), map_layers=shown, S_maps=maps,
        reachable=fold_states(model, axes, fwd.layers, fwd.reachable(), N + 1),
        viable=fold_states(model, axes, fwd.layers, ends.viable, N + 1),
        exists=fwd.K == N, dead_end=None if fwd.K == N else float(times[fwd.K]), best_min_S=s_star,
        motion=motion, q0_S=q0_S,
        end_families=ends.families, commit_time=ends.commit_time, best_family=ends.best_family,
        start_families=starts, dt=dt, joint_step=model.delta, gene_cells=model.r,
        edges=np.array([fwd.start.size, *(e.size for e in fwd.hops)], dtype=np.int64),
        timings=_timings(problem.clock, started, cpu_started, t_dp, t_extras), options=opts,
        goal=None if pick is None else (pick.level, pick.index),
    )


def _checked(robot: Robot, duration: float, q0: Array) -> tuple[PlanarRedundancy, Array]:
    """The arm's closed-form redundancy map and ``q0`` as a checked ``(n,)`` array.

    Raises:
        PlanarOnlyError: a spatial arm, or a planar arm with more than 2 genes.
        ConfigurationError: a bad duration, or ``q0`` outside the joint limits.
    """
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
    q = Q0[0]
    lower, upper = robot.lower_limits, robot.upper_limits
    outside = np.flatnonzero((q < lower - 1e-9) | (q > upper + 1e-9))
    if outside.size:
        j = int(outside[0])
        raise ConfigurationError(f"q0: joint {j + 1} = {q[j]:.6g} rad is outside its limits "
                                 f"[{lower[j]:.6g}, {upper[j]:.6g}] rad")
    return red, q


def _timings(clock: dict[str, float], started: float, cpu_started: float, t_dp: float,
             t_extras: float) -> dict[str, float]:
    """Wall-clock seconds per stage and in all, and the process CPU seconds (see ``ReachResult.timings``)."""
    return {
        "maps": clock["maps"],
        "edges": clock["edges"],
        "dp": t_dp - started - clock["maps"] - clock["edges"],
        "extras": t_extras - t_dp,
        "total": time.perf_counter() - started,
        "cpu": time.process_time() - cpu_started,
    }
