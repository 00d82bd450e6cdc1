"""``previewctl robots``: list the robot names that load."""

from __future__ import annotations

import argparse
import json
import sys

from previewctl.cli.common import Commands
from previewctl.robot.load import example_robot_names, load_robot, shipped_robot_names


def add_parser(commands: Commands) -> None:
    """The ``robots`` subcommand and its options."""
    robots = commands.add_parser("robots", help="list the robot names that load")
    robots.add_argument("--all", action="store_true", help="try every example-robot-data name (slow)")
    robots.add_argument("--json", action="store_true", help="print JSON")
    robots.add_argument("--verbose", action="store_true", help="say why a robot does not load")
    robots.set_defaults(func=cmd_robots)


def cmd_robots(args: argparse.Namespace) -> int:
    """List the robot names that load."""
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
