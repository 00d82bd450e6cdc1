"""Speed of the redundancy search.

1. planar4, the full 1 deg grid over (q1, q2) x 2 elbow branches (259,200 candidates) through
   :func:`previewctl.search.explore.explore`, against a straightforward loop that solves and evaluates one
   configuration at a time (closed-form solve, then ``Evaluator(method="general")``: Pinocchio + Coal,
   the way one would write it without vectorising). The loop runs over a random subset of the grid and
   is extrapolated to the full grid (said so in the output).
2. One generation of the 1-step GA (population 64) on planar4 and on the Panda (capsule and convex
   collision geometry, one sphere obstacle), with the share of the AMSIP evaluation, and how many
   generations fit in a 33 ms camera frame. On the Panda, the bare Pinocchio + Coal calls of that
   evaluation are timed too (one ``computeJointJacobians``, ``updateGeometryPlacements`` and
   ``computeDistances`` per row, nothing else): the floor that no numpy work around them can beat.

Wall times are medians; CPU times (process time) are printed too, since a shared machine inflates wall
time. Run: ``PYTHONPATH=. python benchmarks/bench_search.py``.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.robot.model import Geometry
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Box, Obstacle, Scene, Sphere
from previewctl.search.explore import explore
from previewctl.search.ga import OneStepGA
from previewctl.search.maps import redundancy_map

FRAME = 0.033  # [s]


def timed(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Median wall and CPU time [s] of ``repeat`` calls."""
    wall, cpu = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return float(np.median(wall)), float(np.median(cpu))


def bench_grid() -> None:
    robot = load_robot("planar4")
    scene = Scene((Obstacle("table", Box((1.2, 0.4, 0.4)), Static(np.array([1.3, -0.55, 0.0]))),))
    evaluator = Evaluator(robot, scene)
    red = redundancy_map(robot)
    target = np.array([0.85, 0.65])  # position C
    land = explore(robot, evaluator, target)
    wall, cpu = timed(lambda: explore(robot, evaluator, target), 5)
    reach = land.reachable.mean()
    print(f"planar4 1 deg grid, {land.S.size} candidates ({100 * reach:.1f}% reach the target at C):")
    print(f"  explore (vectorised)           {1e3 * wall:8.1f} ms wall  {1e3 * cpu:8.1f} ms CPU")
    slow = Evaluator(robot, scene, method="general")
    rng = np.random.default_rng(0)
    subset = rng.choice(land.S.size, 2000, replace=False)

    def loop() -> None:
        for k in subset:
            Q, ok = red.solve(land.genes[k : k + 1], land.branch[k : k + 1], target)
            if ok[0]:
                slow(Q[0])

    w_loop, c_loop = timed(loop, 1)
    scale = land.S.size / subset.size
    print(f"  per-configuration loop         {1e3 * w_loop * scale:8.0f} ms wall  {1e3 * c_loop * scale:8.0f} ms CPU"
          f"   (extrapolated from {subset.size} random grid points x {scale:.1f})")
    print(f"  speed-up                       {w_loop * scale / wall:8.0f} x wall {c_loop * scale / cpu:8.0f} x CPU")


def bench_ga(name: str, robot_name: str, scene: Scene, target: np.ndarray, geometry: Geometry = "convex") -> None:
    robot = load_robot(robot_name, geometry=geometry)
    evaluator = Evaluator(robot, scene)
    red = redundancy_map(robot)
    ga = OneStepGA(robot, evaluator, red, np.random.default_rng(0), population=64)
    for _ in range(10):  # warm up: a converged population, as in tracking
        ga.step(target, 0.0)
    repeat = 100 if robot.planar is not None else 15
    wall, cpu = timed(lambda: ga.step(target, 0.0), repeat)
    genes = ga.population_genes
    Q, ok = red.solve(genes, np.zeros(len(genes), dtype=int), target)
    _, c_eval = timed(lambda: evaluator(Q[ok], 0.0), repeat)
    print(f"{name}: one GA generation of 64  {1e3 * wall:7.2f} ms wall {1e3 * cpu:7.2f} ms CPU "
          f"(AMSIP evaluation {1e3 * c_eval:.2f} ms CPU, the rest: redundancy map + GA operators) -> "
          f"{FRAME / wall:.1f} generations per 33 ms frame ({FRAME / cpu:.1f} by CPU time); best S {ga.best.S:.1f}")
    if robot.planar is None:
        _, c_bare = timed(lambda: library_calls(evaluator, Q[ok]), repeat)
        print(f"  of the evaluation, Pinocchio + Coal calls alone: {1e3 * c_bare:.2f} ms CPU for {int(ok.sum())} rows "
              f"({1e6 * c_bare / max(int(ok.sum()), 1):.1f} us a row)")


def library_calls(evaluator: Evaluator, Q: np.ndarray) -> None:
    """Only the library calls of an evaluation: kinematics, geometry placements and distances per row."""
    model, data, clearance = evaluator.robot.model, evaluator.data, evaluator.clearance
    for q in Q:
        pin.computeJointJacobians(model, data, q)
        pin.updateGeometryPlacements(model, data, clearance.geometry, clearance.data)
        pin.computeDistances(clearance.geometry, clearance.data)


def main() -> None:
    bench_grid()
    print()
    planar_scene = Scene((Obstacle("table", Box((1.2, 0.4, 0.4)), Static(np.array([1.3, -0.55, 0.0]))),))
    bench_ga("planar4", "planar4", planar_scene, np.array([0.85, 0.65]))
    panda_scene = Scene((Obstacle("ball", Sphere(0.08), Static(np.array([0.35, 0.0, 0.35]))),))
    for geometry in ("capsules", "convex"):
        bench_ga(f"panda ({geometry})", "panda", panda_scene, np.array([0.5, 0.1, 0.4]), geometry)


if __name__ == "__main__":
    main()
