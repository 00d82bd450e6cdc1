"""The solvability witness of a benchmark scene: a scene no motion can solve is not a fair test.

* **Planar arms: sufficient.** The reachability DP (:func:`~previewctl.search.reachability.reach_over_time`)
  from ``q0`` over the whole run must find a collision-free tracking motion within the joint speed limits.
  A "yes" holds on any grid (the DP's motion is collision-free between its samples by its sweep bound), so
  a grid coarser than the oracle's 2° is sound; it only finds fewer motions and rejects more draws.
* **Spatial arms: necessary only.** ``q0`` is collision-free, and every ``witness_period`` seconds some
  collision-free configuration puts the hand on the path (global exploration over the redundancy
  space, Halton samples). Whether the arm can move from one to the next in time is not checked.
"""

from __future__ import annotations

import math

import numpy as np

from previewctl.bench.scenes import SceneSettings
from previewctl.errors import UnreachableTargetError
from previewctl.index.evaluator import Evaluator
from previewctl.search.explore import explore
from previewctl.search.maps import redundancy_map
from previewctl.search.reachability import ReachOptions, reach_over_time
from previewctl.sim.scenario import Scenario


def witness(scenario: Scenario, settings: SceneSettings) -> tuple[bool, str]:
    """Whether the scene passes its witness, and what was found (one sentence)."""
    robot = scenario.robot
    evaluator = Evaluator(robot, scenario.scene, scenario.index, scenario.potential)
    duration = scenario.timing.duration
    steps = max(1, round(duration / settings.witness_period))
    if robot.planar is not None:
        options = ReachOptions(resolution_deg=settings.witness_resolution_deg, steps=steps, map_times=0)
        result = reach_over_time(robot, evaluator, scenario.path, scenario.q0, duration, options)
        grid = f"reachability DP on a {settings.witness_resolution_deg:g} deg grid, {steps} steps"
        if result.exists:
            return True, f"{grid}: a collision-free tracking motion exists (best min S {result.best_min_S:.1f})"
        return False, f"{grid}: {result.verdict()}"
    if bool(evaluator(scenario.q0[None, :], 0.0).collision[0]):
        return False, "q0 collides at t = 0"
    red = redundancy_map(robot)
    worst = math.inf
    for t in np.linspace(0.0, duration, steps + 1):
        try:
            best = explore(robot, evaluator, scenario.path.position(t), float(t),
                           samples=settings.witness_samples, redundancy=red).best
        except UnreachableTargetError:
            return False, f"the hand target at t = {t:.2f} s is out of reach"
        if best.S <= 0:
            return False, f"no collision-free configuration puts the hand on the path at t = {t:.2f} s"
        worst = min(worst, best.S)
    return True, (f"a collision-free configuration with the hand on the path exists every {duration / steps:.3g} s "
                  f"({settings.witness_samples} samples; least best S {worst:.1f}); transitions not checked")
