"""``previewctl run``: simulate a scenario file and write its log and figures."""

from __future__ import annotations

import argparse
from pathlib import Path

from previewctl.cli.common import (
    Commands,
    ExitCode,
    ProgressBar,
    add_json_option,
    print_json,
    seed_value,
)
from previewctl.control.params import CONTROLLER_NAMES
from previewctl.errors import PreviewctlError
from previewctl.files import atomic_folder, check_output_folder
from previewctl.sim.log import save_run
from previewctl.sim.loop import positive_rate, simulate
from previewctl.sim.scenario import load_scenario
from previewctl.sim.start import check_start, exact_evaluator
from previewctl.sim.verdict import self_collision_text, verdict_text
from previewctl.viz.figures import make_figures
from previewctl.viz.replay import REPLAY_NAME, write_replay


def add_parser(commands: Commands) -> None:
    """The ``run`` subcommand and its options."""
    run = commands.add_parser(
        "run",
        help="simulate a scenario file and write its log and figures",
        description="Simulate a scenario (TOML): progress on stderr, then a summary table; the log "
        "(run.npz, summary.json) and the figures go to --out. A run succeeds when it is free of collisions (with "
        "obstacles and with itself) and its largest hand error is at most the tolerance. Exit status: 0 success, "
        f"{int(ExitCode.VERDICT_FAILED)} the run failed (a collision, a self-collision or a hand error over the "
        f"tolerance), {int(ExitCode.USAGE)} bad input (a start configuration in collision included: refused before "
        "anything runs).",
    )
    run.add_argument("scenario", help="scenario TOML file (see scenarios/)")
    run.add_argument("--controller", choices=CONTROLLER_NAMES,
                     help="override the scenario's controller ('horizon': the reachability DP over the preview "
                     "window, replanned; 'oracle': non-causal, follows the DP's best motion over the whole run, see "
                     "reach-map; on a spatial arm both plan by a sampled search instead of the planar DP)")
    run.add_argument("--out", help="output folder (default out/<scenario name>-<controller>, and -realtime with "
                     "--realtime)")
    run.add_argument("--seed", type=seed_value, help="random seed (default: the scenario's)")
    run.add_argument("--tolerance", type=float,
                     help="largest hand error [m] of a successful run (default: the scenario's [verdict] "
                     "tolerance, 0.005)")
    run.add_argument("--q0", choices=["auto"],
                     help="'auto': start from the best collision-free configuration with the hand at the first "
                     "waypoint (global exploration) instead of the scenario's q0")
    run.add_argument("--continue-after-collision", action="store_true",
                     help="log collisions and keep going instead of stopping at the first one")
    run.add_argument("--no-gif", action="store_true", help="do not write the animated GIF")
    run.add_argument("--view", action="store_true",
                     help=f"also write the 3-D replay (OUT/{REPLAY_NAME}, opens from disk in a browser)")
    run.add_argument("--realtime", action="store_true",
                     help="run in real time: the simulated arm advances with the wall clock at --rate, each cycle "
                     "waiting for its deadline (an overrun is counted as a deadline miss, not caught up) by sleeping "
                     "through the first half of the period and rehearsing the last step through the second, to keep "
                     "the caches warm; the "
                     "searches and planner run in a worker process beside the loop ('none', 'qp' and 'gradient' "
                     "have nothing to plan and run inline), the loop on a core of its own (the lowest), the worker on "
                     "the others, the loop in Linux's real-time class (SCHED_FIFO) and the cores kept out of deep idle "
                     "states (/dev/cpu_dma_latency) when the OS grants them (root, or CAP_SYS_NICE for the first; a "
                     "warning says which it refused); not reproducible. Ctrl-C ends the worker too (exit 130)")
    run.add_argument("--rate", type=rate_value, metavar="HZ",
                     help=f"loop rate of --realtime [Hz] (default {DEFAULT_RATE:g}; the control period is 1/rate, "
                     "not the scenario's dt)")
    add_json_option(run, "the run's summary (summary.json) and the files written")
    run.set_defaults(func=cmd_run)


DEFAULT_RATE = 250.0
"""Loop rate of ``run --realtime`` [Hz] unless ``--rate`` says otherwise."""


def rate_value(text: str) -> float:
    """An argparse ``type``: a loop rate > 0 [Hz] (:func:`~previewctl.sim.loop.positive_rate`)."""
    try:
        return positive_rate(float(text))
    except (ValueError, PreviewctlError):
        raise argparse.ArgumentTypeError(f"must be a loop rate > 0 [Hz], got {text!r}") from None


def cmd_run(args: argparse.Namespace) -> int:
    """Simulate a scenario file: progress bar on stderr, summary table, log and figures in --out."""
    if args.rate is not None and not args.realtime:
        raise PreviewctlError(f"--rate {args.rate:g} sets the loop rate of --realtime: add --realtime, or drop --rate")
    scenario = load_scenario(args.scenario, auto_start=args.q0 == "auto")
    name = args.controller or scenario.controller.name
    exact = exact_evaluator(scenario)
    check_start(scenario, exact)  # before --out is checked (its parents created): a bad start writes nothing
    clock = "-realtime" if args.realtime else ""
    out = check_output_folder(args.out or Path("out") / f"{scenario.name}-{name}{clock}")
    bar = ProgressBar()
    try:
        result = simulate(scenario, name, progress=bar.update, stop_on_collision=not args.continue_after_collision,
                          seed=args.seed, exact_evaluator=exact, tolerance=args.tolerance,
                          rate=(args.rate or DEFAULT_RATE) if args.realtime else None)
    finally:
        bar.close()
    summary = result.summary()
    gif = False if args.no_gif else None
    with atomic_folder(out) as folder:  # the old folder stays whole until the new one is
        written = [*save_run(result, folder), *make_figures(result, scenario, folder, gif=gif)]
        if args.view:
            written.append(write_replay(result, folder / REPLAY_NAME, scenario=scenario))
    npz_path, json_path, *figures = [out / p.relative_to(folder) for p in written]
    code = ExitCode.OK if summary["success"] else ExitCode.VERDICT_FAILED
    if args.json:
        print_json({"summary": summary, "files": [str(p) for p in (npz_path, json_path, *figures)]})
        return code

    def metre(value: float | None) -> str:
        return "-" if value is None else f"{value * 1e3:.2f} mm"

    def self_distance(value: float | None, reach: float) -> str:  # beyond the self influence, only a bound is known
        return metre(value) if value is None or value < reach else f">= {reach * 1e3:.2f} mm (no self pair nearer)"

    collision = (f"NO: collision at t = {summary['collision_time']:.3f} s ({summary['collision_link']})"
                 if summary["collided"] else "yes")
    self_collision = f"NO: {self_collision_text(summary)}" if summary["self_collided"] else "yes"
    pairs = len(result.self_pairs)
    error = f"{metre(summary['max_hand_error'])} (tolerance {metre(summary['tolerance'])})"
    age = summary["plan_age_p95"]
    rows = [
        ("scenario", f"{scenario.name} ({scenario.robot.name}, {summary['steps']} steps, {summary['duration']:.2f} s)"),
        ("controller", f"{summary['controller']}, executed by "
                       f"{'the QP' if summary['execution'] == 'qp' else 'the pseudo-inverse eq. 19'}"
                       + (f" (damper slack up to {summary['max_slack']:.3f} m/s)" if summary["max_slack"] > 0 else "")),
        ("success", verdict_text(summary)),
        ("collision-free", collision),
        ("self-collision-free", f"{self_collision} ({pairs} link pairs checked)" if pairs else "- (no self pairs)"),
        ("max hand error", error),
        ("min clearance", metre(summary["min_clearance"])),
        ("min self distance", self_distance(summary["min_self_distance"], scenario.potential.self_influence_distance)),
        ("mean / min S", f"{summary['mean_S']:.2f} / {summary['min_S']:.2f}"),
        ("max |qdot|", f"{summary['max_abs_qdot']:.4f} rad/s ({100 * summary['max_qdot_ratio']:.0f}% of limit)"),
        ("cycle time median / max",
         f"{summary['cycle_time_median'] * 1e3:.2f} / {summary['cycle_time_max'] * 1e3:.2f} ms"),
        ("whole cycle p50/p99/max", f"{summary['cycle_p50'] * 1e3:.2f} / {summary['cycle_p99'] * 1e3:.2f} / "
                                    f"{summary['cycle_max'] * 1e3:.2f} ms"),
        ("deadline misses", f"{summary['deadline_misses']} of {summary['steps']} cycles longer than "
                            f"{result.dt * 1e3:g} ms" + (" (real time)" if args.realtime else " (simulated time)")),
        ("plan age p95 / fallback", f"{'-' if age is None else f'{age * 1e3:.0f} ms'} / "
                                    f"{100 * summary['fallback_fraction']:.1f}% of cycles"),
    ]
    if summary["real_time_class"] is not None:
        fifo = "SCHED_FIFO" if summary["real_time_class"] else "ordinary class (SCHED_FIFO refused)"
        awake = "cores kept awake" if summary["cores_awake"] else "cores may halt (refused)"
        rows.append(("real-time loop", f"{fifo}, {awake}"))
    sensing = scenario.sensing
    if sensing is not None:
        rows.append(("observations", f"{summary['observations']} delivered, {summary['observations_dropped']} dropped "
                                     f"({sensing.rate:g} Hz, noise {sensing.noise * 1e3:g} mm, latency "
                                     f"{sensing.latency * 1e3:g} ms, dropout {sensing.dropout:g})"))
    for label, value in rows:
        print(f"{label:<26}{value}")
    print(f"{'written':<26}{npz_path}, {json_path}")
    for figure in figures:
        print(f"{'':<26}{figure}")
    return code
