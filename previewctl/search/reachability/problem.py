"""One reachability problem: what every pass over the layers needs, and the two things they ask of it.

The passes (the DP from ``q0``, the start families) ask for a layer at time ``t_k`` and for the edges of a
step; :class:`Problem` builds both from the arm's closed form, the scorer, the hand path and the grid
model, and keeps the wall-clock time spent on each (the ``maps`` and ``edges`` of
:attr:`~previewctl.search.reachability.result.ReachResult.timings`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability.grid import GridModel, Start
from previewctl.search.reachability.layers import Layer, evaluate_layer
from previewctl.search.reachability.options import ReachOptions
from previewctl.search.reachability.transitions import Edges, grid_edges, obstacle_travel, start_states
from previewctl.types import Array, BoolArray, IntArray


@dataclass(frozen=True)
class Problem:
    """The arm, its scorer, the hand path, the grid model and the layer times of one run.

    Attributes:
        red: the arm's closed-form redundancy map.
        evaluator: AMSIP evaluator (robot, scene, index, potential).
        path: the desired hand path.
        model: the grid and transition model.
        times: ``(N + 1,)`` layer times [s].
        travel: ``(N,)`` bound on the obstacles' travel during each step [m].
        s_min: feasible cells have ``S > s_min``.
        lazy: evaluate only the cells the DP asks for (two genes); otherwise the whole grid is cheap, and
            every layer is evaluated whole.
        clock: wall-clock seconds spent so far building layers (``maps``) and edges (``edges``); the one
            mutable part, a stopwatch.
    """

    red: PlanarRedundancy
    evaluator: Evaluator
    path: HandPath
    model: GridModel
    times: Array
    travel: tuple[float, ...]
    s_min: float
    lazy: bool
    clock: dict[str, float] = field(default_factory=lambda: {"maps": 0.0, "edges": 0.0})

    @property
    def N(self) -> int:  # noqa: N802 -- the number of steps, as in the docstring
        return int(self.times.size) - 1

    def layer(self, k: int, candidates: IntArray | None) -> Layer:
        """Layer ``k`` (time ``t_k``) over the ``candidates`` (flat physical indices; ``None``: the whole grid)."""
        tic = time.perf_counter()
        t = self.times[k]
        layer = evaluate_layer(self.red, self.evaluator, self.model, np.asarray(self.path.position(t), float),
                               float(t), self.s_min, candidates if self.lazy else None)
        self.clock["maps"] += time.perf_counter() - tic
        return layer

    def edges(self, src: Layer, dst: Layer, k: int, states: BoolArray | None) -> Edges:
        """The edges of step ``k`` (layer ``k`` to ``k + 1``) from ``src``'s ``states`` (``None``: all)."""
        tic = time.perf_counter()
        edges = grid_edges(self.model, src, dst, self.travel[k], states)
        self.clock["edges"] += time.perf_counter() - tic
        return edges

    def first_step(self, start: Start, d0: Array, dst: Layer) -> IntArray:
        """The states of layer 1, ``dst``, reachable from ``start`` (capsule distances ``d0`` [m])."""
        tic = time.perf_counter()
        states = start_states(self.model, start, d0, dst, self.travel[0])
        self.clock["edges"] += time.perf_counter() - tic
        return states


def make_problem(red: PlanarRedundancy, evaluator: Evaluator, path: HandPath, model: GridModel, times: Array,
                 opts: ReachOptions) -> Problem:
    """The problem over ``times``, with the obstacles' travel per step bounded from their sampled motion."""
    travel = tuple(obstacle_travel(evaluator.scene, float(times[k]), float(times[k + 1]), opts.obstacle_substeps)
                   for k in range(times.size - 1))
    return Problem(red=red, evaluator=evaluator, path=path, model=model, times=times, travel=travel,
                   s_min=opts.s_min, lazy=red.g == 2)
