"""``previewctl paper``: the paper's planar experiment with every controller (the main job)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from previewctl.cli.common import Commands, ProgressBar
from previewctl.errors import PreviewctlError
from previewctl.sim.log import RunResult
from previewctl.sim.paper import PAPER_CONTROLLERS, run_paper
from previewctl.sim.scenario import Scenario
from previewctl.viz.figures import make_figures


def add_parser(commands: Commands) -> None:
    """The ``paper`` subcommand and its options."""
    paper = commands.add_parser(
        "paper",
        help="the paper's planar experiment with every controller (the main job)",
        description="Run the canonical planar scene (scenarios/paper_planar.toml: planar4 tracing five 0.75 m "
        "segments along an inverted staircase in 50 s, with a pillar trap) with none, gradient, single "
        "(t~ = 10 s), multi (t~ = 5 s, k = 0.3, 0.65, 0.05) and reach; print the comparison table; write "
        "each run's log and figures to OUT/<controller>/ and OUT/summary.json.",
    )
    paper.add_argument("--out", default="out/paper", help="output folder (default out/paper)")
    paper.add_argument("--controllers", help="comma-separated subset, e.g. single,multi (default: all five)")
    paper.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    paper.add_argument("--no-gif", action="store_true", help="do not write the animated GIFs")
    paper.set_defaults(func=cmd_paper)


def cmd_paper(args: argparse.Namespace) -> int:
    """Run the canonical planar scene with every controller: comparison table, figures, summary.json."""
    names = [n.strip() for n in args.controllers.split(",")] if args.controllers else list(PAPER_CONTROLLERS)
    for name in names:
        if name not in PAPER_CONTROLLERS:
            raise PreviewctlError(f"--controllers: unknown controller {name!r}; valid: {', '.join(PAPER_CONTROLLERS)}")
    out = Path(args.out)
    bars: list[ProgressBar] = []

    def progress(name: str) -> Callable[[float, float], None]:
        if bars:
            bars[-1].close()
        bars.append(ProgressBar(f"{name:<9}"))
        return bars[-1].update

    def figures(name: str, scenario: Scenario, result: RunResult, folder: Path) -> None:
        make_figures(result, scenario, folder, gif=False if args.no_gif else None)

    try:
        summaries = run_paper(out, controllers=names, seed=args.seed, progress=progress, after_run=figures)
    finally:
        if bars:
            bars[-1].close()
    print(f"\ncanonical planar scene (scenarios/paper_planar.toml), 50 s; figures and logs in {out}/<controller>/")
    header = (f"{'controller':<11}{'collision-free':<30}{'max hand err':>13}{'min clear':>11}"
              f"{'mean S':>9}{'min S':>9}{'max|qd|':>9}{'cycle med/max [ms]':>20}")
    print(header)
    print("-" * len(header))
    for name, s in summaries.items():
        verdict = (f"NO: t={s['collision_time']:.2f} s {s['collision_link']}" if s["collided"] else "yes")
        clearance = "-" if s["min_clearance"] is None else f"{s['min_clearance'] * 1e3:.1f} mm"
        print(f"{name:<11}{verdict:<30}{s['max_hand_error'] * 1e3:>10.2f} mm{clearance:>11}{s['mean_S']:>9.0f}"
              f"{s['min_S']:>9.0f}{s['max_abs_qdot']:>9.3f}"
              f"{s['cycle_time_median'] * 1e3:>11.2f} / {s['cycle_time_max'] * 1e3:.1f}")
    print(f"written {out / 'summary.json'}")
    return 0
