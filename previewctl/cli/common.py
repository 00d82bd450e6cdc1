"""What the commands share: the argument parser that exits 2 on bad input, vector parsing, progress display."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TextIO, TypeAlias

import numpy as np
from tqdm import tqdm

from previewctl.errors import PreviewctlError
from previewctl.robot.model import GEOMETRY_CHOICES

EXIT_USAGE = 2
EXIT_FAILED_RUN = 3
"""Exit code of ``previewctl run`` when the run completed but failed: a collision, or a hand error over
the tolerance (2 stays bad input)."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse with exit code 2 and a one-line message for usage errors."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"previewctl: error: {message} (see '{self.prog} --help')\n")
        raise SystemExit(EXIT_USAGE)


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
