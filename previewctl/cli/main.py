"""Command line: ``previewctl {robots,index,map,run,paper,reach-map,view,bench,ros}``.

Bad input -> one line on stderr, exit 2; every exit code is in :class:`~previewctl.cli.common.ExitCode`."""

from __future__ import annotations

import argparse
import contextlib
import importlib.metadata
import logging
import sys
import warnings
from collections.abc import Iterator, Sequence
from typing import Any, NoReturn, TextIO

from previewctl.cli import bench, index, paper, reach_map, robots, ros, run, view
from previewctl.cli import map as map_command
from previewctl.cli.common import ArgumentParser, ExitCode, exit_codes_text
from previewctl.errors import IgnoredSettingWarning, PreviewctlError


class VersionAction(argparse.Action):
    """``--version``: print ``previewctl <version>`` (the installed distribution's) and exit 0.

    The version is looked up only when asked for. Without an installed distribution (the source tree on
    ``PYTHONPATH``) there is none to report: one line on stderr says so, exit 1 (``ExitCode.ERROR``)."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> NoReturn:
        try:
            version = importlib.metadata.version("previewctl")
        except importlib.metadata.PackageNotFoundError:
            parser.exit(ExitCode.ERROR, "previewctl: version unknown: previewctl is not installed as a distribution "
                        "(install it with 'pip install -e .' from the source tree)\n")
        sys.stdout.write(f"previewctl {version}\n")
        parser.exit(ExitCode.OK)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand (each command module adds its own)."""
    parser = ArgumentParser(
        prog="previewctl",
        description="On-line trajectory tracking with obstacle avoidance for redundant arms\n"
        "(avoidance manipulability, 1-step GA, multi-preview control).",
        epilog=exit_codes_text(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action=VersionAction, help="print the installed version and exit")
    parser.add_argument("-v", "--verbose", action="store_true", dest="log_info",  # robots has its own --verbose
                        help="log the library's diagnostics (robot, self pairs, controller, runs) to stderr")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    for command in (robots, index, run, paper, map_command, reach_map, view, bench, ros):
        command.add_parser(commands)
    return parser


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: TextIO | None = None, line: str | None = None) -> None:
    """previewctl's own warnings as one line (``previewctl: warning: ...``); others as Python shows them."""
    if issubclass(category, IgnoredSettingWarning):
        (file or sys.stderr).write(f"previewctl: warning: {message}\n")
    else:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


@contextlib.contextmanager
def _diagnostics(enabled: bool) -> Iterator[None]:
    """With ``enabled`` (``-v``), the library's log records of level INFO and above on stderr, one line each."""
    if not enabled:
        yield
        return
    log = logging.getLogger("previewctl")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("previewctl: %(name)s: %(message)s"))
    level = log.level
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    try:
        yield
    finally:
        log.removeHandler(handler)
        log.setLevel(level)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``previewctl`` command."""
    args = build_parser().parse_args(argv)
    try:
        with warnings.catch_warnings(), _diagnostics(args.log_info):
            warnings.showwarning = _show_warning
            return int(args.func(args))
    except PreviewctlError as exc:
        sys.stderr.write(f"previewctl: error: {exc}\n")
        return ExitCode.USAGE
    except KeyboardInterrupt:
        sys.stderr.write("previewctl: interrupted\n")
        return ExitCode.INTERRUPTED


if __name__ == "__main__":
    raise SystemExit(main())
