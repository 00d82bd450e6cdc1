"""Preview control over seeds: every controller on a scene, over the given seeds, one table per scene.

For each (scene, controller): how many seeds succeeded (free of collisions with obstacles and of self-collision,
and max hand error < 5 mm), how many finished collision-free, the median time of the first collision (over the
seeds that collided), the worst hand error over all seeds, and the mean S over the runs. Runs go to a process pool
(``--workers``,
default: the number of cores). A controller that draws no random numbers (not one of
``SEEDED_CONTROLLERS``) gives the same run for every seed, so it runs once and counts for every seed
(``run_seed``).

Run: ``python benchmarks/bench_preview.py [--seed 0-9] [--controller none,multi,...] [scenario.toml ...]``
(default scenes: the shipped planar scenes). ``--set key=value`` overrides a controller parameter,
e.g. ``--set coherent=false`` for the paper-literal eqs. 20/21, ``--set execution=pseudoinverse`` for the
paper's eq. 19 instead of the QP.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.cli.common import seed_list
from previewctl.control.params import (
    CONTROLLER_NAMES,
    ControllerParams,
    ControllerSpec,
    run_seed,
)
from previewctl.errors import PreviewctlError, UnknownNameError
from previewctl.sim.loop import simulate
from previewctl.sim.paper import shipped_scenarios_dir
from previewctl.sim.scenario import Scenario, load_scenario
from previewctl.validation.toml import toml_value

DEFAULT_SCENES = ("paper_planar.toml",)
SUCCESS_TOLERANCE = 5e-3  # [m]


def _override(scenario: Scenario, settings: dict[str, str]) -> Scenario:
    """``scenario`` with controller parameters overridden from ``key=value`` strings, each value read as the
    scenario file's ``[controller]`` table would hold it (:func:`~previewctl.validation.toml.toml_value`).

    Raises:
        UnknownNameError: a key that is no ``ControllerParams`` field (the valid ones listed).
        ParameterError: a value the field does not take.
    """
    fields = [f.name for f in dataclasses.fields(ControllerParams)]
    for key in settings:
        if key not in fields:
            raise UnknownNameError("controller parameter", key, fields)
    typed: dict[str, Any] = {key: toml_value(text) for key, text in settings.items()}
    params = dataclasses.replace(scenario.controller.params, **typed)
    return dataclasses.replace(scenario, controller=dataclasses.replace(scenario.controller, params=params))


def run_one(job: tuple[str, str, int, dict[str, str]]) -> tuple[str, str, int, dict[str, float]]:
    """One run: ``(scene path, controller, seed, overrides)`` -> its outcome."""
    path, controller, seed, settings = job
    result = simulate(_override(load_scenario(path), settings), controller, seed=seed)
    summary = result.summary()
    S = np.asarray(result.S)
    return path, controller, seed, {
        "collided": float(summary["collided"] or summary["self_collided"]),
        "collision_time": float(summary["collision_time"]) if summary["collided"] else np.nan,
        "max_hand_error": float(summary["max_hand_error"]),
        "mean_S": float(np.mean(S[S > 0])) if np.any(S > 0) else 0.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", help="scenario files (default: the shipped planar scenes)")
    parser.add_argument("--seed", type=seed_list, default=tuple(range(10)), metavar="SEEDS",
                        help="controller seeds: a comma list or ranges, e.g. 0-9 (default 0-9)")
    parser.add_argument("--controller", default=",".join(CONTROLLER_NAMES), metavar="NAMES",
                        help="comma-separated controllers (default: all)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="controller parameter")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, metavar="N", help="worker processes")
    args = parser.parse_args()
    scenes = [str(Path(s)) for s in args.scenes] or [str(shipped_scenarios_dir() / s) for s in DEFAULT_SCENES]
    if any("=" not in item for item in args.set):
        parser.error(f"--set takes KEY=VALUE, got {next(item for item in args.set if '=' not in item)!r}")
    settings = dict(item.split("=", 1) for item in args.set)
    controllers = args.controller.split(",")
    try:  # bad settings, scenes or names: one line, before any run
        for scene in scenes:
            _override(load_scenario(scene), settings)
        for name in controllers:
            ControllerSpec(name)
    except PreviewctlError as exc:
        sys.exit(f"bench_preview: {exc}")
    # a controller that draws no random numbers makes the same run for every seed: run it once, count it per seed
    seeds = args.seed
    jobs = [(s, c, seed, settings) for s in scenes for c in controllers
            for seed in dict.fromkeys(run_seed(c, k) for k in seeds)]
    outcomes: dict[tuple[str, str], list[dict[str, float]]] = {}
    with ProcessPoolExecutor(args.workers) as pool:
        for path, controller, seed, outcome in pool.map(run_one, jobs):
            copies = sum(run_seed(controller, other) == seed for other in seeds)
            outcomes.setdefault((path, controller), []).extend([outcome] * copies)
    for scene in scenes:
        print(f"\n{Path(scene).name}, seeds {','.join(map(str, seeds))}{', ' + str(settings) if settings else ''}")
        print(f"{'controller':<10}{'success':>9}{'collision-free':>16}{'first collision (median)':>26}"
              f"{'max hand error':>16}{'mean S':>9}")
        for controller in controllers:
            rows = outcomes[(scene, controller)]
            free = sum(r["collided"] == 0.0 for r in rows)
            success = sum(r["collided"] == 0.0 and r["max_hand_error"] < SUCCESS_TOLERANCE for r in rows)
            times = [r["collision_time"] for r in rows if r["collided"]]
            first = f"{np.median(times):.2f} s" if times else "-"
            error = max(r["max_hand_error"] for r in rows) * 1e3
            mean_S = np.mean([r["mean_S"] for r in rows])
            counts = f"{f'{success} / {len(rows)}':>9}{f'{free} / {len(rows)}':>16}"
            print(f"{controller:<10}{counts}{first:>26}{error:>13.2f} mm{mean_S:>9.0f}")


if __name__ == "__main__":
    main()
