"""What the commands share: the exit codes, the argument parser that exits 2 on bad input, deprecated flags, JSON
output, vector and seed parsing, progress display."""

from __future__ import annotations

import argparse
import enum
import json
import sys
import textwrap
import time
from collections.abc import Sequence
from typing import Any, TextIO, TypeAlias

import numpy as np
from tqdm import tqdm

from previewctl.errors import PreviewctlError
from previewctl.robot.model import GEOMETRY_CHOICES


class ExitCode(enum.IntEnum):
    """The exit status of every command; :data:`EXIT_MEANINGS` says what each means (``previewctl --help`` and
    docs/guide/cli.md show that table)."""

    OK = 0
    ERROR = 1
    USAGE = 2
    VERDICT_FAILED = 3
    INTERRUPTED = 130


EXIT_MEANINGS: dict[ExitCode, str] = {
    ExitCode.OK: "success",
    ExitCode.ERROR: "some work raised: a bench run (the report of the others is still written), or --version "
    "without an installed distribution",
    ExitCode.USAGE: "bad input (one line on stderr)",
    ExitCode.VERDICT_FAILED: "a run completed but failed its verdict: a collision, a self-collision or a hand "
    "error over the tolerance (run)",
    ExitCode.INTERRUPTED: "interrupted (Ctrl-C)",
}
"""What each exit code means; paper and bench exit 0 whatever their runs' verdicts: their tables are the result."""


def exit_codes_text() -> str:
    """The exit-code table as help text: one line per code."""
    rows = (textwrap.fill(meaning, 100, initial_indent=f"  {int(code):>3}  ", subsequent_indent=" " * 7)
            for code, meaning in EXIT_MEANINGS.items())
    return "exit codes:\n" + "\n".join(rows)


class ArgumentParser(argparse.ArgumentParser):
    """argparse with exit code 2 and a one-line message for usage errors."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"previewctl: error: {message} (see '{self.prog} --help')\n")
        raise SystemExit(ExitCode.USAGE)


class DeprecatedFlag(argparse.Action):
    """An old spelling of an option, kept for one release: it stores its value where the new spelling does and
    writes one line, ``previewctl: warning: --jobs is deprecated; use --workers``, to stderr.

    Use: ``parser.add_argument("--jobs", dest="workers", type=int, action=DeprecatedFlag, use="--workers")``;
    give a ``type`` that turns the old meaning into the new value where the meaning changed."""

    def __init__(self, option_strings: Sequence[str], dest: str, *, use: str, **kwargs: Any) -> None:
        kwargs.setdefault("help", f"deprecated: use {use}")
        kwargs.setdefault("default", argparse.SUPPRESS)  # the new spelling's default stands
        super().__init__(option_strings, dest, **kwargs)
        self.use = use

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        sys.stderr.write(f"previewctl: warning: {option_string} is deprecated; use {self.use}\n")
        setattr(namespace, self.dest, values)


def print_json(document: Any) -> None:
    """Print ``document`` as the whole of stdout (``--json``): indented JSON and a newline."""
    sys.stdout.write(json.dumps(document, indent=2) + "\n")


def add_json_option(parser: argparse.ArgumentParser, what: str) -> None:
    """The ``--json`` flag of a command that prints results: ``what`` the document holds."""
    parser.add_argument("--json", action="store_true",
                        help=f"print {what} as JSON, and nothing else, on stdout (progress stays on stderr)")


Commands: TypeAlias = "argparse._SubParsersAction[ArgumentParser]"
"""Where each command module adds its subparser (``add_parser(commands)``)."""


def parse_vector(text: str, name: str) -> np.ndarray:
    """Parse ``"1.2,1.8,-2.9"`` into a float array; a clear error otherwise."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v != ""]
    except ValueError as exc:
        raise PreviewctlError(f"--{name} must be comma-separated numbers, got {text!r}") from exc
    if not values:
        raise PreviewctlError(f"--{name} must be comma-separated numbers, got {text!r}")
    return np.array(values)


def seed_value(text: str) -> int:
    """An argparse ``type``: a random seed, an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return value


def seed_list(text: str) -> tuple[int, ...]:
    """An argparse ``type``: seeds as a comma list of integers >= 0 and ranges, ``"3"``, ``"0,1,2"``, ``"0-4"``
    (both ends included), ``"0-2,7"``; each seed once, in the order given."""
    seeds: dict[int, None] = {}  # ordered, each seed once
    for part in text.replace(" ", "").split(","):
        low, dash, high = part.partition("-")
        try:
            first, last = seed_value(low), seed_value(high if dash else low)
        except argparse.ArgumentTypeError:
            first, last = 0, -1
        if first > last:
            raise argparse.ArgumentTypeError(f"must be seeds >= 0 as a comma list or ranges (e.g. 0-4 or 0,1,2), "
                                             f"got {text!r}")
        seeds |= dict.fromkeys(range(first, last + 1))
    return tuple(seeds)


def seed_count(text: str) -> tuple[int, ...]:
    """An argparse ``type`` for the deprecated ``--seeds N`` (a count): the seeds ``0 .. N-1``."""
    try:
        count = int(text)
    except ValueError:
        count = 0
    if count < 1:
        raise argparse.ArgumentTypeError(f"must be a count >= 1, got {text!r}")
    return tuple(range(count))


def finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


class ProgressBar:
    """Progress of one simulated run on stderr, drawn by tqdm: label, percent done, simulated time, elapsed.

    On a terminal tqdm redraws the bar in place, at most 10 times a second. Anywhere else (a log
    file, a pipe, CI) nothing is redrawn: :meth:`close` writes the last state as one line, so a log
    holds one readable line per run instead of hundreds of ``\\r`` frames.

    Args:
        label: printed before the bar (e.g. the controller name).
        file: where to write; default ``sys.stderr`` (looked up when the bar is made).
    """

    BAR_FORMAT = "{desc}[{bar:30}] {percentage:5.1f}%{postfix}  elapsed {elapsed}"
    """tqdm's ``bar_format``; the postfix is the simulated time, e.g. ``50.0%, t =  25.00 s``."""

    def __init__(self, label: str = "", file: TextIO | None = None) -> None:
        self.label = label
        self._file = sys.stderr if file is None else file
        self._fraction, self._t, self._updated = 0.0, 0.0, False
        self._start = time.perf_counter()
        self._bar = tqdm(total=1.0, desc=label, bar_format=self.BAR_FORMAT, ascii=".#", file=self._file,
                         mininterval=0.1, leave=True, postfix=self._time(0.0), disable=not is_terminal(self._file))

    @staticmethod
    def _time(t: float) -> str:
        return f"t = {t:6.2f} s"

    def update(self, fraction: float, t: float) -> None:
        """Show ``fraction`` of the run done (in [0, 1]) at simulated time ``t`` [s]."""
        self._fraction, self._t, self._updated = fraction, t, True
        self._bar.set_postfix_str(self._time(t), refresh=False)
        self._bar.update(fraction - self._bar.n)

    def close(self) -> None:
        """End the bar: on a terminal, its final frame and a newline; elsewhere, one line (if updated)."""
        if not self._bar.disable:
            self._bar.close()
        elif self._updated:
            line = tqdm.format_meter(self._fraction, 1.0, time.perf_counter() - self._start, prefix=self.label,
                                     ascii=".#", bar_format=self.BAR_FORMAT, postfix=self._time(self._t))
            self._file.write(line + "\n")
            self._file.flush()


def is_terminal(stream: TextIO) -> bool:
    """Whether ``stream`` is a terminal (progress bars are drawn only there)."""
    isatty = getattr(stream, "isatty", None)
    return bool(isatty is not None and isatty())


def add_evaluation_options(parser: argparse.ArgumentParser) -> None:
    """Scene, time, geometry and index options shared by ``index`` and ``map``."""
    parser.add_argument("--scene", help="scene TOML file with [[obstacles]] tables")
    parser.add_argument("--time", type=float, default=0.0, help="time at which moving obstacles are placed [s]")
    parser.add_argument("--geometry", choices=GEOMETRY_CHOICES, default="convex",
                        help="robot collision geometry: convex hulls (default), enclosing capsules, or exact meshes")
    parser.add_argument("--length-unit", type=float, default=0.01,
                        help="index length unit L_ref [m] (default 0.01: cm)")
    parser.add_argument("--influence", type=float, default=0.15, help="potential influence distance d_0 [m]")
