"""Command line: ``previewctl {robots,index,map,run,paper,reach-map,view,bench}``.

Bad input -> one line on stderr, exit 2."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from previewctl.cli import bench, index, paper, reach_map, robots, run, view
from previewctl.cli import map as map_command
from previewctl.cli.common import EXIT_USAGE, ArgumentParser
from previewctl.errors import PreviewctlError


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand (each command module adds its own)."""
    parser = ArgumentParser(
        prog="previewctl",
        description="On-line trajectory tracking with obstacle avoidance for redundant arms "
        "(avoidance manipulability, 1-step GA, multi-preview control).",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    for command in (robots, index, run, paper, map_command, reach_map, view, bench):
        command.add_parser(commands)
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
