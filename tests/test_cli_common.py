"""Tests of :mod:`previewctl.cli.common`: the exit codes and their documented table, seed lists, the progress
bar (tqdm) on a terminal and in a log file."""

from __future__ import annotations

import argparse
import io
import re
from pathlib import Path

import pytest
from helpers import tiny_planar_toml

from previewctl.cli.common import EXIT_MEANINGS, ExitCode, ProgressBar, seed_count, seed_list
from previewctl.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def test_every_exit_code_has_a_meaning_and_the_docs_table_is_the_same() -> None:
    assert list(EXIT_MEANINGS) == list(ExitCode)
    text = (ROOT / "docs" / "guide" / "cli.md").read_text()
    table = text[text.index("| code | meaning |"):].split("\n\n")[0].splitlines()[2:]
    rows = [line.strip("|").split("|", 1) for line in table]
    assert {int(code): meaning.strip() for code, meaning in rows} == {
        int(code): meaning for code, meaning in EXIT_MEANINGS.items()}


@pytest.mark.parametrize(("text", "seeds"), [
    ("3", (3,)), ("0,1,2", (0, 1, 2)), ("0-4", (0, 1, 2, 3, 4)), ("0-2,7", (0, 1, 2, 7)), ("5, 1-2,1", (5, 1, 2)),
    ("4-4", (4,)),
])
def test_seed_list_takes_values_and_ranges(text: str, seeds: tuple[int, ...]) -> None:
    assert seed_list(text) == seeds


@pytest.mark.parametrize("text", ["", "-1", "2-1", "a", "1.5", "0-", "1,,2", "0-2-4"])
def test_seed_list_names_the_bad_text(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=rf"^must be seeds >= 0 as a comma list or ranges \(e\.g\. "
                       rf"0-4 or 0,1,2\), got {re.escape(repr(text))}$"):
        seed_list(text)


def test_the_old_seed_count_is_the_seeds_from_0() -> None:
    assert seed_count("3") == (0, 1, 2)
    with pytest.raises(argparse.ArgumentTypeError, match=r"^must be a count >= 1, got '0'$"):
        seed_count("0")

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
