"""Configurations per second of ``evaluate`` (AMSI + potential on true distances).

Each figure comes with the ratio to a straightforward per-configuration loop measured in the same
run: Pinocchio kinematics, ``np.linalg.pinv`` and one ``np.linalg.svd`` per control point, and
``pin.computeDistances`` per configuration -- what one writes first.

Then the cost of the self pairs: the time of one ``evaluate`` call on a population of 64, with the robot's self
pairs and with the same robot stripped of them, the two calls alternated in the same run; percentiles of the
per-call times (wall and CPU), and the ratio of the medians (target for the Panda with convex hulls: <= 1.5).

Run: ``python benchmarks/bench_evaluate.py [--quick]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import pinocchio as pin

import previewctl as pc
from previewctl.index.amsi import unit_ball_volume
from previewctl.robot.model import Geometry, Robot
from previewctl.robot.self_pairs import SelfPairs
from previewctl.scene.motion import Static


def naive_amsip(robot: Robot, scene: pc.Scene, Q: np.ndarray) -> np.ndarray:
    """The per-configuration reference: one configuration at a time, generic numpy linear algebra."""
    ev = pc.Evaluator(robot, scene)  # only for its geometry model / pairs
    clearance, model = ev.clearance, robot.model
    data = model.createData()
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    out = np.empty(len(Q))
    for b, q in enumerate(Q):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        J = pin.getFrameJacobian(model, data, robot.tip_frame_id, frame)[robot.task_rows]
        N = np.eye(robot.nv) - np.linalg.pinv(J) @ J
        E = 0.0
        for fid, p in zip(robot.control_frame_ids, robot.structural_ranks, strict=True):
            M = pin.getFrameJacobian(model, data, fid, frame)[robot.point_rows] @ N
            E += unit_ball_volume(p) * np.prod(np.linalg.svd(M, compute_uv=False)[:p]) / 0.01**p
        d = clearance.per_link(np.array([clearance.pair_distances(data)]))[0]
        out[b] = ev.potential.apply(np.array([E]), d[None])[0][0]
    return out


def rate(fn, count: int, repeats: int) -> float:
    """Best-of-``repeats`` configurations per second of ``fn()`` evaluating ``count`` configurations."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return count / best


def planar_scene() -> pc.Scene:
    """A sphere, a box straddling the plane and a floor: every planar primitive kind but capsules."""
    return pc.Scene(
        (
            pc.Obstacle("ball", pc.Sphere(0.2), Static(np.array([0.8, 0.9, 0.0]))),
            pc.Obstacle("block", pc.Box((0.4, 0.3, 0.5)), Static(np.array([-0.5, 1.2, 0.0]))),
            pc.Obstacle("floor", pc.Halfspace((0.0, 1.0, 0.0), 0.0), Static(np.array([0.0, -0.3, 0.0]))),
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller batches (for a smoke run)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    big, naive_n, repeats = (100_000, 300, 2) if args.quick else (1_000_000, 2000, 3)
    print(f"{'case':<44}{'configs/s':>12}{'naive/s':>10}{'ratio':>8}")

    robot = pc.load_robot("planar4")
    cases = (("planar4 vectorised, no obstacle", pc.Scene()), ("planar4 vectorised, 3 obstacles", planar_scene()))
    for label, scene in cases:
        ev = pc.Evaluator(robot, scene)
        Q = rng.uniform(-np.pi, np.pi, (big, 4))
        fast = rate(lambda: ev(Q), big, repeats)  # noqa: B023
        Qn = Q[:naive_n]
        slow = rate(lambda: naive_amsip(robot, scene, Qn), naive_n, 1)  # noqa: B023
        print(f"{label:<44}{fast:>12,.0f}{slow:>10,.0f}{fast / slow:>7.0f}x")

    ball = pc.Scene((pc.Obstacle("ball", pc.Sphere(0.1), Static(np.array([0.4, 0.2, 0.5]))),))
    for name in ("panda", "ur5"):
        for geometry in ("capsules", "convex", "mesh"):
            robot = pc.load_robot(name, geometry=geometry)
            ev = pc.Evaluator(robot, ball)
            Q = robot.random_configurations(rng, 64)
            ev(Q)
            loops = 10 if args.quick else 40
            fast = rate(lambda: [ev(Q) for _ in range(loops)], 64 * loops, repeats)  # noqa: B023
            slow = rate(lambda: naive_amsip(robot, ball, Q), 64, repeats)  # noqa: B023
            label = f"{name} {geometry}, population 64, 1 sphere"
            print(f"{label:<44}{fast:>12,.0f}{slow:>10,.0f}{fast / slow:>7.1f}x")

    calls = 60 if args.quick else 400
    print(f"\nself pairs: one evaluate call, population 64, 1 sphere ({calls} calls each, alternated) [ms]")
    print(f"{'case':<36}{'without':>16}{'with':>16}{'wall':>9}{'CPU':>17}{'CPU':>9}")
    print(f"{'':<36}{'p50':>8}{'p90':>8}{'p50':>8}{'p90':>8}{'ratio':>9}{'w/o p50':>9}{'p50':>8}{'ratio':>9}")
    robots: tuple[tuple[str, Geometry], ...] = (("panda", "convex"), ("panda", "capsules"), ("panda", "mesh"),
                                                ("ur5", "convex"))
    for name, geometry in robots:
        self_pair_cost(name, geometry, ball, calls if geometry != "mesh" else calls // 8, rng)


def self_pair_cost(name: str, geometry: Geometry, scene: pc.Scene, calls: int, rng: np.random.Generator) -> None:
    """Print the per-call times of one population with and without the self pairs, and their ratio."""
    robot = pc.load_robot(name, geometry=geometry)
    bare = dataclasses.replace(robot, self_pairs=SelfPairs())
    Q = robot.random_configurations(rng, 64)
    with_pairs, without = pc.Evaluator(robot, scene), pc.Evaluator(bare, scene)
    with_pairs(Q), without(Q)
    times: dict[str, list[tuple[int, int]]] = {"with": [], "without": []}
    for _ in range(calls):  # alternated, so that a busy spell of the host hits both alike
        for key, evaluator in (("without", without), ("with", with_pairs)):
            wall, cpu = time.perf_counter_ns(), time.process_time_ns()
            evaluator(Q)
            times[key].append((time.perf_counter_ns() - wall, time.process_time_ns() - cpu))
    ms = {key: np.array(value) / 1e6 for key, value in times.items()}
    p50 = {key: np.percentile(value, 50, axis=0) for key, value in ms.items()}
    p90 = {key: np.percentile(value, 90, axis=0) for key, value in ms.items()}
    ratio = p50["with"] / p50["without"]
    label = f"{name} {geometry}, {len(robot.self_pairs)} self pairs"
    print(f"{label:<36}{p50['without'][0]:>8.2f}{p90['without'][0]:>8.2f}{p50['with'][0]:>8.2f}{p90['with'][0]:>8.2f}"
          f"{ratio[0]:>8.2f}x{p50['without'][1]:>9.2f}{p50['with'][1]:>8.2f}{ratio[1]:>8.2f}x")


if __name__ == "__main__":
    main()
