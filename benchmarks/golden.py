"""Golden run logs: record every distinct controller × execution run, then check a later code gives the same bits.

A restructure that must not change behaviour is checked with it, before and after::

    python benchmarks/golden.py record /tmp/golden-before      # at the old commit
    python benchmarks/golden.py record /tmp/golden-after       # at the new one
    python benchmarks/golden.py compare /tmp/golden-before /tmp/golden-after

The runs: every controller name under each execution it runs (``none`` under the pseudo-inverse, ``qp`` under the
QP, every other under both) on ``paper_fitted`` and ``panda_crossing`` and on one planar and one Panda bench scene,
and on the two bench scenes the law variants that flags select (the paper-literal modes, tracked peaks, the local
gradient term, a plan latency). ``compare`` checks every array of every ``run.npz`` that the first folder holds,
bit for bit (NaNs equal), but the wall-clock cycle times, and names each difference; fields that only the second
folder has are not compared. The bench scenes' documents are stored in the first folder, so ``record`` of the second
reads them from there instead of drawing them again (``--scenes``).
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

CONTROLLERS = ("none", "qp", "gradient", "single", "multi", "reach", "horizon", "oracle")
EXECUTIONS = ("qp", "pseudoinverse")
BENCH_SCENES = (("planar4", 3), ("panda", 8))
WALL_CLOCK = ("cycle_time", "loop_time")
"""The arrays that measure wall time, which no two runs share: not compared."""
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "multi-peaks": ("multi", {"imaginary_arms": "peaks"}),
    "multi-literal": ("multi", {"coherent": False}),
    "single-literal": ("single", {"coherent": False}),
    "reach-literal": ("reach", {"coherent": False}),
    "single-gradient": ("single", {"with_gradient": True}),
    "multi-peaks-gradient": ("multi", {"imaginary_arms": "peaks", "with_gradient": True}),
    "multi-gradient": ("multi", {"with_gradient": True}),
    "horizon-latency": ("horizon", {"plan_latency": 0.2}),
    "reach-latency": ("reach", {"plan_latency": 0.2}),
}


def _distinct(name: str, execution: str) -> bool:
    """``none`` under the QP is the ``qp`` run, ``qp`` under the pseudo-inverse the ``none`` run."""
    return (name, execution) not in (("none", "qp"), ("qp", "pseudoinverse"))


def _jobs(scene_docs: dict[str, dict[str, Any]]) -> list[tuple[str, str, str, str, dict[str, Any]]]:
    """``(label, scene, controller, execution, overrides)`` of every run."""
    jobs: list[tuple[str, str, str, str, dict[str, Any]]] = []
    scenes = ["paper_fitted", "panda_crossing", *scene_docs]
    for scene in scenes:
        for name in CONTROLLERS:
            for execution in EXECUTIONS:
                if _distinct(name, execution):
                    jobs.append((f"{scene}/{name}-{execution}", scene, name, execution, {}))
    for scene in scene_docs:
        for label, (name, overrides) in VARIANTS.items():
            executions = EXECUTIONS if scene.startswith("planar") else ("qp",)
            for execution in executions:
                jobs.append((f"{scene}/{label}-{execution}", scene, name, execution, overrides))
    return jobs


def _scenario(scene: str, scene_docs: dict[str, dict[str, Any]]) -> Any:
    from previewctl.sim.paper import shipped_scenarios_dir
    from previewctl.sim.scenario import load_scenario, scenario_from_dict

    if scene in scene_docs:
        return scenario_from_dict(scene_docs[scene], source=scene)
    return load_scenario(shipped_scenarios_dir() / f"{scene}.toml")


def _run(job: tuple[str, str, str, str, dict[str, Any]], scene_docs: dict[str, dict[str, Any]], out: str) -> str:
    import time

    from previewctl.control.params import ControllerSpec
    from previewctl.sim.log import save_run
    from previewctl.sim.loop import simulate

    label, scene, name, execution, overrides = job
    scenario = _scenario(scene, scene_docs)
    params = replace(scenario.controller.params, execution=execution, **overrides)
    scenario = replace(scenario, controller=ControllerSpec(name, params))
    start = time.perf_counter()
    result = simulate(scenario)
    save_run(result, Path(out) / label)
    return f"{label}: {result.steps} steps, {time.perf_counter() - start:.1f} s"


def record(out: Path, scenes_from: Path | None, workers: int, only: str = "") -> None:
    """Run every job (whose label starts with ``only``) into ``out/<scene>/<label>/run.npz``."""
    docs_file = (scenes_from or out) / "scenes.json"
    if docs_file.is_file():
        scene_docs = json.loads(docs_file.read_text())
    else:
        from previewctl.bench.scenes import generate

        scene_docs = {}
        for robot, index in BENCH_SCENES:
            bench = generate(robot, index)
            scene_docs[f"{robot}_{index:03d}"] = bench.document
    out.mkdir(parents=True, exist_ok=True)
    (out / "scenes.json").write_text(json.dumps(scene_docs, indent=1))
    jobs = [job for job in _jobs(scene_docs) if job[0].startswith(only)]
    with ProcessPoolExecutor(workers) as pool:
        for line in pool.map(_run, jobs, [scene_docs] * len(jobs), [str(out)] * len(jobs)):
            print(line, flush=True)


def compare(before: Path, after: Path) -> int:
    """Every array of every run in ``before`` equal in ``after``; the number of differences."""
    differences, runs = 0, 0
    for old in sorted(before.rglob("run.npz")):
        label = old.parent.relative_to(before)
        new = after / label / "run.npz"
        runs += 1
        if not new.is_file():
            print(f"{label}: missing in {after}")
            differences += 1
            continue
        with np.load(old) as a, np.load(new) as b:
            for key in a.files:
                if key in WALL_CLOCK:
                    continue
                if key not in b.files:
                    print(f"{label}: {key} missing")
                    differences += 1
                elif not np.array_equal(a[key], b[key], equal_nan=a[key].dtype.kind in "fc"):
                    print(f"{label}: {key} differs")
                    differences += 1
    print(f"{runs} runs compared, {differences} differences")
    return differences


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="run every job and write its run log")
    rec.add_argument("out", type=Path)
    rec.add_argument("--scenes", type=Path, default=None, help="a golden folder whose bench scenes to reuse")
    rec.add_argument("--workers", type=int, default=2)
    rec.add_argument("--only", default="", help="record only the runs whose label starts with this")
    cmp = sub.add_parser("compare", help="compare two golden folders bit for bit")
    cmp.add_argument("before", type=Path)
    cmp.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    if args.command == "record":
        record(args.out, args.scenes, args.workers, args.only)
        return 0
    return 1 if compare(args.before, args.after) else 0


if __name__ == "__main__":
    sys.exit(main())
