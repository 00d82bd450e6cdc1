"""Command line: ``previewctl {robots,index,map,run,paper}``. Bad input -> one line on stderr, exit 2."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

import numpy as np

from previewctl.errors import PreviewctlError

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
        except Exception as exc:  # noqa: BLE001 -- listing: a robot that fails is reported, not fatal
            if args.verbose:
                sys.stderr.write(f"{name}: does not load ({exc})\n")
            continue
        rows.append((name, robot.nv, robot.task, robot.tip_frame, len(robot.control_points)))
    if args.json:
        print(json.dumps([dict(zip(("name", "dof", "task", "tip", "control_points"), r)) for r in rows], indent=2))
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
    report = {
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
    print(f"robot {robot.name}  q = {np.array2string(q, precision=4)} [rad]  hand at {np.round(ev.tip_position[0], 4)} [m]")
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
    index.add_argument("--robot", default="planar4", help="URDF path, shipped or example-robot-data name (default planar4)")
    index.add_argument("--q", required=True, help="configuration, comma-separated [rad], e.g. 1.2,1.8,-2.9,1.5")
    index.add_argument("--degrees", action="store_true", help="read --q in degrees")
    index.add_argument("--scene", help="scene TOML file with [[obstacles]] tables")
    index.add_argument("--time", type=float, default=0.0, help="time at which moving obstacles are placed [s]")
    index.add_argument("--geometry", choices=("convex", "mesh"), default="convex", help="robot collision geometry")
    index.add_argument("--length-unit", type=float, default=0.01, help="index length unit L_ref [m] (default 0.01: cm)")
    index.add_argument("--influence", type=float, default=0.15, help="potential influence distance d_0 [m]")
    index.add_argument("--json", action="store_true", help="print JSON")
    index.set_defaults(func=cmd_index)
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
