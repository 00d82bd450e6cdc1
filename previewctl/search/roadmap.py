"""Reachability over time for any arm: a forward beam of sampled configurations (the spatial oracle's planner).

The planar arms have an exact answer on a grid (:mod:`previewctl.search.reachability`); a 7-joint arm's
self-motion manifold (4-D for a position task) is too large for a grid. This module searches it forward in
time instead, reading the whole future as the planar DP does (non-causal, offline):

* **Layers.** ``t_k = t_0 + k Δt``, ``k = 0 .. N``; layer 0 is ``q0``. Each step is split into
  ``substeps + 1`` equal sub-steps.
* **Successors.** From every node ``q`` of layer ``k``, ``children`` moves are drawn: ``q + δ`` with
  ``δ_j`` uniform in ``±v_j Δt`` (``v_j`` the joint speed limit x ``speed_share``), the first one ``δ = 0``
  (plain tracking). At every sub-step ``s`` the move's linear interpolation ``q + (s / (substeps + 1)) δ``
  is projected onto the hand target ``r_d(t)`` of its time by the Newton redundancy map (started from that
  interpolated configuration), so each successor is a sampled motion with the hand on the path. Moves are
  taken in joint coordinates (``nv``): a continuous joint's angle, unwrapped along the motion, in place of its
  (cos, sin) pair.
* **Feasible moves.** Every sample is reachable (the hand within the map's tolerance of the path), within
  the joint limits (the map clips), at least ``margin`` [m] from every obstacle at its time (exact
  distances, Coal through Pinocchio, asked only where a bounding-sphere test cannot rule the obstacle out), and
  consecutive samples differ by at most ``v_j Δt / (substeps + 1)``
  per joint (the speed limits).
* **The beam.** A successor's value is the bottleneck ``min S`` over every sample of its motion from ``q0``
  (AMSIP, eq. 18). Of every layer's feasible successors, half the ``beam`` are the best by value, skipping any
  within ``spread`` [rad] (largest joint difference) of one already kept; the other half are added farthest
  first from every kept one (a beam kept by value alone crowds into the best region and loses the one plain
  tracking stays in: docs/guide/search.md#reachability-over-time).
* **Goals** (optional: the imaginary arms' peaks of ``reach``, :class:`~previewctl.search.reachability.goals.Goals`).
  Each node's second successor heads for the best goal of the first goal time after the step, as a straight
  joint-space move arriving at that time (clipped to the speed limits). A goal is *reached* when a node of the
  layer nearest its time lies within ``goal_radius`` [rad] (joint distance) of it and is *viable* (some motion
  goes on from it to the last layer reached). The chosen goal is the best reached one at the latest time that
  has any, as on the planar grid, and the motion returned ends at the viable node nearest it.

What it answers: a motion it returns was checked at every sample, ``Δt / (substeps + 1)`` apart (0.05 s by
default); between two samples nothing is checked beyond the ``margin`` (unlike the planar DP, there is no sweep
bound), so the evidence that a scene is solvable is a run that follows the motion under the exact check (the
bench's witness). A "no" only says that this beam found none: the search is not complete. A seeded
:class:`numpy.random.Generator` (``seed``) makes the answer reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import numba
import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from previewctl.errors import ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.search.genes import joint_distance
from previewctl.search.newton import NewtonRedundancy
from previewctl.search.reachability.goals import Goals
from previewctl.search.reachability.result import ReachMotion
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array, IntArray
from previewctl.validation import Checked, Count, Finite, Integer, NonNegative, Positive, interval


@dataclass(frozen=True)
class RoadmapOptions(Checked):
    """The beam's settings (see the module docstring); every field is checked when made.

    Attributes:
        step: ``Δt`` [s] between layers (the last step is shortened to end on the horizon).
        substeps: checked samples inside each step.
        beam: nodes kept per layer.
        children: successors drawn per node (the first is plain tracking).
        speed_share: share of each joint's speed limit a move may use, in ``(0, 1]``; the rest is left to the
            controller that follows the motion (its hand task).
        margin: least distance [m] of every guarded link to every obstacle at every sample.
        spread: least largest-joint difference [rad] between two kept nodes of a layer.
        goal_radius: how close [rad] (joint distance) a node must come to a goal to reach it.
        seed: seed of the successors' draws.
    """

    step: Positive = 0.25
    substeps: Annotated[Integer, Field(ge=0)] = 4
    beam: Count = 48
    children: Count = 12
    speed_share: Annotated[Finite, interval(0, 1, "(]")] = 0.6
    margin: NonNegative = 0.01
    spread: Positive = 0.15
    goal_radius: Positive = 0.3
    seed: Annotated[Integer, Field(ge=0)] = 0


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
        goal: ``(level, index)`` of the chosen goal (``goals[level].q[index]``), or ``None`` (none given or reached;
            the motion is then the best one to the last layer reached).
    """

    exists: bool
    motion: ReachMotion
    reached: float
    horizon: float
    evaluations: int
    goal: tuple[int, int] | None = None

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
    angles: Array  # (B, nv) the nodes' joint coordinates, continuous joints unwrapped along the motion

    @property
    def q(self) -> Array:
        """``(B, nq)`` the nodes."""
        return self.samples[:, -1]


def roadmap_over_time(robot: Robot, evaluator: Evaluator, path: HandPath, q0: Array, duration: float,
                      options: RoadmapOptions | None = None, *, t_start: float = 0.0,
                      goals: Sequence[Goals] = ()) -> RoadmapResult:
    """Search for a collision-free tracking motion from ``q0`` at ``t_start`` over ``duration`` [s] (toward the best
    reached of ``goals``, when given).

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
    layers = [_Layer(np.array([np.inf]), np.zeros(1, dtype=int), Q0[:, None], first.S[:, None], robot.angles_of(Q0))]
    evaluations = 1
    wanted = [g for g in goals if len(g.q)]
    for k in range(steps):
        aim = _aim(wanted, float(times[k + 1]))
        grown, count = _successors(robot, red, evaluator, path, layers[-1], times[k], times[k + 1], opts, rng, aim)
        evaluations += count
        if grown is None:
            break
        layers.append(grown)
    reached = len(layers) - 1
    pick = _pick_goal(robot, layers, times, list(goals), opts.goal_radius)
    end = None if pick is None else pick[2:]
    return RoadmapResult(exists=reached == steps, motion=_motion(layers, times, opts.substeps, end),
                         reached=float(times[reached]), horizon=float(times[-1]), evaluations=evaluations,
                         goal=None if pick is None else pick[:2])


def _aim(goals: list[Goals], t: float) -> tuple[float, Array] | None:
    """``(t_i, q)``: the best goal of the first goal time at or after ``t`` [s], or ``None``."""
    ahead = [g for g in goals if g.t >= t - 1e-9]
    if not ahead:
        return None
    first = min(ahead, key=lambda g: g.t)
    return first.t, np.asarray(first.q[int(np.argmax(first.score))], dtype=float)


def _pick_goal(robot: Robot, layers: list[_Layer], times: Array, goals: list[Goals],
               radius: float) -> tuple[int, int, int, int] | None:
    """``(level, index, layer, node)``: the best reached goal at the latest time that has one, and the viable node
    nearest it."""
    if not goals or len(layers) < 2:
        return None
    viable = [np.ones(len(layers[-1].q), dtype=bool)]
    for layer, below in zip(reversed(layers[1:]), reversed(layers[:-1]), strict=True):
        alive = np.zeros(len(below.q), dtype=bool)
        alive[layer.parent[viable[0]]] = True
        viable.insert(0, alive)
    periodic = robot.joints.full_turn
    picks: list[tuple[int, float, int, int, int]] = []  # (layer, score, level, index, node)
    for level, goal in enumerate(goals):
        k = int(np.argmin(np.abs(times - goal.t)))
        if k < 1 or k >= len(layers) or not len(goal.q):
            continue
        nodes = np.flatnonzero(viable[k])
        if not nodes.size:
            continue
        distance = joint_distance(robot.angles_of(np.asarray(goal.q, dtype=float)),
                                  robot.angles_of(layers[k].q[nodes]), periodic)
        for index in np.argsort(-np.asarray(goal.score)):
            if distance[index].min() <= radius:
                picks.append((k, float(goal.score[index]), level, int(index), int(nodes[np.argmin(distance[index])])))
                break
    if not picks:
        return None
    k, _, level, index, node = max(picks, key=lambda p: (p[0], p[1]))
    return level, index, k, node


def _successors(robot: Robot, red: NewtonRedundancy, evaluator: Evaluator, path: HandPath, layer: _Layer,
                t0: float, t1: float, opts: RoadmapOptions, rng: np.random.Generator,
                aim: tuple[float, Array] | None) -> tuple[_Layer | None, int]:
    """The next layer's kept nodes (``None`` when no move is feasible) and how many configurations were evaluated;
    ``aim`` ``(t_i, q)``: the goal each node's second successor heads for."""
    h = t1 - t0
    reach = robot.velocity_limits * opts.speed_share * h
    parent = np.repeat(np.arange(len(layer.q)), opts.children)
    delta = rng.uniform(-1.0, 1.0, (len(parent), robot.nv)) * reach
    delta[:: opts.children] = 0.0  # plain tracking
    if aim is not None and opts.children > 1:  # straight toward the goal, arriving at its time
        goal = np.repeat(robot.angles_of(aim[1][None, :]), len(layer.angles), axis=0)
        toward = _next_to(robot, goal, layer.angles) - layer.angles
        delta[1 :: opts.children] = np.clip(toward * (h / max(aim[0] - t0, h)), -reach, reach)
    start = layer.angles[parent]
    end = start + delta
    previous, alive = start.copy(), np.ones(len(parent), dtype=bool)
    samples = np.empty((len(parent), opts.substeps + 1, robot.nq))
    evaluations = 0
    sample_S = np.full((len(parent), opts.substeps + 1), -np.inf)
    guesses, projected, projectable = _projections(robot, red, path, start, end, t0, h, opts.substeps)
    for s in range(1, opts.substeps + 2):
        t = t0 + s / (opts.substeps + 1) * h
        rows = np.flatnonzero(alive)
        guess, Q, reachable = guesses[s - 1, rows], projected[s - 1, rows], projectable[s - 1, rows]
        angles = _next_to(robot, robot.angles_of(Q), guess)
        within = np.all(np.abs(angles - previous[rows]) <= reach / (opts.substeps + 1) + 1e-9, axis=1)
        check = rows[reachable & within]
        ok = np.zeros(len(parent), dtype=bool)
        if check.size:
            found = evaluator(Q[reachable & within], t, exact_below=opts.margin)
            evaluations += check.size
            clear = found.min_distance > opts.margin
            ok[check[clear]] = True
            sample_S[check, s - 1] = found.S
        alive &= ok
        samples[rows, s - 1] = Q
        previous[rows] = angles
        if not alive.any():
            return None, evaluations
    rows = np.flatnonzero(alive)
    value = np.minimum(layer.value[parent[rows]], sample_S[rows].min(axis=1))
    kept = _spread_out(previous[rows], value, opts)
    rows = rows[kept]
    return _Layer(value[kept], parent[rows], samples[rows], sample_S[rows], previous[rows]), evaluations


def _projections(robot: Robot, red: NewtonRedundancy, path: HandPath, start: Array, end: Array, t0: float, h: float,
                 substeps: int) -> tuple[Array, Array, NDArray[np.bool_]]:
    """Every move's sub-step samples, each sub-step's linear interpolation from ``start`` to ``end`` ``(R, nv)``
    projected onto the hand target of its time by the Newton map (started from it), in one batch: the guesses
    ``(substeps + 1, R, nv)``, the configurations ``(substeps + 1, R, nq)`` and whether each is reachable.

    A row's projection does not depend on the others (:meth:`~previewctl.search.newton.NewtonRedundancy.solve_many`),
    so this equals one projection per sub-step of the moves still alive, and pays Newton's overhead per call once a
    step; the moves that die at an earlier sub-step are projected in vain.
    """
    count = substeps + 1
    guesses = np.stack([start + s / count * (end - start) for s in range(1, count + 1)])
    flat = guesses.reshape(-1, start.shape[1])
    targets = [path.position(t0 + s / count * h) for s in range(1, count + 1)]
    groups = np.repeat(np.arange(count), len(start))
    Q, reachable = red.solve_many(flat, np.zeros(len(flat), dtype=int), targets, groups,
                                  q_seed=robot.configurations_from_angles(flat))
    return guesses, Q.reshape(count, len(start), -1), reachable.reshape(count, len(start))


def _next_to(robot: Robot, angles: Array, reference: Array) -> Array:
    """Joint coordinates ``angles`` ``(B, nv)`` with each continuous joint's angle shifted by whole turns to within
    π of ``reference`` (the other coordinates unchanged): the motion's angles stay unwrapped."""
    turning = robot.joints.continuous
    if turning.any():
        angles[:, turning] = reference[:, turning] + wrap_angle(angles[:, turning] - reference[:, turning])
    return angles


def _spread_out(Q: Array, value: Array, opts: RoadmapOptions) -> IntArray:
    """Indices of the kept nodes: half the ``beam`` the best by ``value`` (none within ``spread`` of a better kept
    one), the other half the farthest from every kept node (largest joint difference), so the beam covers the
    reachable part of the manifold and not only its best region."""
    kept = np.empty(opts.beam, dtype=np.int64)
    count = _spread(np.ascontiguousarray(Q, dtype=float), np.argsort(-value, kind="stable"), opts.spread, kept)
    return kept[:count]


@numba.njit(cache=True, nogil=True)
def _gap(Q: Array, a: int, b: int) -> float:  # pragma: no cover - compiled
    """The largest joint difference between rows ``a`` and ``b`` of ``Q`` (exact, whichever order)."""
    gap = 0.0
    for k in range(Q.shape[1]):
        gap = max(gap, abs(Q[a, k] - Q[b, k]))
    return gap


@numba.njit(cache=True, nogil=True)
def _spread(Q: Array, order: IntArray, spread: float, kept: IntArray) -> int:  # pragma: no cover - compiled
    """:func:`_spread_out`'s choice in one compiled pass: fills ``kept`` (its length is the beam) and returns how many
    nodes it kept."""
    beam, rows = len(kept), Q.shape[0]
    count = 0
    for i in order:  # the best by value, none within spread of a kept one
        apart = True
        for c in range(count):
            if _gap(Q, kept[c], i) <= spread:
                apart = False
                break
        if apart:
            kept[count] = i
            count += 1
            if 2 * count >= beam:
                break
    nearest = np.full(rows, np.inf)  # each node's largest-joint distance to its nearest kept node
    for r in range(rows):
        for c in range(count):
            nearest[r] = min(nearest[r], _gap(Q, r, kept[c]))
    while count < beam:  # then the farthest from every kept node
        far = int(np.argmax(nearest))
        if nearest[far] <= spread:
            break
        kept[count] = far
        count += 1
        for r in range(rows):
            nearest[r] = min(nearest[r], _gap(Q, r, far))
    return count


def _motion(layers: list[_Layer], times: Array, substeps: int, end: tuple[int, int] | None = None) -> ReachMotion:
    """The motion from ``q0`` to ``end`` ``(layer, node)`` (default: the last layer's best node), every checked sample
    in time order."""
    if end is not None:
        layers = layers[: end[0] + 1]
    node = int(np.argmax(layers[-1].value)) if end is None else end[1]
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
