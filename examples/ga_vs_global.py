"""The paper's Tables 2-3: the 1-step GA against global exploration at six hand positions A-F.

The canonical planar path of the paper (section 7): A = (0.10, 1.40) m, then five 0.75 m segments
A -> B -> C -> D -> E -> F (right, down, right, down, right), in the canonical scene
``scenarios/paper_planar.toml`` (the inverted staircase and the pillar). For every position the hand
is held still at the time the path passes it; the global optimum comes from the
1 deg grid over (q1, q2) x both elbow branches; the GA (population 64) runs one generation per frame
and its best after 1, 5 and 30 frames is compared with it:

* S gap [%] = 100 (S_max - S_GA) / S_max (negative: the GA beat the grid, which is only 1 deg fine);
* dq [deg] = the largest joint-angle difference between the two configurations (angles mod 360).
  Mirror-image configurations can have the same S, so a small S gap with a large dq is a tie between
  peaks, not a failure.

Run: ``PYTHONPATH=. python examples/ga_vs_global.py [--seeds 10]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from previewctl.index.evaluator import Evaluator
from previewctl.search.explore import explore
from previewctl.search.ga import OneStepGA
from previewctl.search.maps import redundancy_map
from previewctl.search.redundancy import wrap_angle
from previewctl.sim.paper import canonical_scenario

SCENARIO = canonical_scenario("paper_planar")
PATH = np.asarray(SCENARIO.path.waypoints)
FRAMES = (1, 5, 30)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="GA runs per position for the mean row (default 10)")
    parser.add_argument("--population", type=int, default=64, help="GA population (default 64)")
    args = parser.parse_args()

    robot = SCENARIO.robot
    evaluator = Evaluator(robot, SCENARIO.scene, SCENARIO.index, SCENARIO.potential)
    redundancy = redundancy_map(robot)

    header = ["pos", "hand [m]", "global q1, q2 [deg] (elbow)", "S_max"]
    header += [f"GA@{f}: S gap %, dq deg" for f in FRAMES]
    print("| " + " | ".join(header) + " |")
    print("|" + "|".join("---" for _ in header) + "|")
    mean_gap = np.zeros((len(PATH), len(FRAMES)))
    for k, target in enumerate(PATH):
        land = explore(robot, evaluator, target)
        best = land.best
        s_max = best.S
        gaps = np.zeros((args.seeds, len(FRAMES)))
        first_run: list[str] = []
        for seed in range(args.seeds):
            ga = OneStepGA(robot, evaluator, redundancy, np.random.default_rng(seed), population=args.population)
            for frame in range(1, max(FRAMES) + 1):
                found = ga.step(target, 0.0)
                if frame in FRAMES:
                    column = FRAMES.index(frame)
                    gaps[seed, column] = 100.0 * (s_max - found.S) / s_max
                    if seed == 0:
                        dq = np.degrees(np.abs(wrap_angle(found.q - best.q)).max())
                        first_run.append(f"{gaps[seed, column]:+.2f}, {dq:.1f}")
        mean_gap[k] = gaps.mean(axis=0)
        q12 = np.degrees(np.mod(best.genes, 2 * np.pi))
        elbow = "+" if best.branch == 0 else "-"
        row = ["ABCDEF"[k], f"({target[0]:.2f}, {target[1]:.2f})", f"{q12[0]:.0f}, {q12[1]:.0f} ({elbow})",
               f"{s_max:.1f}", *first_run]
        print("| " + " | ".join(row) + " |")
    print()
    print(f"GA seed 0 in the table; mean S gap [%] over {args.seeds} seeds:")
    print("| pos | " + " | ".join(f"GA@{f}" for f in FRAMES) + " |")
    print("|---|" + "|".join("---" for _ in FRAMES) + "|")
    for k in range(len(PATH)):
        print(f"| {'ABCDEF'[k]} | " + " | ".join(f"{g:+.2f}" for g in mean_gap[k]) + " |")


if __name__ == "__main__":
    main()
