"""Tests of :mod:`previewctl.cli.main`: every command's ``--help``, ``--json`` and old flag spellings, and
``--version``."""

from __future__ import annotations

import argparse
import dataclasses
import importlib.metadata
import json
import logging
import re
from pathlib import Path
from typing import Any

import pytest
from helpers import tiny_planar_toml

import previewctl.sim.paper
from previewctl.cli import robots
from previewctl.cli.common import ExitCode
from previewctl.cli.main import build_parser, main


def command_names() -> list[str]:
    """Every subcommand the parser registers, read from the parser itself."""
    (commands,) = (a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return list(commands.choices)


COMMANDS = command_names()


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int | str | None, str, str]:
    """``main(argv)`` in this process: its exit code (from ``SystemExit`` or the return), stdout and stderr."""
    try:
        code: int | str | None = main(argv)
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_the_parser_registers_the_documented_commands() -> None:
    # the enumeration below must not come back empty (then the help test would check nothing)
    assert {"robots", "index", "run", "paper", "map", "reach-map", "view", "bench"} <= set(COMMANDS)


@pytest.mark.parametrize("command", [[], *([name] for name in COMMANDS)], ids=lambda c: " ".join(c) or "previewctl")
def test_help_of_every_command_exits_0_and_names_the_command(command: list[str],
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_main([*command, "--help"], capsys)
    assert code == 0, err
    assert err == ""
    prog = " ".join(["previewctl", *command])
    assert out.startswith(f"usage: {prog} ")
    assert "options:" in out and len(out.splitlines()) > 3
    if not command:  # the top-level help lists every command and every exit code
        assert all(name in out for name in COMMANDS)
        codes = out[out.index("exit codes:"):]
        assert [int(line.split()[0]) for line in codes.splitlines()[1:] if line[:5].strip()] == list(ExitCode)


def test_version_prints_the_installed_distribution_version(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_main(["--version"], capsys)
    assert code == 0 and err == ""
    assert out == f"previewctl {importlib.metadata.version('previewctl')}\n"
    assert re.fullmatch(r"previewctl \d+\.\d+\S*\n", out)


def test_version_without_an_installed_distribution_says_so(capsys: pytest.CaptureFixture[str],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    def not_installed(name: str) -> str:
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", not_installed)
    code, out, err = run_main(["--version"], capsys)
    assert code == ExitCode.ERROR != 0
    assert out == ""
    assert re.fullmatch(r"previewctl: version unknown: previewctl is not installed as a distribution \(.*pip "
                        r"install.*\)\n", err)


def test_version_is_an_option_of_previewctl_only(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_main(["robots", "--version"], capsys)
    assert code == 2 and out == ""
    assert "unrecognized arguments: --version" in err


def test_an_ignored_setting_is_one_warning_line_and_recorded(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """A scenario shared between controllers may set what the chosen one does not read: the run goes on, stderr
    says so in one line (no Python warning trace), and the run's summary records it."""
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(tiny_planar_toml(
        "tiny", '[controller]\nname = "none"\npreview_time = 2.0\n[timing]\nduration = 0.05\n'
        '[output]\nfigures = []\ngif = false\n'))
    assert main(["run", str(scenario), "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "previewctl: warning: controller 'none' does not use preview_time = 2.0: ignored\n" in err
    assert "IgnoredSettingWarning" not in err and "make_controller" not in err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["composition"] == "none (Tracking), execution pseudoinverse, ignored: preview_time = 2.0"


def test_verbose_logs_the_library_diagnostics_to_stderr_and_only_while_it_runs(
    capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["index", "--robot", "planar4", "--q", "0.3,0.3,0.3,0.3"]
    code, out, err = run_main(["-v", *argv], capsys)
    assert code == 0 and "S =" in out
    assert "previewctl: previewctl.index.load: robot 'planar4': 4 joints, task planar, tip 'tip'" in err
    log = logging.getLogger("previewctl")
    assert [type(h) for h in log.handlers] == [logging.NullHandler] and log.level == logging.NOTSET
    code, out, err = run_main(argv, capsys)
    assert code == 0 and err == ""  # the library itself prints nothing


# ---------------------------------------------------------------------------------------- old spellings

DEPRECATED = [  # (old argv, the same with the new spelling)
    (["paper", "--jobs", "3"], ["paper", "--workers", "3"]),
    (["paper", "--controllers", "none,multi"], ["paper", "--controller", "none,multi"]),
    (["paper", "--executions", "qp"], ["paper", "--execution", "qp"]),
    (["paper", "--scenes", "paper_fitted"], ["paper", "--scenario", "paper_fitted"]),
    (["bench", "--controllers", "none,multi"], ["bench", "--controller", "none,multi"]),
    (["bench", "--executions", "qp"], ["bench", "--execution", "qp"]),
    (["bench", "--seeds", "3"], ["bench", "--seed", "0-2"]),  # a count then, the seeds now
]


@pytest.mark.parametrize(("old", "new"), DEPRECATED, ids=lambda argv: " ".join(argv))
def test_an_old_spelling_still_works_and_warns_in_one_line(old: list[str], new: list[str],
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert build_parser().parse_args(new) == build_parser().parse_args(old)
    err = capsys.readouterr().err
    assert err == f"previewctl: warning: {old[1]} is deprecated; use {new[1]}" + ("\n" if new[1] != "--seed" else
                                                                                  " (seeds, not a count: --seeds 3 "
                                                                                  "is --seed 0-2)\n")


def test_an_old_spelling_does_not_override_the_new_ones_default() -> None:
    assert build_parser().parse_args(["paper"]).workers >= 1
    assert build_parser().parse_args(["bench"]).seed == (0,)


# ----------------------------------------------------------------------------------------------- --json

def short_paper_scenes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The canonical scenes cut to their first 0.5 s, so that ``paper`` runs in a second."""
    canonical = previewctl.sim.paper.canonical_scenario

    def short(name: str = previewctl.sim.paper.CANONICAL_SCENES[0]) -> previewctl.sim.paper.Scenario:
        scenario = canonical(name)
        return dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=0.5))

    monkeypatch.setattr(previewctl.sim.paper, "canonical_scenario", short)


def json_of(argv: list[str], capsys: pytest.CaptureFixture[str], code: int = 0) -> dict[str, Any]:
    """The document ``previewctl ARGV --json`` prints: the whole of stdout, parsed."""
    got, out, err = run_main([*argv, "--json"], capsys)
    assert got == code, err
    document = json.loads(out)
    assert isinstance(document, dict)
    return document


def tiny_scenario(folder: Path, duration: float = 0.2) -> str:
    path = folder / "tiny.toml"
    path.write_text(tiny_planar_toml("tiny", f"[timing]\nduration = {duration}\n[output]\nfigures = []\n"
                                             "gif = false\n"))
    return str(path)


NO_RESULTS = {"ros"}
"""Commands that print no results: ``ros`` runs a node until it is stopped."""


def test_every_command_that_prints_results_has_json() -> None:
    (commands,) = (a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert [name for name, parser in commands.choices.items()
            if "--json" not in parser._option_string_actions and name not in NO_RESULTS] == []


def test_robots_json(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(robots, "FEATURED", ())  # the shipped robots only: quick
    document = json_of(["robots"], capsys)
    assert set(document) == {"arms", "not_arms"}
    assert document["arms"][0] == {"name": "planar4", "dof": 4, "task": "planar", "tip": "tip", "control_points": 3,
                                   "self_pairs": 0, "self_pairs_from": "SRDF"}


def test_index_json(capsys: pytest.CaptureFixture[str]) -> None:
    document = json_of(["index", "--q", "1.2,1.8,-2.9,1.5"], capsys)
    assert {"robot", "q", "control_points", "links", "amsi", "U", "S", "collision"} <= set(document)
    assert [p["rank"] for p in document["control_points"]] == [1, 2, 1]  # the paper's ranks of M_1, M_2, M_3


def test_map_json(capsys: pytest.CaptureFixture[str]) -> None:
    document = json_of(["map", "--target", "1.5,1.0", "--resolution", "10"], capsys)
    assert {"robot", "target", "method", "best", "peaks", "files"} <= set(document)
    assert document["target"] == [1.5, 1.0] and document["best"]["S"] > 0


def test_reach_map_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    document = json_of(["reach-map", tiny_scenario(tmp_path, 1.0), "--resolution", "10", "--steps", "5"], capsys)
    assert {"scenario", "robot", "duration", "exists", "verdict", "grid"} <= set(document)
    assert document["exists"] is True


def test_run_json_and_its_exit_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    document = json_of(["run", tiny_scenario(tmp_path), "--out", str(tmp_path / "run")], capsys)
    assert set(document) == {"summary", "files"}
    assert document["summary"] == json.loads((tmp_path / "run" / "summary.json").read_text())
    assert document["files"] == [str(tmp_path / "run" / name) for name in ("run.npz", "summary.json")]
    failed = json_of(["run", tiny_scenario(tmp_path), "--out", str(tmp_path / "run"), "--tolerance", "1e-9"], capsys,
                     code=ExitCode.VERDICT_FAILED)
    assert failed["summary"]["success"] is False


def test_view_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tiny_scenario(tmp_path)
    assert main(["run", scenario, "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    document = json_of(["view", str(tmp_path / "run"), "--scenario", scenario], capsys)
    assert document == {"replay": str(tmp_path / "run" / "replay.html"),
                        "bytes": (tmp_path / "run" / "replay.html").stat().st_size}
    code, out, err = run_main(["view", str(tmp_path / "run"), "--serve", "--json"], capsys)
    assert code == ExitCode.USAGE and out == ""
    assert err == "previewctl: error: --json reports the file written; --serve writes none: give one of them\n"


def test_paper_json(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    short_paper_scenes(monkeypatch)
    document = json_of(["paper", "--controller", "none", "--scenario", "paper_planar", "--workers", "1", "--no-gif",
                        "--no-replay", "--out", str(tmp_path), "--publish", str(tmp_path / "paper.md")], capsys)
    assert set(document) == {"out", "summary_file", "scenarios", "published"}
    assert document["published"] == str(tmp_path / "paper.md") and (tmp_path / "paper.md").is_file()
    assert document["scenarios"] == json.loads((tmp_path / "summary.json").read_text())
    assert list(document["scenarios"]) == ["paper_planar"]
    assert list(document["scenarios"]["paper_planar"]) == ["none-pinv"]
    assert document["scenarios"]["paper_planar"]["none-pinv"]["duration"] == 0.5


def test_bench_json_of_the_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = {"robot": "planar4", "scene": 0, "seed": 0, "controller": "qp", "execution": "qp", "success_1mm": True,
              "success_5mm": True, "collision_free": True, "self_collision_free": True, "max_hand_error": 1e-4,
              "cycle_time_median": 1e-3, "cycle_time_p95": 2e-3, "wall_time": 1.0, "cpu_time": 0.5}
    (tmp_path / "results.jsonl").write_text(json.dumps(record) + "\n")
    document = json_of(["bench", "--report-only", "--out", str(tmp_path)], capsys)
    assert document == {"out": str(tmp_path), "records": 1, "files": [
        str(tmp_path / name) for name in ("results.jsonl", "report.md", "success.png")]}
