"""Control-cycle time of multi-preview control (p = 3, population 64), set against the 33 ms frame.

A cycle that falls on a camera frame runs one GA generation per imaginary arm (three here); the
others only apply eq. 19 with the last targets. Both are reported: median, 99th percentile and worst
over the run (on a shared machine the worst can be a stall of the host; the 99th percentile is not).

Run: ``python benchmarks/bench_control.py [--quick]``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from previewctl.sim.loop import simulate
from previewctl.sim.paper import canonical_scenario, shipped_scenarios_dir, with_controller
from previewctl.sim.scenario import Scenario, load_scenario

FRAME_MS = 33.0


def multi(scenario: Scenario, duration: float) -> Scenario:
    """``scenario`` with three-preview control (the paper's weights) for ``duration`` [s]."""
    timed = dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=duration))
    return with_controller(timed, "multi")


def report(label: str, scenario: Scenario) -> None:
    result = simulate(scenario, "multi")
    cycle = np.asarray(result.cycle_time) * 1e3
    frames = np.asarray(result.frame_due, dtype=bool)
    for kind, mask in (("frame cycles", frames), ("other cycles", ~frames)):
        if mask.any():
            c = cycle[mask]
            print(f"{label:<34}{kind:<14}{np.median(c):>9.2f}{np.percentile(c, 99):>9.2f}{c.max():>9.2f}"
                  f"{100 * np.median(c) / FRAME_MS:>9.0f}%")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs (a smoke test)")
    args = parser.parse_args()
    duration = 2.0 if args.quick else 10.0
    header = f"{'scene (multi, p = 3, population 64)':<34}{'cycles':<14}"
    print(f"{header}{'median':>9}{'p99':>9}{'worst':>9}{'of 33ms':>10}")
    report("planar4, paper_planar", multi(canonical_scenario("paper_planar"), duration))
    panda = load_scenario(shipped_scenarios_dir() / "panda_crossing.toml")
    report("panda (convex), panda_crossing", multi(panda, duration))
    capsules = dataclasses.replace(panda, robot=panda.robot_spec.load("capsules"))
    report("panda (capsules), panda_crossing", multi(capsules, duration))


if __name__ == "__main__":
    main()
