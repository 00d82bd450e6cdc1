"""Tests of :mod:`previewctl.cli.main`: every command's ``--help``, and ``--version``."""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import logging
import re
from pathlib import Path

import pytest
from helpers import tiny_planar_toml

from previewctl.cli.main import EXIT_NO_VERSION, build_parser, main


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
    if not command:  # the top-level help lists every command
        assert all(name in out for name in COMMANDS)


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
    assert code == EXIT_NO_VERSION != 0
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
