"""What the commands share: the argument parser that exits 2 on bad input, vector parsing, progress display."""

from __future__ import annotations

import argparse
import sys
from typing import TypeAlias

import numpy as np

from previewctl.errors import PreviewctlError
from previewctl.robot.model import GEOMETRY_CHOICES

EXIT_USAGE = 2


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


def finite_or_none(value: float) -> float | None:
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


def add_evaluation_options(parser: argparse.ArgumentParser) -> None:
    """Scene, time, geometry and index options shared by ``index`` and ``map``."""
    parser.add_argument("--scene", help="scene TOML file with [[obstacles]] tables")
    parser.add_argument("--time", type=float, default=0.0, help="time at which moving obstacles are placed [s]")
    parser.add_argument("--geometry", choices=GEOMETRY_CHOICES, default="convex",
                        help="robot collision geometry: convex hulls (default), enclosing capsules, or exact meshes")
    parser.add_argument("--length-unit", type=float, default=0.01,
                        help="index length unit L_ref [m] (default 0.01: cm)")
    parser.add_argument("--influence", type=float, default=0.15, help="potential influence distance d_0 [m]")
