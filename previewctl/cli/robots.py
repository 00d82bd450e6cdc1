"""``previewctl robots``: list the robots that load as arms, and why the others do not."""

from __future__ import annotations

import argparse
import sys

from tqdm import tqdm

from previewctl.cli.common import Commands, add_json_option, is_terminal, print_json
from previewctl.errors import PreviewctlError
from previewctl.index.load import example_robot_names, load_robot, shipped_robot_names

FEATURED = ("panda", "ur5", "ur3", "ur10", "kinova", "xarm7", "z1")
"""The example-robot-data arms listed without ``--all``."""


def add_parser(commands: Commands) -> None:
    """The ``robots`` subcommand and its options."""
    robots = commands.add_parser("robots", help="list the robots that load as arms")
    robots.add_argument("--all", action="store_true", help="try every example-robot-data name (about 40 s)")
    add_json_option(robots, "the arms and the robots that are not arms, with the reason,")
    robots.add_argument("--verbose", action="store_true", help="also list the robots that are not arms, and why")
    robots.set_defaults(func=cmd_robots)


def cmd_robots(args: argparse.Namespace) -> int:
    """List the robots that load as arms (with ``--verbose``, the others with the reason)."""
    known = example_robot_names()  # empty without the [robots] extra
    names = [*shipped_robot_names(), *(known if args.all else [n for n in FEATURED if n in known])]
    rows, refused = [], []
    for name in tqdm(names, desc="loading", unit="robot", leave=False, disable=not is_terminal(sys.stderr)):
        try:
            robot = load_robot(name)
        except PreviewctlError as exc:
            refused.append((name, str(exc)))
            continue
        checked = robot.self_pairs
        rows.append((name, robot.nv, robot.task, robot.tip_frame, len(robot.control_points), len(checked.links),
                     "SRDF" if checked.source.startswith("SRDF") else "sampled"))
    if args.json:
        keys = ("name", "dof", "task", "tip", "control_points", "self_pairs", "self_pairs_from")
        report = {"arms": [dict(zip(keys, r, strict=True)) for r in rows],
                  "not_arms": [{"name": n, "reason": why} for n, why in refused]}
        print_json(report)
        return 0
    print(f"{'robot':<28}{'dof':>4}  {'task':<9}{'tip frame':<28}{'control points':<16}self pairs (link pairs checked)")
    for name, nv, task, tip, k, pairs, source in rows:
        print(f"{name:<28}{nv:>4}  {task:<9}{tip:<28}{k:<16}{pairs} ({source})")
    if refused and args.verbose:
        print(f"\nnot arms ({len(refused)}):")
        for name, why in refused:
            print(f"{name:<28}{why}")
    elif refused:
        print(f"\n{len(refused)} more do not load as arms ({', '.join(n for n, _ in refused)}); --verbose says why")
    if not known:
        print("\nexample-robot-data's arms (panda, ur5, ...) need: pip install 'previewctl[robots]'")
    return 0
