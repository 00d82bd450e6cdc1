"""Command line: ``previewctl {robots,index,map,run,paper}``. Bad input -> one line on stderr, exit 2."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from previewctl.cli.common import EXIT_USAGE, ArgumentParser, add_evaluation_options
from previewctl.cli.index import cmd_index
from previewctl.cli.map import cmd_map
from previewctl.cli.paper import cmd_paper
from previewctl.cli.robots import cmd_robots
from previewctl.cli.run import cmd_run
from previewctl.errors import PreviewctlError


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = ArgumentParser(
        prog="previewctl",
        description="On-line trajectory tracking with obstacle avoidance for redundant arms "
        "(avoidance manipulability, 1-step GA, multi-preview control).",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)

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
    add_evaluation_options(index)
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
        description="Run the canonical planar scenes (scenarios/paper_fitted.toml: planar4 tracing five 0.75 m "
        "segments fitted to the paper's Table 3 along a target object, 50 s; scenarios/paper_planar.toml: the "
        "inverted staircase with a pillar trap) with none, gradient, single (t~ = 10 s), multi (t~ = 5 s, "
        "k = 0.3, 0.65, 0.05) and reach; print one comparison table per scene; write each run's log and "
        "figures to OUT/<scene>/<controller>/ and OUT/summary.json.",
    )
    paper.add_argument("--out", default="out/paper", help="output folder (default out/paper)")
    paper.add_argument("--controllers", help="comma-separated subset, e.g. single,multi (default: all five)")
    paper.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    paper.add_argument("--scenes", help="comma-separated subset, e.g. paper_fitted (default: both canonical scenes)")
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
    map_.add_argument("--scenario", help="scenario TOML file: robot, scene, index and (at --time) the target")
    map_.add_argument("--out", help="write the map to this PNG file")
    map_.add_argument("--surface", action="store_true", help="also write the 3-D surface to <out>_surface.png")
    map_.add_argument("--json", action="store_true", help="print JSON (genes in degrees, configuration, S, peaks)")
    map_.add_argument("--resolution", type=float, default=1.0, help="grid step [deg] (default 1)")
    map_.add_argument("--top-k", type=int, default=4, help="number of peaks to report (default 4)")
    map_.add_argument("--samples", type=int, help="Halton samples for arms with more than two genes")
    map_.add_argument("--seed", type=int, default=0, help="random shift of the samples (default 0)")
    add_evaluation_options(map_)
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
