"""A core install (no extras) runs a controller; what needs an extra says which one, in one line.

A missing module is simulated with ``sys.modules[name] = None``, which makes ``import name`` fail as if it were
not installed.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from previewctl.bench.sweep import dask_client
from previewctl.cli.main import main
from previewctl.errors import MissingExtraError, PreviewctlError
from previewctl.extras import require
from previewctl.index.load import load_robot
from previewctl.sim.log import save_run
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import load_scenario
from previewctl.viz.drawing import pyplot
from previewctl.viz.meshes import file_parts

SCENARIO = Path(__file__).parents[1] / "scenarios" / "planar_free.toml"


def test_require_returns_the_installed_module() -> None:
    assert require("math", "viz", "anything") is math


def test_require_names_the_missing_module_and_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "viser", None)
    with pytest.raises(MissingExtraError) as caught:
        require("viser", "viz", "the browser replay")
    assert str(caught.value) == "the browser replay needs viser, which is not installed: pip install 'previewctl[viz]'"
    assert isinstance(caught.value, PreviewctlError) and isinstance(caught.value, ImportError)


def test_view_without_viser_is_one_line_naming_the_viz_extra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    scenario = load_scenario(SCENARIO)
    save_run(simulate(scenario, "none"), tmp_path / "run")
    capsys.readouterr()
    monkeypatch.setitem(sys.modules, "viser", None)
    assert main(["view", str(tmp_path / "run"), "--scenario", str(SCENARIO)]) == 2
    captured = capsys.readouterr()
    assert captured.err == ("previewctl: error: the browser replay needs viser, which is not installed: "
                            "pip install 'previewctl[viz]'\n")
    assert captured.out == "" and not (tmp_path / "run" / "replay.html").exists()


def test_a_robot_name_without_example_robot_data_names_the_robots_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "example_robot_data", None)
    with pytest.raises(MissingExtraError, match=r"^robot 'panda' \(not a shipped robot: planar4\) needs "
                       r"example_robot_data, which is not installed: pip install 'previewctl\[robots\]'$"):
        load_robot("panda")
    assert load_robot("planar4").nv == 4  # a shipped robot (a URDF file) needs no extra


def test_index_on_a_robot_name_without_example_robot_data_is_one_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "example_robot_data", None)
    assert main(["index", "--robot", "panda", "--q", "0,0,0,-1.5,0,1.5,0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("pip install 'previewctl[robots]'\n"), err


@pytest.mark.parametrize(("missing", "call", "extra"), [
    ("matplotlib", pyplot, "viz"),
    ("trimesh", lambda: file_parts("arm.stl", [1.0, 1.0, 1.0], (1.0, 1.0, 1.0, 1.0)), "viz"),
    ("distributed", lambda: dask_client(workers=1).__enter__(), "bench"),
])
def test_each_optional_import_names_its_extra(
    missing: str, call: Callable[[], Any], extra: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, missing, None)
    with pytest.raises(MissingExtraError, match=rf"needs {missing}, which is not installed: "
                       rf"pip install 'previewctl\[{extra}\]'$"):
        call()


def test_robots_without_example_robot_data_lists_the_shipped_ones_and_names_the_extra(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "example_robot_data", None)
    assert main(["robots"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines[1:] if line] == ["planar4", "example-robot-data's"]
    assert lines[-1] == "example-robot-data's arms (panda, ur5, ...) need: pip install 'previewctl[robots]'"
