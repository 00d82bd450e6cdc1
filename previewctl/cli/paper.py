"""``previewctl paper``: the paper's planar experiment with every controller on both canonical scenes."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from previewctl.cli.common import Commands, ProgressBar, verdict_text
from previewctl.errors import PreviewctlError
from previewctl.sim.log import RunResult
from previewctl.sim.paper import CANONICAL_SCENES, PAPER_CONTROLLERS, run_paper_scenes
from previewctl.sim.scenario import Scenario
from previewctl.viz.figures import make_figures


def add_parser(commands: Commands) -> None:
    """The ``paper`` subcommand and its options."""
    paper = commands.add_parser(
        "paper",
        help="the paper's planar experiment with every controller (the main job)",
        description="Run the canonical planar scenes (scenarios/paper_fitted.toml: planar4 tracing five 0.75 m "
        "segments fitted to the paper's Table 3 along a target object, 50 s; scenarios/paper_planar.toml: the "
        "inverted staircase with a pillar trap) with none, gradient, single (t~ = 10 s), multi (t~ = 5 s, "
        "k = 0.3, 0.65, 0.05), reach and the non-causal oracle; print one comparison table per scene; write "
        "each run's log and figures to OUT/<scene>/<controller>/ and OUT/summary.json.",
    )
    paper.add_argument("--out", default="out/paper", help="output folder (default out/paper)")
    paper.add_argument("--controllers", help="comma-separated subset, e.g. single,multi (default: all)")
    paper.add_argument("--scenes", help="comma-separated subset, e.g. paper_fitted (default: both canonical scenes)")
    paper.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    paper.add_argument("--tolerance", type=float,
                       help="largest hand error [m] of a successful run (default: each scene's [verdict] "
                       "tolerance, 0.005); the tables say which runs succeed, the exit status stays 0")
    paper.add_argument("--no-gif", action="store_true", help="do not write the animated GIFs")
    paper.set_defaults(func=cmd_paper)


def _names(option: str | None, valid: tuple[str, ...], flag: str) -> list[str]:
    names = [n.strip() for n in option.split(",")] if option else list(valid)
    for name in names:
        if name not in valid:
            raise PreviewctlError(f"{flag}: unknown name {name!r}; valid: {', '.join(valid)}")
    return names


def _table(scene: str, summaries: dict[str, dict[str, Any]], out: Path) -> None:
    print(f"\n{scene} (scenarios/{scene}.toml), 50 s; figures and logs in {out / scene}/<controller>/")
    header = (f"{'controller':<11}{'success':<60}{'max hand err':>13}{'min clear':>11}"
              f"{'mean S':>9}{'min S':>9}{'max|qd|':>9}{'cycle med/max [ms]':>20}")
    print(header)
    print("-" * len(header))
    for name, s in summaries.items():
        verdict = verdict_text(s, digits=2)
        clearance = "-" if s["min_clearance"] is None else f"{s['min_clearance'] * 1e3:.1f} mm"
        print(f"{name:<11}{verdict:<60}{s['max_hand_error'] * 1e3:>10.2f} mm{clearance:>11}{s['mean_S']:>9.0f}"
              f"{s['min_S']:>9.0f}{s['max_abs_qdot']:>9.3f}"
              f"{s['cycle_time_median'] * 1e3:>11.2f} / {s['cycle_time_max'] * 1e3:.1f}")


def cmd_paper(args: argparse.Namespace) -> int:
    """Run the canonical planar scenes with every controller: comparison tables, figures, summary.json."""
    names = _names(args.controllers, tuple(PAPER_CONTROLLERS), "--controllers")
    scenes = _names(args.scenes, CANONICAL_SCENES, "--scenes")
    out = Path(args.out)
    bars: list[ProgressBar] = []

    def progress(scene: str, name: str) -> Callable[[float, float], None]:
        if bars:
            bars[-1].close()
        bars.append(ProgressBar(f"{scene}/{name:<9}"))
        return bars[-1].update

    def figures(name: str, scenario: Scenario, result: RunResult, folder: Path) -> None:
        make_figures(result, scenario, folder, gif=False if args.no_gif else None)

    try:
        results = run_paper_scenes(
            out, scenes=scenes, controllers=names, seed=args.seed, progress=progress, after_run=figures,
            tolerance=args.tolerance,
        )
    finally:
        if bars:
            bars[-1].close()
    for scene, summaries in results.items():
        _table(scene, summaries, out)
    print(f"written {out / 'summary.json'} (and {out}/<scene>/summary.json)")
    return 0
