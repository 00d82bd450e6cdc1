"""``previewctl reach-map``: reachability over time of a scenario (the global, non-causal reference): the DP on a
planar arm, the sampled forward search on a spatial one."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.cli.common import add_json_option, print_json
from previewctl.control.planner import ORACLE_GENE_SPEED
from previewctl.files import atomic_write, atomic_write_bytes
from previewctl.index.evaluator import Evaluator
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability import ReachMotion, ReachOptions, ReachResult, reach_over_time
from previewctl.search.reachability.grid import MAX_GRID_NODES, fast_enough, grid_nodes
from previewctl.search.roadmap import RoadmapOptions, roadmap_over_time
from previewctl.sim.scenario import Scenario, load_scenario


def add_parser(sub: Any) -> None:
    """Register ``reach-map`` on the subcommand table ``sub`` (from ``add_subparsers``)."""
    defaults = ReachOptions()
    parser = sub.add_parser(
        "reach-map",
        help="can the arm track the whole path without collision? (planar: DP over grid x time; spatial: a "
        "sampled search)",
        description="Reachability over time (the paper's section 5.1 made exact on a grid): dynamic programming "
        "over the redundancy grid (q1 .. q(n-2) x both elbow branches) x time, from the scenario's q0, with "
        "S > 0 as the feasible set, every joint within its speed limit per step (the elbow switching only "
        "through the stretched wrist) and a sweep bound that keeps the motion between samples collision-free. "
        "Prints whether a collision-free tracking motion exists (else where every motion gets stuck), the "
        "latest time by which the arm must commit to a family, the best minimum S of a motion and the time "
        "taken. A 'no' is relative to the grid, the time step and the per-step gene cap. The DP needs a planar "
        "arm of 2-4 joints (see previewctl.search.reachability for every definition). On a spatial arm the "
        "grid options do not apply: a sampled forward search over time (previewctl.search.roadmap, the spatial "
        "oracle's) says whether it found a collision-free tracking motion (checked at samples 0.05 s apart; a "
        "'no' only means that it found none), its best minimum S and the time taken.",
    )
    parser.add_argument("scenario", help="scenario TOML file (see scenarios/)")
    parser.add_argument("--resolution", type=float, default=defaults.resolution_deg,
                        help=f"gene grid step [deg] (default {defaults.resolution_deg:g})")
    parser.add_argument("--steps", type=int, default=None,
                        help=f"time steps over the scenario's duration (default: at least {defaults.steps}, and as "
                        f"many more as let a gene move at {100 * ORACLE_GENE_SPEED:.0f}%% of its joint speed limit, "
                        "with the grid coarsened (2x, 4x, ...) where that many steps would not fit the memory budget: "
                        "the oracle's model)")
    parser.add_argument("--max-step-cells", type=int, default=defaults.max_step_cells,
                        help="most grid cells a gene may move per step; the gene speed bound is this x resolution / "
                        f"step, or the joint limit if lower (default {defaults.max_step_cells})")
    parser.add_argument("--s-min", type=float, default=defaults.s_min,
                        help=f"feasible cells have S > S_MIN (default {defaults.s_min:g})")
    parser.add_argument("--velocity-scale", type=float, default=defaults.velocity_scale,
                        help="fraction of the URDF joint speed limits the motion may use (default 1)")
    parser.add_argument("--start-families", action="store_true",
                        help="also report the components of S > S_MIN at t = 0 (the paper's peaks, when S <= 0 "
                        "separates them) and how long each one's reachable set lives; evaluates the whole grid at "
                        "every step")
    parser.add_argument("--out", help="folder for reach_maps.png (Fig. 8-like), reach_motion.png, reach.json and "
                        "reach_motion.npz (a spatial arm: reach.json and reach_motion.npz)")
    add_json_option(parser, "the summary")
    parser.set_defaults(func=cmd_reach_map)


def cmd_reach_map(args: argparse.Namespace) -> int:
    """Run the reachability DP on a scenario; print the verdict, commit time, best min S and time taken."""
    scenario = load_scenario(args.scenario)
    robot = scenario.robot
    if robot.planar is None:
        return _spatial(args, scenario)
    steps = ReachOptions().steps if args.steps is None else args.steps
    options = ReachOptions(resolution_deg=args.resolution, steps=steps, max_step_cells=args.max_step_cells,
                           s_min=args.s_min, velocity_scale=args.velocity_scale, start_families=args.start_families)
    duration = scenario.timing.duration
    # by default, the oracle's steps, unless the asked grid is too fine even for 50 (then the budget error below)
    if args.steps is None and grid_nodes(PlanarRedundancy(robot), options) <= MAX_GRID_NODES:
        options = fast_enough(robot, options, duration, ORACLE_GENE_SPEED)
    evaluator = Evaluator(robot, scenario.scene, scenario.index, scenario.potential)
    result = reach_over_time(robot, evaluator, scenario.path, scenario.q0, duration, options)
    summary: dict[str, Any] = {"scenario": scenario.name, "robot": robot.name, "duration": duration,
                               **result.summary()}
    written: list[str] = []
    if args.out:
        from previewctl.viz.reach import plot_reach_maps, plot_reach_motion

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        if result.axes:
            written.append(str(plot_reach_maps(result, out / "reach_maps.png")))
        written.append(str(plot_reach_motion(result, out / "reach_motion.png")))
        written = _write_results(out, summary, result.motion, written)
    if args.json:
        print_json(summary)
        return 0
    _print(summary, result, written, asked_resolution=args.resolution)
    return 0


def _spatial(args: argparse.Namespace, scenario: Scenario) -> int:
    """``reach-map`` on a spatial arm: the sampled forward search from ``q0`` over the whole scenario."""
    robot, duration = scenario.robot, scenario.timing.duration
    evaluator = Evaluator(robot, scenario.scene, scenario.index, scenario.potential)
    options = RoadmapOptions()
    started, cpu = time.perf_counter(), time.process_time()
    found = roadmap_over_time(robot, evaluator, scenario.path, scenario.q0, duration, options)
    timings = {"total": time.perf_counter() - started, "cpu": time.process_time() - cpu}
    summary: dict[str, Any] = {
        "scenario": scenario.name, "robot": robot.name, "duration": duration, "search": "sampled",
        "exists": found.exists, "verdict": found.verdict(), "reached": found.reached,
        "best_min_S": None if math.isnan(found.motion.min_S) else found.motion.min_S,
        "evaluations": found.evaluations, "options": dataclasses.asdict(options), "timings_s": timings}
    written: list[str] = []
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        written = _write_results(out, summary, found.motion, [])
    if args.json:
        print_json(summary)
        return 0
    rows = [("scenario", f"{scenario.name} ({robot.name}), {duration:g} s"),
            ("search", f"sampled forward search: layers every {options.step:g} s, {options.beam} kept "
                       f"configurations, {options.children} moves each at up to {options.speed_share:.0%} of the "
                       f"joint speed limits, samples every {options.step / (options.substeps + 1):g} s at least "
                       f"{1e3 * options.margin:g} mm from every obstacle; seed {options.seed}"),
            ("verdict", found.verdict()),
            ("time taken", f"{timings['total']:.2f} s wall, {timings['cpu']:.2f} s CPU; {found.evaluations} "
                           "configurations evaluated")]
    rows += [("written", path) for path in written]
    for label, value in rows:
        print(f"{label:<18}{value}")
    return 0


def _write_results(out: Path, summary: dict[str, Any], motion: ReachMotion, figures: list[str]) -> list[str]:
    """Write ``reach.json`` (``summary``, its ``files`` listing every file written) and ``reach_motion.npz`` into
    ``out``; the paths of ``figures`` and of both files, in that order."""
    written = [*figures, str(out / "reach.json"), str(out / "reach_motion.npz")]
    summary["files"] = list(written)
    atomic_write_bytes(out / "reach.json", (json.dumps(summary, indent=2) + "\n").encode())
    save_motion(motion, out / "reach_motion.npz")
    return written


def save_motion(motion: ReachMotion, path: Path) -> Path:
    """Write a motion (``times`` [s], ``q`` [rad], ``S``, ``branch``) to an ``.npz`` file, atomically."""
    atomic_write(path, lambda f: np.savez(f, times=motion.times, q=motion.q, S=motion.S, branch=motion.branch))
    return path


def _print(summary: dict[str, Any], result: ReachResult, written: list[str], *, asked_resolution: float) -> None:
    grid = summary["grid"]
    shape = " x ".join(f"{n} ({lo:g}..{hi:g})" for lo, hi, n in grid["gene_axes_deg"]) or "1"
    steps_deg = ", ".join("-" if v is None else f"{v:.3g}" for v in grid["joint_step_deg"])
    gene_speed = ", ".join(f"{v:.3g}" for v in grid["gene_speed_deg_s"])
    rows: list[tuple[str, str]] = [
        ("scenario", f"{summary['scenario']} ({summary['robot']}), {summary['duration']:g} s"),
        ("grid", f"{grid['resolution_deg']:g} deg over the joint limits: {shape} deg x 2 elbow branches, "
                 f"{grid['steps']} steps of {grid['dt']:.4g} s"),
        ("transition model", f"joints <= [{steps_deg}] deg per step; genes <= {grid['gene_cells_per_step']} cells "
                             f"per step = [{gene_speed}] deg/s; feasible: S > {grid['s_min']:g}"),
        ("verdict", summary["verdict"]),
        ("best min S", "-" if summary["best_min_S"] is None else
         f"{summary['best_min_S']:.2f} over t >= {result.times[1]:.4g} s (S at q0 = {summary['q0_S']:.2f})"),
    ]
    switches = summary["motion"]["elbow_switch_times"]
    if switches:
        rows.append(("best motion", "elbow switch (stretched wrist) near t = "
                     + ", ".join(f"{t:.3g}" for t in switches) + " s"))
    families = summary["end_families"]
    if summary["commit_time"] is not None:
        commit = (f"t = {summary['commit_time']:g} s: until then the arm can keep two of the {len(families)} end "
                  "families reachable, afterwards it is committed to one")
        best = next((f for f in families if f["label"] == summary["best_family"]), None)
        if best is not None and best.get("shared_until") is not None:
            commit += (f"; the best motion's family ({best['label']}) can be left until t = "
                       f"{best['shared_until']:g} s")
    elif families:
        commit = "none needed: every motion from q0 ends in one family"
    else:
        commit = "-"
    rows.append(("commit time", commit))
    timings = summary["timings_s"]
    rows.append(("time taken", f"{timings['total']:.2f} s wall, {timings['cpu']:.2f} s CPU (maps "
                               f"{timings['maps']:.2f}, edges {timings['edges']:.2f}, dp {timings['dp']:.2f}, figures' "
                               f"maps / start families {timings['extras']:.2f}); {summary['edges']} transitions"))
    limit = [math.degrees(v) / grid["dt"] for v in result.joint_step[: len(result.gene_cells)]]
    slow = [(s, v) for s, v in zip(grid["gene_speed_deg_s"], limit, strict=True) if s < v - 1e-9]
    if slow:
        rows.append(("note", f"genes may move only {slow[0][0]:.3g} deg/s in this model (joint limit "
                             f"{slow[0][1]:.3g} deg/s): a 'no' or a low best min S can be the model's; raise "
                             "--steps or --max-step-cells to check"))
    if grid["resolution_deg"] != asked_resolution:
        rows.append(("note", f"the grid is {grid['resolution_deg']:g} deg, not {asked_resolution:g}: with "
                             f"{grid['steps']} steps (for the genes' speed) the finer grid would not fit the memory "
                             "budget; give --steps to keep the resolution"))
    for label, value in rows:
        print(f"{label:<18}{value}")
    end_label = "end families" if result.exists else f"families at the dead end t = {result.dead_end:g} s"
    for title, items in ((end_label, families), ("start families", summary["start_families"])):
        if not items:
            continue
        print(f"{title}:")
        for f in items:
            extra = []
            if "best_min_S" in f:
                extra.append(f"best min S {f['best_min_S']:.1f}")
            if "alive_until" in f:
                extra.append("reaches the end" if f.get("finishes") else f"dies after t = {f['alive_until']:g} s")
            if f.get("shared_until") is not None:
                extra.append(f"shares cells with another family until t = {f['shared_until']:g} s")
            if f.get("holds_q0"):
                extra.append("holds q0")
            if title == end_label and f["label"] == summary["best_family"]:
                extra.append("the best motion ends here")
            genes = ", ".join(f"{v:.0f}" for v in f["peak_genes_deg"])
            print(f"  {f['label']:>2}: {f['cells']:>6} cells, peak S {f['peak_S']:9.1f} at genes ({genes}) deg, "
                  f"branch {f['peak_branch']}; " + "; ".join(extra))
    for path in written:
        print(f"{'written':<18}{path}")
