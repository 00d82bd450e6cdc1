"""Command line: ``previewctl {robots,index,map,run,paper}``. Bad input -> one line on stderr, exit 2."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from previewctl.errors import PreviewctlError
from previewctl.robot import GEOMETRY_CHOICES

EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    """argparse with exit code 2 and a one-line message for usage errors."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"previewctl: error: {message} (see '{self.prog} --help')\n")
        raise SystemExit(EXIT_USAGE)


def parse_vector(text: str, name: str) -> np.ndarray:
    """Parse ``"1.2,1.8,-2.9"`` into a float array; a clear error otherwise."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError as exc:
        raise PreviewctlError(f"--{name} must be comma-separated numbers, got {text!r}") from exc
    if not values:
        raise PreviewctlError(f"--{name} must be comma-separated numbers, got {text!r}")
    return np.array(values)


def cmd_robots(args: argparse.Namespace) -> int:
    """List the robot names that load."""
    from previewctl.robot import example_robot_names, load_robot, shipped_robot_names

    names = list(shipped_robot_names())
    if args.all:
        names += list(example_robot_names())
    else:
        names += ["panda", "ur5", "ur3", "ur10", "kinova", "xarm7", "z1"]
    rows = []
    for name in names:
        try:
            robot = load_robot(name)
        except Exception as exc:  # listing: a robot that fails to load is reported, not fatal
            if args.verbose:
                sys.stderr.write(f"{name}: does not load ({exc})\n")
            continue
        rows.append((name, robot.nv, robot.task, robot.tip_frame, len(robot.control_points)))
    if args.json:
        keys = ("name", "dof", "task", "tip", "control_points")
        print(json.dumps([dict(zip(keys, r, strict=True)) for r in rows], indent=2))
    else:
        print(f"{'robot':<16}{'dof':>4}  {'task':<9}{'tip frame':<28}control points")
        for name, nv, task, tip, k in rows:
            print(f"{name:<16}{nv:>4}  {task:<9}{tip:<28}{k}")
    return 0


def cmd_index(args: argparse.Namespace) -> int:
    """Print the per-point avoidance table and AMSIP for one configuration."""
    from previewctl.amsip import Evaluator, Potential
    from previewctl.avoidance import IndexParams, avoidance
    from previewctl.robot import load_robot
    from previewctl.scene import Scene, load_scene

    robot = load_robot(args.robot, geometry=args.geometry)
    q = parse_vector(args.q, "q")
    if args.degrees:
        q = np.radians(q)
    scene = load_scene(args.scene) if args.scene else Scene()
    index = IndexParams(length_unit=args.length_unit)
    potential = Potential(influence_distance=args.influence)
    result = avoidance(robot, q, index)
    ev = Evaluator(robot, scene, index, potential)(q, args.time)
    report: dict[str, Any] = {
        "robot": robot.name,
        "q": [float(v) for v in q],
        "tip_position": [float(v) for v in ev.tip_position[0]],
        "control_points": [
            {
                "joint": name,
                "rank": int(result.ranks[i]),
                "structural_rank": int(result.structural_ranks[i]),
                "singular_values": [float(s) for s in result.singular_values[i]],
                "volume": float(result.volumes[i]),
            }
            for i, name in enumerate(robot.control_points)
        ],
        "links": [
            {"link": name, "min_distance": _finite_or_none(ev.link_distances[0, i])}
            for i, name in enumerate(robot.guarded_links)
        ],
        "amsi": float(ev.amsi[0]),
        "U": float(ev.U[0]),
        "S": float(ev.S[0]),
        "min_distance": _finite_or_none(ev.min_distance[0]),
        "collision": bool(ev.collision[0]),
        "length_unit_m": index.length_unit,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    hand = np.round(ev.tip_position[0], 4)
    print(f"robot {robot.name}  q = {np.array2string(q, precision=4)} [rad]  hand at {hand} [m]")
    print(f"{'control point':<22}{'rank':>5}{'p':>3}  {'singular values [m/rad]':<30}{'V_i [m^p]':>12}")
    for row in report["control_points"]:
        sv = ", ".join(f"{s:.4f}" for s in row["singular_values"])
        print(f"{row['joint']:<22}{row['rank']:>5}{row['structural_rank']:>3}  {sv:<30}{row['volume']:>12.5f}")
    print(f"{'guarded link':<22}{'min distance [m]':>18}")
    for row in report["links"]:
        d = row["min_distance"]
        print(f"{row['link']:<22}{'-' if d is None else f'{d:.4f}':>18}")
    unit = "cm" if np.isclose(index.length_unit, 0.01) else f"{index.length_unit} m"
    print(f"AMSI E = {report['amsi']:.2f} (unit {unit})   U = {report['U']:.2f}   S = {report['S']:.2f}"
          f"   {'COLLISION' if report['collision'] else 'collision-free'}")
    return 0


def _finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


class ProgressBar:
    """A one-line text progress bar on stderr, redrawn at most 10 times a second."""

    def __init__(self, label: str = "", width: int = 30) -> None:
        import time

        self.label, self.width, self._clock = label, width, time.perf_counter
        self.start, self.shown = self._clock(), -1.0

    def update(self, fraction: float, t: float) -> None:
        """Show ``fraction`` done at simulated time ``t`` [s]."""
        now = self._clock()
        if now - self.shown < 0.1 and fraction < 1.0:
            return
        self.shown = now
        filled = round(self.width * fraction)
        sys.stderr.write(f"\r{self.label}[{'#' * filled}{'.' * (self.width - filled)}] {100 * fraction:5.1f}%  "
                         f"t = {t:6.2f} s  elapsed {now - self.start:6.1f} s")
        sys.stderr.flush()

    def close(self) -> None:
        """End the line (if anything was drawn)."""
        if self.shown >= 0:
            sys.stderr.write("\n")


def cmd_run(args: argparse.Namespace) -> int:
    """Simulate a scenario file: progress bar on stderr, summary table, log and figures in --out."""
    from pathlib import Path

    from previewctl.scenario import load_scenario
    from previewctl.simulate import save_run, simulate
    from previewctl.viz import make_figures

    scenario = load_scenario(args.scenario)
    name = args.controller or scenario.controller.name
    out = Path(args.out) if args.out else Path("out") / f"{scenario.name}-{name}"
    bar = ProgressBar()
    try:
        result = simulate(scenario, name, progress=bar.update, stop_on_collision=not args.continue_after_collision,
                          seed=args.seed)
    finally:
        bar.close()
    summary = result.summary()
    npz_path, json_path = save_run(result, out)
    figures = make_figures(result, scenario, out, gif=False if args.no_gif else None)

    def metre(value: float | None) -> str:
        return "-" if value is None else f"{value * 1e3:.2f} mm"

    collision = (f"NO: collision at t = {summary['collision_time']:.3f} s ({summary['collision_link']})"
                 if summary["collided"] else "yes")
    rows = [
        ("scenario", f"{scenario.name} ({scenario.robot.name}, {summary['steps']} steps, {summary['duration']:.2f} s)"),
        ("controller", summary["controller"]),
        ("collision-free", collision),
        ("max hand error", metre(summary["max_hand_error"])),
        ("min clearance", metre(summary["min_clearance"])),
        ("mean / min S", f"{summary['mean_S']:.2f} / {summary['min_S']:.2f}"),
        ("max |qdot|", f"{summary['max_abs_qdot']:.4f} rad/s ({100 * summary['max_qdot_ratio']:.0f}% of limit)"),
        ("cycle time median / max",
         f"{summary['cycle_time_median'] * 1e3:.2f} / {summary['cycle_time_max'] * 1e3:.2f} ms"),
    ]
    for label, value in rows:
        print(f"{label:<26}{value}")
    print(f"{'written':<26}{npz_path}, {json_path}")
    for figure in figures:
        print(f"{'':<26}{figure}")
    return 0


def cmd_paper(args: argparse.Namespace) -> int:
    """Run the canonical planar scene with every controller: comparison table, figures, summary.json."""
    from pathlib import Path

    from previewctl.paper import PAPER_CONTROLLERS, run_paper
    from previewctl.scenario import Scenario
    from previewctl.simulate import RunResult
    from previewctl.viz import make_figures

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


def cmd_map(args: argparse.Namespace) -> int:
    """Global AMSIP map over the redundancy space of one hand target: best, peaks, optional PNG."""
    from pathlib import Path

    from previewctl.amsip import Evaluator, Potential
    from previewctl.avoidance import IndexParams
    from previewctl.robot import load_robot
    from previewctl.scene import Scene, load_scene
    from previewctl.search import Candidate, explore

    scenario_file = getattr(args, "scenario", None)
    if scenario_file:
        if args.scene or args.robot:
            raise PreviewctlError("give either --scenario or --robot/--scene, not both")
        from previewctl.scenario import load_scenario

        scenario = load_scenario(scenario_file)
        robot, scene = scenario.robot, scenario.scene
        index, potential = scenario.index, scenario.potential
        target = parse_vector(args.target, "target") if args.target else scenario.path.position(args.time)
    else:
        if not args.target:
            raise PreviewctlError("--target X,Y (or X,Y,Z) is required" + (" unless --scenario is given"
                                                                             if _has_scenarios() else ""))
        robot = load_robot(args.robot or "planar4", geometry=args.geometry)
        scene = load_scene(args.scene) if args.scene else Scene()
        index, potential = IndexParams(length_unit=args.length_unit), Potential(influence_distance=args.influence)
        target = parse_vector(args.target, "target")
    if args.surface and not args.out:
        raise PreviewctlError("--surface needs --out FILE.png (the surface goes to FILE_surface.png)")
    evaluator = Evaluator(robot, scene, index, potential)
    landscape = explore(robot, evaluator, target, args.time, resolution_deg=args.resolution, top_k=args.top_k,
                        samples=args.samples, rng=np.random.default_rng(args.seed))

    def row(candidate: Candidate) -> dict[str, Any]:
        return {
            "genes_deg": [round(float(v), 4) for v in np.degrees(np.mod(candidate.genes, 2 * np.pi))],
            "branch": candidate.branch,
            "q": [float(v) for v in candidate.q],
            "q_deg": [round(float(v), 4) for v in np.degrees(candidate.q)],
            "S": candidate.S,
        }

    written: list[str] = []
    if args.out:
        from previewctl.viz_map import plot_landscape, plot_surface

        out = Path(args.out)
        written.append(str(plot_landscape(landscape, robot, scene, out)))
        if args.surface:
            written.append(str(plot_surface(landscape, out.with_name(f"{out.stem}_surface{out.suffix or '.png'}"))))
    report: dict[str, Any] = {
        "robot": robot.name,
        "target": [float(v) for v in np.asarray(target, float)],
        "time": float(args.time),
        "method": landscape.method,
        "candidates": int(landscape.S.size),
        "reachable_fraction": float(landscape.reachable.mean()),
        "collision_free_fraction": float((landscape.S >= 0).mean()),
        "best": row(landscape.best),
        "peaks": [row(p) for p in landscape.peaks],
        "files": written,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"robot {robot.name}  hand target {report['target']} [m]  t = {args.time:g} s  ({landscape.method}: "
          f"{report['candidates']} candidates, {100 * report['reachable_fraction']:.1f}% reach the target, "
          f"{100 * report['collision_free_fraction']:.1f}% with S >= 0)")
    print(f"{'':<8}{'genes [deg]':<22}{'branch':>7}  {'q [deg]':<40}{'S':>12}")
    for label, item in [("best", report["best"]), *((f"peak {k}", p) for k, p in enumerate(report["peaks"], 1))]:
        genes = ", ".join(f"{v:.1f}" for v in item["genes_deg"][:4]) + (" ..." if len(item["genes_deg"]) > 4 else "")
        qs = ", ".join(f"{v:.1f}" for v in item["q_deg"])
        print(f"{label:<8}{genes:<22}{item['branch']:>7}  {qs:<40}{item['S']:>12.2f}")
    for path in written:
        print(f"written {path}")
    return 0


def _has_scenarios() -> bool:
    """Whether ``previewctl.scenario`` provides ``load_scenario`` (for ``map --scenario``)."""
    import importlib.util

    if importlib.util.find_spec("previewctl.scenario") is None:
        return False
    try:
        from previewctl import scenario
    except ImportError:
        return False
    return hasattr(scenario, "load_scenario")


def _add_evaluation_options(parser: argparse.ArgumentParser) -> None:
    """Scene, time, geometry and index options shared by ``index`` and ``map``."""
    parser.add_argument("--scene", help="scene TOML file with [[obstacles]] tables")
    parser.add_argument("--time", type=float, default=0.0, help="time at which moving obstacles are placed [s]")
    parser.add_argument("--geometry", choices=GEOMETRY_CHOICES, default="convex",
                        help="robot collision geometry: convex hulls (default), enclosing capsules, or exact meshes")
    parser.add_argument("--length-unit", type=float, default=0.01,
                        help="index length unit L_ref [m] (default 0.01: cm)")
    parser.add_argument("--influence", type=float, default=0.15, help="potential influence distance d_0 [m]")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = _Parser(
        prog="previewctl",
        description="On-line trajectory tracking with obstacle avoidance for redundant arms "
        "(avoidance manipulability, 1-step GA, multi-preview control).",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    robots = sub.add_parser("robots", help="list the robot names that load")
    robots.add_argument("--all", action="store_true", help="try every example-robot-data name (slow)")
    robots.add_argument("--json", action="store_true", help="print JSON")
    robots.add_argument("--verbose", action="store_true", help="say why a robot does not load")
    robots.set_defaults(func=cmd_robots)

    index = sub.add_parser(
        "index",
        help="avoidance manipulability and AMSIP of one configuration",
        description="Print the per-control-point avoidance table (rank, singular values, volume V_i), "
        "the per-link clearance and S = E + U for one configuration.",
    )
    index.add_argument("--robot", default="planar4",
                       help="URDF path, shipped or example-robot-data name (default planar4)")
    index.add_argument("--q", required=True, help="configuration, comma-separated [rad], e.g. 1.2,1.8,-2.9,1.5")
    index.add_argument("--degrees", action="store_true", help="read --q in degrees")
    _add_evaluation_options(index)
    index.add_argument("--json", action="store_true", help="print JSON")
    index.set_defaults(func=cmd_index)

    run = sub.add_parser(
        "run",
        help="simulate a scenario file and write its log and figures",
        description="Simulate a scenario (TOML): progress on stderr, then a summary table; the log "
        "(run.npz, summary.json) and the figures go to --out.",
    )
    run.add_argument("scenario", help="scenario TOML file (see scenarios/)")
    run.add_argument("--controller", choices=("none", "gradient", "single", "multi", "reach"),
                     help="override the scenario's controller")
    run.add_argument("--out", help="output folder (default out/<scenario name>-<controller>)")
    run.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    run.add_argument("--continue-after-collision", action="store_true",
                     help="log collisions and keep going instead of stopping at the first one")
    run.add_argument("--no-gif", action="store_true", help="do not write the animated GIF")
    run.set_defaults(func=cmd_run)

    paper = sub.add_parser(
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

    map_ = sub.add_parser(
        "map",
        help="global AMSIP map over the redundancy space of a hand target",
        description="Evaluate S over the redundancy space of one hand target (planar4: a grid over (q1, q2) "
        "x both elbow branches; other arms: Halton samples of the Newton map) and print the best "
        "configuration and the distinct peaks; --out writes the heat map (S < 0 black) and the arm.",
    )
    map_.add_argument("--robot", help="URDF path, shipped or example-robot-data name (default planar4)")
    map_.add_argument("--target", help="hand target, comma-separated [m]: X,Y (planar) or X,Y,Z")
    if _has_scenarios():
        map_.add_argument("--scenario", help="scenario TOML file: robot, scene, index and (at --time) the target")
    map_.add_argument("--out", help="write the map to this PNG file")
    map_.add_argument("--surface", action="store_true", help="also write the 3-D surface to <out>_surface.png")
    map_.add_argument("--json", action="store_true", help="print JSON (genes in degrees, configuration, S, peaks)")
    map_.add_argument("--resolution", type=float, default=1.0, help="grid step [deg] (default 1)")
    map_.add_argument("--top-k", type=int, default=4, help="number of peaks to report (default 4)")
    map_.add_argument("--samples", type=int, help="Halton samples for arms with more than two genes")
    map_.add_argument("--seed", type=int, default=0, help="random shift of the samples (default 0)")
    _add_evaluation_options(map_)
    map_.set_defaults(func=cmd_map)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``previewctl`` command."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except PreviewctlError as exc:
        sys.stderr.write(f"previewctl: error: {exc}\n")
        return EXIT_USAGE
    except KeyboardInterrupt:
        sys.stderr.write("previewctl: interrupted\n")
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
