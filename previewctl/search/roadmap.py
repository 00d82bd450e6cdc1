"""Reachability over time for any arm: a forward beam of sampled configurations (the spatial oracle's planner).

The planar arms have an exact answer on a grid (:mod:`previewctl.search.reachability`); a 7-joint arm's
self-motion manifold (4-D for a position task) is too large for a grid. This module searches it forward in
time instead, reading the whole future as the planar DP does (non-causal, offline):

* **Layers.** ``t_k = t_0 + k Δt``, ``k = 0 .. N``; layer 0 is ``q0``. Each step is split into
  ``substeps + 1`` equal sub-steps.
* **Successors.** From every node ``q`` of layer ``k``, ``children`` moves are drawn: ``q + δ`` with
  ``δ_j`` uniform in ``±v_j Δt`` (``v_j`` the joint speed limit x ``speed_share``), the first one ``δ = 0``
  (plain tracking). At every sub-step ``s`` the move's linear interpolation ``q + (s / (substeps + 1)) δ``
  is projected onto the hand target ``r_d(t)`` of its time by the Newton redundancy map (warm-started from
  the previous sub-step's solution), so each successor is a sampled motion with the hand on the path.
* **Feasible moves.** Every sample is reachable (the hand within the map's tolerance of the path), within
  the joint limits (the map clips), at least ``margin`` [m] from every obstacle at its time (exact
  distances, Coal through Pinocchio), and consecutive samples differ by at most ``v_j Δt / (substeps + 1)``
  per joint (the speed limits).
* **The beam.** A successor's value is the bottleneck ``min S`` over every sample of its motion from ``q0``
  (AMSIP, eq. 18). Of every layer's feasible successors, the ``beam`` best are kept, skipping any within ``spread``
  [rad] (largest joint difference) of one already kept, so the beam stays spread over the manifold.

The answer is **sound, not complete**: a motion it returns was checked sample by sample (its sub-steps are
``Δt / (substeps + 1)`` apart; between them the motion is the linear interpolation of two checked
configurations, which the ``margin`` covers for the arm's and the obstacles' speeds of the bench scenes); a
"no" only says that this beam found none. A seeded :class:`numpy.random.Generator` (``seed``) makes the
answer reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from previewctl.errors import ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.search.newton import NewtonRedundancy
from previewctl.search.reachability.result import ReachMotion
from previewctl.types import Array, IntArray


@dataclass(frozen=True)
class RoadmapOptions:
    """The beam's settings (see the module docstring).

    Attributes:
        step: ``Δt`` [s] between layers (the last step is shortened to end on the horizon).
        substeps: checked samples inside each step.
        beam: nodes kept per layer.
        children: successors drawn per node (the first is plain tracking).
        speed_share: share of each joint's speed limit a move may use, in ``(0, 1]``; the rest is left to the
            controller that follows the motion (its hand task).
        margin: least distance [m] of every guarded link to every obstacle at every sample.
        spread: least largest-joint difference [rad] between two kept nodes of a layer.
        seed: seed of the successors' draws.
    """

    step: float = 0.25
    substeps: int = 4
    beam: int = 48
    children: int = 12
    speed_share: float = 0.6
    margin: float = 0.01
    spread: float = 0.15
    seed: int = 0

    def __post_init__(self) -> None:
        """Check the values.

        Raises:
            ParameterError: a value out of its range (the message names it and the range).
        """
        for name, low in (("step", 0.0), ("spread", 0.0)):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > low):
                raise ParameterError(f"roadmap {name} must be a finite number > {low:g}, got {value!r}")
        if not (isinstance(self.margin, (int, float)) and math.isfinite(self.margin) and self.margin >= 0):
            raise ParameterError(f"roadmap margin must be a finite number >= 0 [m], got {self.margin!r}")
        if not (isinstance(self.speed_share, (int, float)) and 0 < self.speed_share <= 1):
            raise ParameterError(f"roadmap speed_share must be in (0, 1], got {self.speed_share!r}")
        for name, low in (("substeps", 0), ("beam", 1), ("children", 1), ("seed", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ParameterError(f"roadmap {name} must be an integer >= {low}, got {value!r}")


@dataclass(frozen=True)
class RoadmapResult:
    """What :func:`roadmap_over_time` found.

    Attributes:
        exists: whether some checked motion reaches the horizon.
        motion: the best motion found (to the horizon, or to the last layer any motion reached), every checked
            sample included (``branch`` 0 and ``cells`` -1: there is no grid).
        reached: the last time [s] some motion reached.
        horizon: the time [s] the search had to reach.
        evaluations: configurations evaluated (S or distances).
    """

    exists: bool
    motion: ReachMotion
    reached: float
    horizon: float
    evaluations: int

    def verdict(self) -> str:
        """One sentence: what was found."""
        if self.exists:
            return (f"a collision-free tracking motion was found to t = {self.horizon:.2f} s "
                    f"(best min S {self.motion.min_S:.1f})")
        return f"no motion found beyond t = {self.reached:.2f} s (the horizon is {self.horizon:.2f} s)"


@dataclass
class _Layer:
    """The kept nodes of one layer, with each node's motion from its parent (its sub-step samples)."""

    value: Array  # (B,) bottleneck min S so far
    parent: IntArray  # (B,) index in the previous layer
    samples: Array  # (B, substeps + 1, nq) the checked samples of the step, the node itself last
    S: Array  # (B, substeps + 1) their S

    @property
    def q(self) -> Array:
        """``(B, nq)`` the nodes."""
        return self.samples[:, -1]


def roadmap_over_time(robot: Robot, evaluator: Evaluator, path: HandPath, q0: Array, duration: float,
                      options: RoadmapOptions | None = None, *, t_start: float = 0.0) -> RoadmapResult:
    """Search for a collision-free tracking motion from ``q0`` at ``t_start`` over ``duration`` [s].

    Raises:
        ParameterError: a non-positive or non-finite duration.
        ConfigurationError: a bad ``q0``.
    """
    opts = options or RoadmapOptions()
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ParameterError(f"the roadmap's duration must be a finite number > 0 [s], got {duration!r}")
    Q0, _ = robot.check_configurations(q0)
    red = NewtonRedundancy(robot)
    rng = np.random.default_rng(opts.seed)
    steps = max(1, math.ceil(duration / opts.step - 1e-9))
    times = t_start + np.minimum(np.arange(steps + 1) * opts.step, duration)
    first = evaluator(Q0, t_start)
    layers = [_Layer(np.array([np.inf]), np.zeros(1, dtype=int), Q0[:, None], first.S[:, None])]
    evaluations = 1
    for k in range(steps):
        grown, count = _successors(robot, red, evaluator, path, layers[-1], times[k], times[k + 1], opts, rng)
        evaluations += count
        if grown is None:
            break
        layers.append(grown)
    reached = len(layers) - 1
    return RoadmapResult(exists=reached == steps, motion=_motion(layers, times, opts.substeps),
                         reached=float(times[reached]), horizon=float(times[-1]), evaluations=evaluations)


def _successors(robot: Robot, red: NewtonRedundancy, evaluator: Evaluator, path: HandPath, layer: _Layer,
                t0: float, t1: float, opts: RoadmapOptions, rng: np.random.Generator) -> tuple[_Layer | None, int]:
    """The next layer's kept nodes (``None`` when no move is feasible) and how many configurations were evaluated."""
    h = t1 - t0
    reach = robot.velocity_limits * opts.speed_share * h
    parent = np.repeat(np.arange(len(layer.q)), opts.children)
    delta = rng.uniform(-1.0, 1.0, (len(parent), robot.nv)) * reach
    delta[:: opts.children] = 0.0  # plain tracking
    start = layer.q[parent]
    aim = start + delta
    previous, alive = start, np.ones(len(parent), dtype=bool)
    samples = np.empty((len(parent), opts.substeps + 1, robot.nq))
    evaluations = 0
    sample_S = np.full((len(parent), opts.substeps + 1), -np.inf)
    for s in range(1, opts.substeps + 2):
        fraction = s / (opts.substeps + 1)
        t = t0 + fraction * h
        rows = np.flatnonzero(alive)
        guess = start[rows] + fraction * (aim[rows] - start[rows])
        Q, reachable = red.solve(guess, np.zeros(len(rows), dtype=int), path.position(t), q_seed=guess)
        within = np.all(np.abs(Q - previous[rows]) <= reach / (opts.substeps + 1) + 1e-9, axis=1)
        check = rows[reachable & within]
        ok = np.zeros(len(parent), dtype=bool)
        if check.size:
            found = evaluator(Q[reachable & within], t)
            evaluations += check.size
            clear = found.min_distance > opts.margin
            ok[check[clear]] = True
            sample_S[check, s - 1] = found.S
        alive &= ok
        samples[rows, s - 1] = Q
        previous = samples[:, s - 1]
        if not alive.any():
            return None, evaluations
    rows = np.flatnonzero(alive)
    value = np.minimum(layer.value[parent[rows]], sample_S[rows].min(axis=1))
    kept = _spread_out(samples[rows, -1], value, opts)
    rows = rows[kept]
    return _Layer(value[kept], parent[rows], samples[rows], sample_S[rows]), evaluations


def _spread_out(Q: Array, value: Array, opts: RoadmapOptions) -> IntArray:
    """Indices of the kept nodes: half the ``beam`` the best by ``value`` (none within ``spread`` of a better kept
    one), the other half the farthest from every kept node (largest joint difference), so the beam covers the
    reachable part of the manifold and not only its best region."""
    kept: list[int] = []
    for i in np.argsort(-value, kind="stable"):
        if not kept or np.min(np.max(np.abs(Q[kept] - Q[i]), axis=1)) > opts.spread:
            kept.append(int(i))
            if 2 * len(kept) >= opts.beam:
                break
    gap = np.min(np.max(np.abs(Q[:, None, :] - Q[kept][None, :, :]), axis=2), axis=1)
    while len(kept) < opts.beam:
        far = int(np.argmax(gap))
        if gap[far] <= opts.spread:
            break
        kept.append(far)
        gap = np.minimum(gap, np.max(np.abs(Q - Q[far]), axis=1))
    return np.array(kept, dtype=int)


def _motion(layers: list[_Layer], times: Array, substeps: int) -> ReachMotion:
    """The best node's motion back to ``q0``, every checked sample in time order."""
    node = int(np.argmax(layers[-1].value))
    value = float(layers[-1].value[node]) if len(layers) > 1 else math.nan
    q_pieces, S_pieces = [], []
    for layer in reversed(layers):
        q_pieces.append(layer.samples[node])
        S_pieces.append(layer.S[node])
        node = int(layer.parent[node])
    q, S = np.vstack(q_pieces[::-1]), np.concatenate(S_pieces[::-1])
    sample_times = np.concatenate([times[:1], *[np.linspace(times[k], times[k + 1], substeps + 2)[1:]
                                                for k in range(len(layers) - 1)]])
    return ReachMotion(times=sample_times, q=q, S=S, branch=np.zeros(len(q), dtype=np.int64),
                       cells=np.full(len(q), -1, dtype=np.int64), min_S=value, total_S=float(np.sum(S[1:])))
