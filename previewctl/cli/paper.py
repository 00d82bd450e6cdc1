"""``previewctl paper``: the paper's planar experiment with every controller on both canonical scenes."""

from __future__ import annotations

import argparse
import functools
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from tqdm import tqdm

from previewctl.bench.paper_report import write_paper_report
from previewctl.cli.common import Commands, DeprecatedFlag, add_json_option, print_json, seed_value
from previewctl.control.params import EXECUTION_MODES
from previewctl.errors import PreviewctlError
from previewctl.sim.log import RunResult
from previewctl.sim.paper import (
    CANONICAL_SCENES,
    PAPER_CONTROLLERS,
    PaperRun,
    canonical_scenario,
    paper_plan,
    run_paper_scenes,
)
from previewctl.sim.scenario import Scenario
from previewctl.sim.verdict import verdict_text
from previewctl.viz.figures import make_figures
from previewctl.viz.replay import REPLAY_NAME, write_replay


def add_parser(commands: Commands) -> None:
    """The ``paper`` subcommand and its options."""
    paper = commands.add_parser(
        "paper",
        help="the paper's planar experiment with every controller (the main job)",
        description=(
            "Run the canonical planar scenes (scenarios/paper_fitted.toml: planar4 tracing five 0.75 m segments "
            "fitted to the paper's Table 3 along a target object, 50 s; scenarios/paper_planar.toml: the inverted "
            "staircase with a pillar trap) with none, qp, gradient, single (t~ = 10 s), multi (t~ = 5 s, k = 0.3, "
            "0.65, 0.05, its imaginary arms on reach's planned route), reach, horizon (the reachability DP over "
            "the 15 s preview window, replanned every 2.5 s) and the non-causal oracle, each executed by the "
            "constrained QP (label: the controller's name) and by the paper's pseudo-inverse eq. 19 (label: "
            "<name>-pinv), but none (eq. 19 alone: none-pinv) and qp (the QP baseline: qp), which run one each; "
            "print one comparison table per scene; write each "
            "run's log, figures and 3-D replay (replay.html, with the oracle's motion beside it) to "
            "OUT/<scene>/<label>/ and OUT/summary.json."
        )
    )
    paper.add_argument("--out", default="out/paper", help="output folder (default out/paper)")
    paper.add_argument("--controller", metavar="NAMES",
                       help=f"comma-separated subset of {','.join(PAPER_CONTROLLERS)} (default: all)")
    paper.add_argument("--execution", metavar="NAMES",
                       help=f"comma-separated subset of {','.join(EXECUTION_MODES)} (default: all)")
    paper.add_argument("--scenario", metavar="NAMES",
                       help=f"comma-separated subset of the canonical scenarios {','.join(CANONICAL_SCENES)} "
                       "(default: all)")
    paper.add_argument("--seed", type=seed_value, help="random seed (default: the scenario's)")
    paper.add_argument("--tolerance", type=float,
                       help="largest hand error [m] of a successful run (default: each scene's [verdict] "
                       "tolerance, 0.005); the tables say which runs succeed, the exit status stays 0")
    paper.add_argument("--no-gif", action="store_true", help="do not write the animated GIFs")
    paper.add_argument("--no-replay", action="store_true",
                       help=f"do not write the 3-D replays (OUT/<scene>/<label>/{REPLAY_NAME})")
    paper.add_argument("--publish", metavar="FILE.md", type=Path,
                       help="also write the tables, with the date, commit and seed, as Markdown to FILE.md: how the "
                       "documentation's results page of the paper's scenes is made "
                       "(e.g. --publish docs/results/paper.md)")
    paper.add_argument("--workers", type=int, default=os.cpu_count() or 1, metavar="N",
                       help="runs in parallel, one process each (default: the number of cores)")
    add_json_option(paper, "every run's summary, by scenario and label,")
    paper.add_argument("--controllers", dest="controller", action=DeprecatedFlag, use="--controller")
    paper.add_argument("--executions", dest="execution", action=DeprecatedFlag, use="--execution")
    paper.add_argument("--scenes", dest="scenario", action=DeprecatedFlag, use="--scenario")
    paper.add_argument("--jobs", dest="workers", type=int, action=DeprecatedFlag, use="--workers")
    paper.set_defaults(func=cmd_paper)


def _names(option: str | None, valid: tuple[str, ...], flag: str) -> list[str]:
    names = [n.strip() for n in option.split(",")] if option else list(valid)
    for name in names:
        if name not in valid:
            raise PreviewctlError(f"{flag}: unknown name {name!r}; valid: {', '.join(valid)}")
    return names


def _table(scene: str, summaries: dict[str, dict[str, Any]], out: Path) -> None:
    print(f"\n{scene} (scenarios/{scene}.toml), 50 s; figures and logs in {out / scene}/<run>/")
    header = (f"{'run':<15}{'success':<60}{'max hand err':>13}{'min clear':>11}"
              f"{'mean S':>9}{'min S':>9}{'max|qd|':>9}{'cycle med/max [ms]':>20}")
    print(header)
    print("-" * len(header))
    for name, s in summaries.items():
        verdict = verdict_text(s, digits=2)
        clearance = "-" if s["min_clearance"] is None else f"{s['min_clearance'] * 1e3:.1f} mm"
        print(f"{name:<15}{verdict:<60}{s['max_hand_error'] * 1e3:>10.2f} mm{clearance:>11}{s['mean_S']:>9.0f}"
              f"{s['min_S']:>9.0f}{s['max_abs_qdot']:>9.3f}"
              f"{s['cycle_time_median'] * 1e3:>11.2f} / {s['cycle_time_max'] * 1e3:.1f}")


def _figures(label: str, scenario: Scenario, result: RunResult, folder: Path, *, gif: bool) -> None:
    """A run's figures (module level, so that worker processes can receive it)."""
    make_figures(result, scenario, folder, gif=None if gif else False)


def _replay(folder: Path, scene: str) -> None:
    """Write a run's 3-D replay (module level, so that worker processes can receive it)."""
    write_replay(folder, scenario=canonical_scenario(scene))


def cmd_paper(args: argparse.Namespace) -> int:
    """Run the canonical planar scenes with every controller: comparison tables, figures, summary.json."""
    names = _names(args.controller, tuple(PAPER_CONTROLLERS), "--controller")
    executions = _names(args.execution, EXECUTION_MODES, "--execution")
    scenes = _names(args.scenario, CANONICAL_SCENES, "--scenario")
    if args.workers < 1:
        raise PreviewctlError(f"--workers must be >= 1, got {args.workers}")
    if args.publish is not None and args.publish.suffix != ".md":
        raise PreviewctlError(f"--publish takes a Markdown file name ending in .md, got {str(args.publish)!r}")
    out = Path(args.out)
    plan = paper_plan(scenes, names, executions)
    bar = tqdm(total=len(plan), desc="paper runs", unit="run", file=sys.stderr, ascii=".#")

    def done(run: PaperRun, summary: dict[str, Any]) -> None:
        bar.write(f"{run.scene}/{run.label}: success {verdict_text(summary, digits=2)}, max hand error "
                  f"{summary['max_hand_error'] * 1e3:.2f} mm", file=sys.stderr)
        bar.update()

    try:
        results = run_paper_scenes(out, scenes=scenes, controllers=names, executions=executions, seed=args.seed,
                                   jobs=min(args.workers, len(plan)), on_done=done, tolerance=args.tolerance,
                                   after_run=functools.partial(_figures, gif=not args.no_gif))
    finally:
        bar.close()
    if not args.no_replay:  # after every run: each replay shows the scene's oracle run beside it
        folders = [out / run.scene / run.label for run in plan]
        with ProcessPoolExecutor(max(1, min(args.workers, len(plan)))) as pool:
            list(tqdm(pool.map(_replay, folders, [run.scene for run in plan]), total=len(plan),
                      desc="3-D replays", unit="run", file=sys.stderr, ascii=".#"))
    published = None if args.publish is None else write_paper_report(results, args.publish, args.seed)
    if args.json:
        print_json({"out": str(out), "summary_file": str(out / "summary.json"), "scenarios": results,
                    "published": None if published is None else str(published)})
        return 0
    for scene, summaries in results.items():
        _table(scene, summaries, out)
    print(f"written {out / 'summary.json'} (and {out}/<scene>/summary.json)")
    if published is not None:
        print(f"published {published}")
    return 0
