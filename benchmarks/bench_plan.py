"""CPU time of the spatial window plans (the sampled search of ``reach`` and ``horizon``) against the replan period.

The plans are the ones real runs make: each scene is run once per controller (inline planning) while every call of
:func:`~previewctl.search.roadmap.roadmap_over_time` made by the window planner is recorded (start configuration,
time, window, goals). The recorded calls are then replayed one by one and timed in CPU time
(``time.process_time``: the host is shared, so wall time says more about the neighbours than about the plan;
``--repeat N`` keeps each plan's least of N runs, which is steadier still). The first call is replayed once untimed
before: what a process pays once (loading the compiled kernels) is no plan's cost.
Printed per robot: the plans' p50, p95 and max CPU time [s] and the ratio of each to the replan period (the
baseline of the same run: a plan fits when the ratio is below 1).

Scenes: the shipped ``panda_crossing`` and ``xarm7_crossing`` scenarios and the first ``--bench-scenes`` Panda
scenes of a bench folder's ``scenes.jsonl`` (``--bench-folder``, e.g. the ``--out`` of ``previewctl bench --robot
panda``; without it, or when it holds none, only the shipped scenarios run, and it is said so). ``--save FILE``
keeps the recorded calls and the plans they made (a pickle of plain fields);
``--load FILE`` replays them without running the scenes again and counts the plans that come out different
(a speed-up that must not change the plans shows 0); with ``--save FILE`` too, it keeps the calls with the plans this
code made (a baseline for a later code, when the recorded plans came from an older one).

Run: ``PYTHONPATH=. python benchmarks/bench_plan.py [--quick] [--save calls.pkl | --load calls.pkl]``.
``--quick``: the Panda crossing scene only, ``horizon`` only, its first second (a smoke run).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pickle
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.control import planner as planner_module
from previewctl.control.planner import PlanTiming
from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.search.reachability.goals import Goals
from previewctl.search.roadmap import RoadmapOptions, roadmap_over_time
from previewctl.sim.loop import simulate
from previewctl.sim.paper import shipped_scenarios_dir
from previewctl.sim.scenario import Scenario, load_scenario, scenario_from_dict

CONTROLLERS = ("reach", "horizon")
SCENARIOS = ("panda_crossing", "xarm7_crossing")


@dataclass(frozen=True)
class Call:
    """One recorded plan: where it starts, what it searches, and the motion it made."""

    scene: str
    controller: str
    q: np.ndarray
    t: float
    duration: float
    options: RoadmapOptions
    goals: tuple[Goals, ...]
    motion: np.ndarray


def _scenes(args: argparse.Namespace) -> Iterator[tuple[str, dict[str, Any] | Path]]:
    """``(name, source)``: a scenario file or a bench scene's document."""
    for name in SCENARIOS[:1] if args.quick else SCENARIOS:
        yield name, shipped_scenarios_dir() / f"{name}.toml"
    if args.quick or not args.bench_scenes or args.bench_folder is None:
        return
    records = args.bench_folder / "scenes.jsonl"
    if not records.is_file():
        print(f"(no {records}: bench scenes skipped)")
        return
    lines = [json.loads(line) for line in records.read_text().splitlines() if line.strip()]
    panda = sorted((r for r in lines if r["document"]["robot"]["source"] == "panda"), key=lambda r: r["index"])
    for record in panda[: args.bench_scenes]:
        yield record["document"]["name"], record["document"]


@dataclass(frozen=True)
class World:
    """What a recorded call is replayed in: the scene's source, its evaluator and path, and the replan period [s]."""

    source: dict[str, Any] | Path
    evaluator: Evaluator
    path: HandPath
    replan: float

    @classmethod
    def of(cls, source: dict[str, Any] | Path) -> World:
        scenario = _scenario(source)
        return cls(source, Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential),
                   scenario.path, PlanTiming.of(scenario.controller.params).replan_period)


def _scenario(source: dict[str, Any] | Path) -> Scenario:
    return load_scenario(source) if isinstance(source, Path) else scenario_from_dict(source, source="bench")


def record(args: argparse.Namespace) -> tuple[list[Call], dict[str, World]]:
    """Run every scene with every controller and record the window planner's searches."""
    calls: list[Call] = []
    worlds: dict[str, World] = {}
    controllers = ("horizon",) if args.quick else args.controller.split(",")
    for name, source in _scenes(args):
        scenario = _scenario(source)
        if args.quick:
            scenario = dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=1.0))
        for controller in controllers:
            def recorder(robot: Any, evaluator: Evaluator, path: HandPath, q: np.ndarray, duration: float,
                         options: RoadmapOptions | None = None, *, t_start: float = 0.0,
                         goals: Any = (), _scene: str = name, _controller: str = controller) -> Any:
                found = roadmap_over_time(robot, evaluator, path, q, duration, options, t_start=t_start, goals=goals)
                calls.append(Call(_scene, _controller, np.array(q), t_start, duration, options or RoadmapOptions(),
                                  tuple(Goals(g.t, np.array(g.q), np.array(g.score)) for g in goals),
                                  found.motion.q.copy()))
                return found

            planner_module.roadmap_over_time = recorder  # type: ignore[assignment]
            try:
                simulate(scenario, controller)
            finally:
                planner_module.roadmap_over_time = roadmap_over_time
        worlds[name] = World.of(source)
    return calls, worlds


def replay(calls: list[Call], worlds: dict[str, World], repeat: int) -> tuple[dict[str, list[float]], list[Call]]:
    """CPU time [s] of every call (the least of ``repeat`` runs), per robot, and the calls with the plans replayed;
    prints how many plans differ from the recorded ones."""
    times: dict[str, list[float]] = {}
    replayed: list[Call] = []
    changed = 0
    for call in calls[:1]:  # once untimed: one-time costs (the compiled kernels' loading) are no plan's
        world = worlds[call.scene]
        roadmap_over_time(world.evaluator.robot, world.evaluator, world.path, call.q, call.duration, call.options,
                          t_start=call.t, goals=call.goals)
    for call in calls:
        world = worlds[call.scene]
        robot = world.evaluator.robot
        spent = []
        for _ in range(repeat):
            start = time.process_time()
            found = roadmap_over_time(robot, world.evaluator, world.path, call.q, call.duration, call.options,
                                      t_start=call.t, goals=call.goals)
            spent.append(time.process_time() - start)
        times.setdefault(robot.name, []).append(min(spent))
        changed += not np.array_equal(found.motion.q, call.motion)
        replayed.append(dataclasses.replace(call, motion=found.motion.q.copy()))
    print(f"{len(calls)} plans replayed, {changed} differ from the recorded ones")
    return times, replayed


def _save(file: Path, calls: list[Call], worlds: dict[str, World]) -> None:
    """Keep ``calls`` and their scenes' sources in ``file`` (a pickle of plain fields)."""
    sources = {name: world.source for name, world in worlds.items()}
    file.write_bytes(pickle.dumps(([vars(call) for call in calls], sources)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="Panda crossing, horizon, 1 s: a smoke run")
    parser.add_argument("--controller", default=",".join(CONTROLLERS), help="controllers whose plans to record")
    parser.add_argument("--bench-scenes", type=int, default=3, help="Panda bench scenes to add (0: none)")
    parser.add_argument("--bench-folder", type=Path, metavar="DIR",
                        help="a previewctl bench output folder whose Panda scenes to add (default: none)")
    parser.add_argument("--repeat", type=int, default=1, help="time each plan this many times, keep the least")
    parser.add_argument("--save", type=Path, help="keep the recorded (with --load: the replayed) calls in this file")
    parser.add_argument("--load", type=Path, help="replay the calls kept in this file instead of running scenes")
    args = parser.parse_args(argv)
    if args.load:
        kept, sources = pickle.loads(args.load.read_bytes())
        calls = [Call(**fields) for fields in kept]
        worlds = {name: World.of(source) for name, source in sources.items()}
    else:
        calls, worlds = record(args)
        if args.save:
            _save(args.save, calls, worlds)
    replans = {worlds[c.scene].evaluator.robot.name: worlds[c.scene].replan for c in calls}
    times, replayed = replay(calls, worlds, args.repeat)
    if args.load and args.save:
        _save(args.save, replayed, worlds)
    print(f"{'robot':8s} {'plans':>5s} {'p50 [s]':>8s} {'p95 [s]':>8s} {'max [s]':>8s} {'period':>7s}  "
          "p50/period p95/period max/period")
    for robot, spent in times.items():
        p50, p95, top = np.percentile(spent, 50), np.percentile(spent, 95), max(spent)
        period = replans[robot]
        print(f"{robot:8s} {len(spent):5d} {p50:8.3f} {p95:8.3f} {top:8.3f} {period:7.2f}  "
              f"{p50 / period:10.2f} {p95 / period:10.2f} {top / period:10.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
