"""Tests of :mod:`previewctl.cli.common`: the progress bar (tqdm) on a terminal and in a log file."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
from helpers import tiny_planar_toml

from previewctl.cli.common import ProgressBar
from previewctl.cli.main import main

LINE = re.compile(r"^multi +\[[#.]{30}\] +(\d+\.\d)%, t = +(\d+\.\d\d) s  elapsed \d\d:\d\d$")
"""One state of the bar: label, bar, percent, simulated time [s], elapsed (mm:ss)."""


class Terminal(io.StringIO):
    """A text stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def run_bar(stream: io.StringIO, steps: int = 400) -> str:
    bar = ProgressBar("multi    ", file=stream)
    for k in range(1, steps + 1):
        bar.update(k / steps, 50.0 * k / steps)
    bar.close()
    return stream.getvalue()


def test_progress_in_a_log_file_is_one_line_with_the_final_state() -> None:
    text = run_bar(io.StringIO())
    assert "\r" not in text and text.endswith("\n")
    (line,) = text.splitlines()
    match = LINE.match(line)
    assert match is not None, line
    assert match.groups() == ("100.0", "50.00")


def test_progress_on_a_terminal_is_redrawn_in_place_and_rate_limited() -> None:
    text = run_bar(Terminal())
    frames = text.rstrip("\n").split("\r")[1:]
    assert text.endswith("\n") and text.count("\n") == 1
    assert 2 <= len(frames) < 400  # the first and the last frame, and not one per update
    assert all(LINE.match(frame) for frame in frames), frames
    assert LINE.match(frames[-1]).groups() == ("100.0", "50.00")  # type: ignore[union-attr]


def test_progress_never_updated_writes_nothing_to_a_log_file() -> None:
    stream = io.StringIO()
    ProgressBar("none", file=stream).close()
    assert stream.getvalue() == ""


def test_run_command_writes_one_progress_line_when_stderr_is_not_a_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(tiny_planar_toml(
        "tiny",
        '[timing]\nduration = 0.2\n[output]\nfigures = ["S"]\ngif = false\n',
    ))
    assert main(["run", str(scenario), "--out", str(tmp_path / "run")]) == 0
    captured = capsys.readouterr()
    (line,) = captured.err.splitlines()
    assert "\r" not in captured.err and "100.0%, t =   0.20 s  elapsed" in line
    assert "\r" not in captured.out and "collision-free" in captured.out
