"""``previewctl bench``: every controller x execution mode on seeded solvable scenes, on a Dask cluster."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from tqdm import tqdm

from previewctl.bench.keep import FAILURES_KEPT
from previewctl.bench.pink import BARRIER_GAINS
from previewctl.bench.profiles import PROFILES
from previewctl.bench.report import write_report
from previewctl.bench.results import read_records
from previewctl.bench.runs import FORESIGHT_CONTROLLERS, LATENCIES, LATENCY_CONTROLLERS, OBSERVED_SENSING, SENSINGS
from previewctl.bench.settings import MOTION_KINDS, SceneSettings
from previewctl.bench.sweep import RESULTS_NAME, SCENES_NAME, Sweep, dask_client, keep_runs, run_sweep
from previewctl.cli.common import (
    Commands,
    DeprecatedFlag,
    ExitCode,
    add_json_option,
    print_json,
    seed_count,
    seed_list,
)
from previewctl.control.params import CONTROLLER_NAMES, EXECUTION_MODES, SEEDED_CONTROLLERS
from previewctl.errors import ParameterError


def add_parser(commands: Commands) -> None:
    """The ``bench`` subcommand and its options."""
    bench = commands.add_parser(
        "bench",
        help="benchmark every controller x execution mode on seeded solvable scenes (Dask)",
        description="Generate seeded scenes per robot (a hand path in reach, an obstacle crossing the intermediate "
        "links mid-run, sometimes a second; each draw must pass a solvability witness: the reachability DP on planar4, "
        "a sampled search on spatial arms, finds a collision-free tracking motion and the oracle follows it within "
        "1 mm), run every controller with every execution mode and controller seed (none runs under the "
        "pseudo-inverse only and qp, the QP baseline, under the QP only; the witness's oracle run is recorded, not "
        "run again), and "
        "write OUT/results.jsonl (one line per run, appended as runs finish), OUT/scenes.jsonl, OUT/report.md and "
        "OUT/success.png, and keep the failures (and one success per controller) with their figures and 3-D replays "
        "in OUT/runs/. A rerun does only the runs missing from OUT/results.jsonl. Runs on a local Dask cluster "
        "(one worker process per core) or on the cluster at --scheduler.",
        epilog="example: previewctl bench --robot planar4,panda --scenes 10 --seed 0-2 --workers 2 --out out/bench",
    )
    option = bench.add_argument
    option("--robot", default="planar4", metavar="NAMES",
           help=f"comma-separated robots (default planar4): {', '.join(PROFILES)} (hand-written scene profiles), "
           "any arm `previewctl robots --all` lists or a URDF file (a profile derived from the arm's reach)")
    option("--scenes", type=int, default=10, metavar="N", help="scenes per robot (default 10)")
    option("--controller", metavar="NAMES",
           help=f"comma-separated controllers (default: all of {', '.join(CONTROLLER_NAMES)}); also the pink "
           f"baselines {', '.join(BARRIER_GAINS)} (pink's solve_ik with its collision barrier at the gains of pink's "
           "examples; only when named, under the QP execution only; need pip install 'previewctl[bench]')")
    option("--execution", metavar="NAMES",
           help=f"comma-separated execution modes (default: all of {', '.join(EXECUTION_MODES)})")
    option("--seed", type=seed_list, default=(0,), metavar="SEEDS",
           help="controller seeds per scene, a comma list or ranges, e.g. 0-4 or 0,1,2 (default 0); the controllers "
           f"that draw no random numbers (all but {', '.join(SEEDED_CONTROLLERS)}) run once, as seed 0")
    option("--latency", default="none", metavar="NAMES",
           help=f"comma-separated, when plans take effect (default none): {', '.join(LATENCIES)}; measured: after "
           "each plan's own CPU time, rounded up to control periods, for "
           f"{', '.join(LATENCY_CONTROLLERS)} (the others run once, inline); the report shows these runs as their own "
           "rows beside the inline ones, which a rerun into the same OUT keeps; measured runs depend on the host's "
           "speed and are not bit-reproducible")
    option("--sensing", default="none", metavar="NAMES",
           help=f"comma-separated, what the controllers know of the moving obstacles (default none): "
           f"{', '.join(SENSINGS)}; none: their true motion (perfect foresight); observed: only observations "
           f"({OBSERVED_SENSING.rate:g} Hz, {OBSERVED_SENSING.noise * 1e3:g} mm noise, "
           f"{OBSERVED_SENSING.latency * 1e3:g} ms latency), from which they predict; "
           f"{', '.join(FORESIGHT_CONTROLLERS)} always run with perfect foresight; the report sets the two side by "
           "side")
    option("--motions", default="constant", metavar="KIND",
           help=f"how the crossing obstacles move (default constant): {', '.join(MOTION_KINDS)}; surprise: on the "
           "way to the arm each turns, stops, changes speed or wanders (seeded), which a constant-velocity prediction "
           "does not foresee; the witness keeps the true future")
    option("--history", type=float, default=0.0, metavar="S",
           help="how long [s] before each run starts the crossing obstacles already move and the observed runs' "
           "sensor already observes them, as a robot's camera runs before its task (default 0: both start with the "
           "run); the runs from t = 0 on see the same obstacles")
    option("--scene-seed", type=int, default=0, metavar="N", help="seed the scenes are drawn with (default 0)")
    option("--duration", type=float, metavar="S", help="run length [s] (default: 8 planar4, 10 spatial arms)")
    option("--out", default="out/bench", metavar="DIR", help="output folder (default out/bench)")
    option("--workers", type=int, metavar="N", help="local cluster: worker processes (default: one per core)")
    option("--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler (e.g. tcp://host:8786) "
           "instead of a local cluster; its workers need this same previewctl")
    option("--keep", type=int, default=FAILURES_KEPT, metavar="N",
           help=f"failed runs kept per robot, controller and execution mode, with their log, figures and 3-D replay "
           f"in OUT/runs/ (default {FAILURES_KEPT}; one success each and the multi-vs-qp contrasts are kept too; "
           "0 keeps nothing)")
    option("--report-only", action="store_true", help="only remake report.md and success.png")
    option("--publish", metavar="FILE.md", type=Path,
           help="also write the report, without the kept runs, to FILE.md and its figure beside it (FILE.png): "
           "how the documentation's results pages are made (e.g. --publish docs/results/bench-planar4.md)")
    add_json_option(bench, "what ran and the files written")
    option("--controllers", dest="controller", action=DeprecatedFlag, use="--controller")
    option("--executions", dest="execution", action=DeprecatedFlag, use="--execution")
    option("--seeds", dest="seed", type=seed_count, metavar="N", action=DeprecatedFlag,
           use="--seed (seeds, not a count: --seeds 3 is --seed 0-2)")
    bench.set_defaults(func=cmd_bench)


def _names(text: str | None) -> tuple[str, ...]:
    return tuple(n.strip() for n in text.split(",") if n.strip()) if text else ()


def cmd_bench(args: argparse.Namespace) -> int:
    """Run the missing runs of the sweep, then write the report; exit 1 if a run raised."""
    out = Path(args.out)
    if args.publish is not None and args.publish.suffix != ".md":
        raise ParameterError(f"--publish takes a Markdown file name ending in .md, got {str(args.publish)!r}")
    document: dict[str, object] = {"out": str(out)}
    if not args.report_only:
        if args.keep < 0:
            raise ParameterError(f"--keep must be >= 0, got {args.keep}")
        if args.workers is not None and args.scheduler is not None:
            raise ParameterError("--workers sizes a local cluster; it cannot be used with --scheduler")
        sweep = Sweep(robots=_names(args.robot), scenes=args.scenes, controllers=_names(args.controller),
                      executions=_names(args.execution), seeds=args.seed, scene_seed=args.scene_seed,
                      settings=SceneSettings(duration=args.duration, motions=args.motions, history=args.history),
                      latencies=_names(args.latency), sensings=_names(args.sensing))
        start = time.perf_counter()
        bars: list[tqdm] = []
        try:
            with dask_client(args.scheduler, args.workers) as client:
                outcome = run_sweep(sweep, out, client, on_result=lambda _: bars[-1].update(1),
                                    on_start=lambda n: bars.append(tqdm(total=n, desc="scene-runs", unit="run",
                                                                        file=sys.stderr, mininterval=1.0)))
                if args.keep > 0:
                    keep_runs(out, client, args.keep, on_done=lambda: bars[-1].update(1),
                              on_start=lambda n: bars.append(tqdm(total=n, desc="kept runs (replays)", unit="run",
                                                                  file=sys.stderr, mininterval=1.0)))
        finally:
            for bar in bars:
                bar.close()
        seconds = time.perf_counter() - start
        document |= {"planned": outcome.planned, "done": outcome.done, "skipped": outcome.skipped,
                     "seconds": round(seconds, 3), "failed": [{**dataclasses.asdict(spec), "error": message}
                                                             for spec, message in outcome.failed]}
        if not args.json:
            print(f"{outcome.done} runs done in {seconds:.1f} s, {outcome.skipped} already in "
                  f"{out / RESULTS_NAME}, {len(outcome.failed)} failed (of {outcome.planned})")
        for spec, message in outcome.failed[:5]:
            print(f"failed: {spec.robot} scene {spec.scene} seed {spec.seed} {spec.controller}/{spec.execution}: "
                  f"{message}", file=sys.stderr)
    records = read_records(out / RESULTS_NAME)
    if not records:
        raise ParameterError(f"no results in {out / RESULTS_NAME}: nothing to report")
    scenes = read_records(out / SCENES_NAME)
    report, figure = write_report(records, scenes, out)
    files = [str(out / RESULTS_NAME), str(report), str(figure)]
    if args.publish is not None:
        try:
            args.publish.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ParameterError(f"--publish: cannot create the folder {str(args.publish.parent)!r}: {exc}") from exc
        files += map(str, write_report(records, scenes, args.publish.parent, report_name=args.publish.name,
                                       figure_name=args.publish.with_suffix(".png").name, kept=False))
    code = ExitCode.ERROR if not args.report_only and outcome.failed else ExitCode.OK
    if args.json:
        print_json(document | {"records": len(records), "files": files})
    else:
        print(f"written {', '.join(files)}")
    return code
