"""The solvability witness of a benchmark scene: a scene no motion can solve is not a fair test.

* **Planar arms: sufficient, and shown by a run.** The reachability DP
  (:func:`~previewctl.search.reachability.reach_over_time`) from ``q0`` over the whole run must find a
  collision-free tracking motion within the joint speed limits. A "yes" holds on any grid (the DP's motion
  is collision-free between its samples by its sweep bound), so a grid coarser than the oracle's 2° is
  sound; it only finds fewer motions and rejects more draws. Then (``witness_follow``, on by default) the
  ``oracle`` controller, run as the bench runs it (the scene's settings, the default QP execution, the exact
  check), must follow its plan over the whole run without collision and with the hand within
  ``witness_tolerance`` of the path: a route planned with the future known was followed, so a failure
  there is the controller's (why the DP alone is not enough: docs/guide/benchmark.md).
* **Spatial arms: sufficient too, and shown by a run.** First a quick necessary check: ``q0`` is
  collision-free, and every ``witness_period`` seconds some collision-free configuration puts the hand on
  the path (global exploration over the redundancy space, Halton samples). Then (``witness_follow``) the
  sampled forward search of :func:`~previewctl.search.roadmap.roadmap_over_time` must find a collision-free
  tracking motion within the speed limits over the whole run, and the ``oracle``, run as the bench runs it,
  must follow that motion as on planar arms: the run is the evidence (the search checks its samples only).
  The search is not complete: a scene it rejects may be solvable (it is then redrawn, and the report counts
  it). With ``witness_follow = false`` only the necessary check is made.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from previewctl.bench.metrics import run_metrics
from previewctl.bench.settings import SceneSettings
from previewctl.control.factory import make_controller
from previewctl.control.laws import Oracle
from previewctl.errors import UnreachableTargetError, shared_settings
from previewctl.index.evaluator import Evaluator
from previewctl.search.explore import explore
from previewctl.search.maps import redundancy_map
from previewctl.search.reachability import ReachMotion, ReachOptions, reach_over_time
from previewctl.search.roadmap import roadmap_over_time
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario


@dataclass(frozen=True)
class Witnessed:
    """What the witness found.

    Attributes:
        holds: whether the scene passes.
        sentence: what was found, one sentence.
        oracle_run: the witness's ``oracle`` run, when one was made: its
            :func:`~previewctl.bench.metrics.run_metrics`, its ``execution`` and controller ``seed``, and its
            ``wall_time`` and ``cpu_time`` [s]. It is the bench's own ``oracle`` run of the scene under that
            execution and seed, so the sweep does not run it again.
        oracle_plan: the motion that run followed (:meth:`ReachMotion.to_json
            <previewctl.search.reachability.ReachMotion.to_json>`): the oracle's plan of the scene, which depends
            on neither execution nor seed, so the bench's other ``oracle`` runs follow it instead of planning.
    """

    holds: bool
    sentence: str
    oracle_run: dict[str, Any] | None = None
    oracle_plan: dict[str, Any] | None = None


def witness(scenario: Scenario, settings: SceneSettings) -> Witnessed:
    """Whether the scene passes its witness, what was found, and the oracle run it made."""
    robot = scenario.robot
    evaluator = Evaluator(robot, scenario.scene, scenario.index, scenario.potential)
    duration = scenario.timing.duration
    steps = max(1, round(duration / settings.witness_period))
    if robot.planar is not None:
        options = ReachOptions(resolution_deg=settings.witness_resolution_deg, steps=steps, map_times=0)
        result = reach_over_time(robot, evaluator, scenario.path, scenario.q0, duration, options)
        grid = f"reachability DP on a {settings.witness_resolution_deg:g} deg grid, {steps} steps"
        if not result.exists:
            return Witnessed(False, f"{grid}: {result.verdict()}")
        found = f"{grid}: a collision-free tracking motion exists (best min S {result.best_min_S:.1f})"
        return _followed(scenario, settings, found) if settings.witness_follow else Witnessed(True, found)
    at_start = evaluator(scenario.q0[None, :], 0.0)
    if bool(at_start.collision[0] or at_start.self_collision[0]):
        return Witnessed(False, "q0 collides at t = 0")
    red = redundancy_map(robot)
    worst = math.inf
    for t in np.linspace(0.0, duration, steps + 1):
        try:
            best = explore(robot, evaluator, scenario.path.position(t), float(t),
                           samples=settings.witness_samples, redundancy=red).best
        except UnreachableTargetError:
            return Witnessed(False, f"the hand target at t = {t:.2f} s is out of reach")
        if best.S <= 0:
            return Witnessed(False, f"no collision-free configuration puts the hand on the path at t = {t:.2f} s")
        worst = min(worst, best.S)
    every = (f"a collision-free configuration with the hand on the path exists every {duration / steps:.3g} s "
             f"({settings.witness_samples} samples; least best S {worst:.1f})")
    if not settings.witness_follow:
        return Witnessed(True, f"{every}; transitions not checked")
    start, cpu = time.perf_counter(), time.process_time()
    searched = roadmap_over_time(robot, evaluator, scenario.path, scenario.q0, duration)
    sentence = f"{every}; sampled search: {searched.verdict()}"
    if not searched.exists:
        return Witnessed(False, sentence)
    return _followed(scenario, settings, sentence, searched.motion,
                     (time.perf_counter() - start, time.process_time() - cpu))


def _followed(scenario: Scenario, settings: SceneSettings, found: str, plan: ReachMotion | None = None,
              planned: tuple[float, float] = (0.0, 0.0)) -> Witnessed:
    """The witness's second half: the ``oracle`` run on ``scenario`` (following ``plan``, or its own plan; the
    scenario's execution and seed) must end collision-free with the hand within ``settings.witness_tolerance`` [m].
    ``planned``: the wall and CPU time [s] ``plan`` took, counted in the run's."""
    start, cpu = time.perf_counter() - planned[0], time.process_time() - planned[1]
    with shared_settings():  # the scene's table is every controller's; the oracle reads part of it
        oracle = make_controller(scenario, name="oracle")
    if plan is not None and isinstance(oracle.law, Oracle):
        oracle.law.planner.motion = plan
    metrics = run_metrics(simulate(scenario, controller=oracle))
    run = {**metrics, "execution": scenario.controller.params.execution, "seed": scenario.seed,
           "wall_time": time.perf_counter() - start, "cpu_time": time.process_time() - cpu}
    motion = oracle.law.planner.motion if isinstance(oracle.law, Oracle) else None
    made = motion.to_json() if motion is not None else None
    error, tolerance = 1e3 * metrics["max_hand_error"], 1e3 * settings.witness_tolerance
    if not metrics["collision_free"]:
        return Witnessed(False, f"{found}, but the oracle following it collides at t = "
                                f"{metrics['collision_time']:.2f} s", run, made)
    if metrics["max_hand_error"] >= settings.witness_tolerance:
        return Witnessed(False, f"{found}, but the oracle following it leaves the path by {error:.2f} mm "
                                f"(tolerance {tolerance:g} mm)", run, made)
    return Witnessed(True, f"{found}; the oracle followed it (max hand error {error:.3f} mm, no collision)", run,
                     made)
