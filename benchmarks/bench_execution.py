"""Cost of the QP execution layer per control cycle, beside the pseudo-inverse eq. 19 it replaces.

For each scene, the law with no null-space input is stepped along a recorded run (the configurations a ``qp``
run visits), once under the pseudo-inverse (``none``) and once under the QP (``qp``). Prints the median whole cycle
of each, the QP cycle's p95, the QP layer's own time per cycle (the execution's call, timed inside the cycle:
dampers, bounds and, when the reference breaks a constraint, the solver) with its p95, and the ratio of the
cycles. Times are the process's CPU time (``time.process_time``), so that another job on the host does not
inflate them; ``--wall`` measures wall time instead.

Targets (issue 12): QP layer ≤ 0.3 ms per cycle on planar4, ≤ 1 ms on the Panda (median).

    python benchmarks/bench_execution.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings
from collections.abc import Callable

import numpy as np

import previewctl as pc
from previewctl.control.base import ControlState, Executed, Execution, Reference
from previewctl.control.params import ExecutionMode
from previewctl.errors import IgnoredSettingWarning
from previewctl.sim.paper import canonical_scenario, shipped_scenarios_dir

SCENES = ("paper_planar", "paper_fitted", "panda_crossing", "xarm7_crossing")


def _scenario(name: str) -> pc.Scenario:
    if name.startswith("paper_"):
        return canonical_scenario(name)
    return pc.load_scenario(shipped_scenarios_dir() / f"{name}.toml")


class TimedExecution:
    """Wraps a controller's execution and records the time of each of its calls [s] on ``clock``."""

    def __init__(self, layer: Execution, clock: Callable[[], float]) -> None:
        self.layer, self.clock, self.times = layer, clock, list[float]()
        self.name = layer.name

    def __call__(self, state: ControlState, reference: Reference) -> Executed:
        start = self.clock()
        out = self.layer(state, reference)
        self.times.append(self.clock() - start)
        return out


def cycle_times(scenario: pc.Scenario, execution: ExecutionMode, qs: np.ndarray, times: np.ndarray,
                clock: Callable[[], float] = time.process_time) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] of ``step`` and of its execution at each recorded state on ``clock``, for a fresh controller with
    no null-space input under ``execution``: ``none`` (always the pseudo-inverse) or ``qp`` (always the QP)."""
    name = {"pseudoinverse": "none", "qp": "qp"}[execution]
    params = dataclasses.replace(scenario.controller.params, execution=execution)
    ctrl = pc.make_controller(scenario, name=name, params=params)
    assert ctrl.execution.name == execution
    layer = TimedExecution(ctrl.execution, clock)
    ctrl.execution = layer
    out = np.empty(len(qs))
    for k, (q, t) in enumerate(zip(qs, times, strict=True)):
        start = clock()
        ctrl.step(q, float(t), 0.01)
        out[k] = clock() - start
    return out, np.array(layer.times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3, help="passes over the recorded states (default 3)")
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated time recorded per scene [s]")
    parser.add_argument("--wall", action="store_true", help="wall time instead of CPU time")
    args = parser.parse_args()
    clock = time.perf_counter if args.wall else time.process_time
    # the scenes' [controller] tables are their preview controllers': none and qp read only eq. 19's settings
    warnings.simplefilter("ignore", IgnoredSettingWarning)
    print(f"{'scene':<16}{'nv':>3}{'pinv med':>10}{'qp med':>9}{'qp p95':>9}{'layer med':>11}{'layer p95':>11}"
          f"{'ratio':>7}")
    for name in SCENES:
        scenario = _scenario(name)
        short = dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=args.seconds))
        run = pc.simulate(short, "qp")
        qs, times = np.asarray(run.q), np.asarray(run.t)
        pinv = np.concatenate([cycle_times(scenario, "pseudoinverse", qs, times, clock)[0] for _ in range(args.repeat)])
        qp_runs = [cycle_times(scenario, "qp", qs, times, clock) for _ in range(args.repeat)]
        qp, layer = (np.concatenate(parts) for parts in zip(*qp_runs, strict=True))
        print(f"{name:<16}{scenario.robot.nv:>3}{np.median(pinv) * 1e3:>8.3f}ms{np.median(qp) * 1e3:>7.3f}ms"
              f"{np.percentile(qp, 95) * 1e3:>7.3f}ms{np.median(layer) * 1e3:>9.3f}ms"
              f"{np.percentile(layer, 95) * 1e3:>9.3f}ms{np.median(qp) / np.median(pinv):>7.2f}")


if __name__ == "__main__":
    main()
