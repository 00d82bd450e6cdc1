"""Tests of :mod:`previewctl.sim.scenario`: TOML scenario files and their error messages."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from previewctl.cli.main import main
from previewctl.errors import PreviewctlError, ScenarioError
from previewctl.sim.scenario import load_scenario, scenario_from_dict

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"

GOOD = """\
name = "tiny"
seed = 3

[robot]
source = "planar4"
q0 = [0.6, 1.0, -1.2, -1.0]

[path]
waypoints = [[1.9069, 1.0417], [1.8069, 1.0417]]
duration = 1.0

[[obstacles]]
name = "ball"
shape = "sphere"
radius = 0.1
position = [-1.0, -1.0]

[controller]
name = "multi"
gain = 1.5
preview_time = 0.5
weights = [0.3, 0.65, 0.05]

[timing]
dt = 0.02
duration = 0.5

[index]
length_unit = 0.01

[potential]
influence_distance = 0.2

[output]
figures = ["S"]
gif = false
"""

BASE: dict[str, Any] = {
    "robot": {"source": "planar4", "q0": [0.6, 1.0, -1.2, -1.0]},
    "path": {"waypoints": [[1.9069, 1.0417], [1.8069, 1.0417]], "duration": 1.0},
}


def doc(**sections: Any) -> dict[str, Any]:
    """``BASE`` with sections replaced or added (a ``None`` value removes the section)."""
    out = copy.deepcopy(BASE)
    for key, value in sections.items():
        if value is None:
            out.pop(key, None)
        else:
            out[key] = value
    return out


def write(tmp_path: Path, text: str, name: str = "scenario.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------------- success


def test_good_file_loads_with_every_section(tmp_path: Path) -> None:
    s = load_scenario(write(tmp_path, GOOD))
    assert s.name == "tiny" and s.seed == 3 and s.source == tmp_path / "scenario.toml"
    assert s.robot.name == "planar4" and s.robot.nq == 4
    np.testing.assert_allclose(s.q0, [0.6, 1.0, -1.2, -1.0])
    assert s.path.dim == 2 and s.path.duration == 1.0
    assert s.scene.names == ("ball",)
    assert s.controller.name == "multi"
    assert s.controller.params.gain == (1.5,) and s.controller.params.weights == (0.3, 0.65, 0.05)
    assert s.controller.params.preview_time == 0.5
    assert (s.timing.dt, s.timing.frame, s.timing.duration, s.timing.steps) == (0.02, 0.033, 0.5, 25)
    assert s.index.length_unit == 0.01 and s.potential.influence_distance == 0.2
    assert s.outputs.figures == ("S",) and s.outputs.gif is False


def test_defaults() -> None:
    s = scenario_from_dict(doc())
    assert s.name == "scenario" and s.seed == 0
    assert s.controller.name == "none"
    assert s.timing.dt == 0.01 and s.timing.frame == 0.033 and s.timing.duration == 1.0
    assert s.scene.obstacles == ()


def test_q0_in_degrees() -> None:
    s = scenario_from_dict(doc(robot={"source": "planar4", "q0_deg": list(np.degrees([0.6, 1.0, -1.2, -1.0]))}))
    np.testing.assert_allclose(s.q0, [0.6, 1.0, -1.2, -1.0])


@pytest.mark.parametrize("name", ["planar_free.toml", "panda_crossing.toml"])
def test_shipped_scenarios_load(name: str) -> None:
    s = load_scenario(SCENARIOS / name)
    assert s.name == Path(name).stem
    assert s.timing.duration > 0 and s.path.duration > 0


# ------------------------------------------------------------------------------------ errors


def test_typo_key_names_dotted_path_suggests_and_lists_valid_keys() -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(doc(controller={"name": "none", "gian": 1.0}))
    message = str(info.value)
    assert "'controller.gian'" in message
    assert "did you mean 'controller.gain'" in message
    assert "feedback_gain" in message and "weights" in message


def test_typo_at_top_level_and_in_obstacles() -> None:
    with pytest.raises(ScenarioError, match=r"unknown key 'controler'.*did you mean 'controller'"):
        scenario_from_dict({**doc(), "controler": {"name": "none"}})
    bad = doc(obstacles=[{"name": "b", "shape": "sphere", "radius": 0.1, "positon": [1, 1]}])
    with pytest.raises(PreviewctlError, match=r"obstacles\[0\].*'positon'"):
        scenario_from_dict(bad)


@pytest.mark.parametrize(
    ("sections", "pattern"),
    [
        ({"timing": {"dt": "fast"}}, r"timing\.dt must be a finite number, got 'fast'"),
        ({"controller": {"name": "multi", "weights": "0.3,0.7"}}, r"controller\.weights must be a list"),
        ({"controller": {"name": "fancy"}}, r"controller\.name = 'fancy' is not valid; valid: none, gradient"),
        ({"controller": {"preview_time": -1}}, r"controller\.preview_time must be > 0, got -1"),
        ({"controller": {"population": 2.5}}, r"controller\.population must be an integer, got 2\.5"),
        ({"output": {"gif": "yes"}}, r"output\.gif must be true or false"),
        ({"controller": {"name": "multi", "with_gradient": 1}}, r"controller\.with_gradient must be true or false"),
        ({"output": {"figures": ["strobe", "movie"]}}, r"unknown figure 'movie'; valid: strobe, S"),
        ({"index": {"weights": [1.0, 1.0]}}, r"index\.weights has 2 entries; robot 'planar4' has 3 control points"),
        ({"potential": {"gain": 2.0}}, r"potential\.gain must lie in \(0, 1\]"),
        ({"path": {"waypoints": [[1.9069, 1.0417, 0.0], [1.8, 1.0, 0.0]], "duration": 1.0}},
         r"path\.waypoints\[0\] must have 2 entries"),
        ({"path": {"waypoints": [[1.9069, 1.0417], [1.8, 1.0]], "duration": 0}}, r"path\.duration must be > 0"),
        ({"robot": {"source": "planar4", "q0": [0.6, 1.0, -1.2, -1.0], "geometry": "exact"}},
         r"robot\.geometry = 'exact' is not valid; valid: convex, capsules, mesh"),
        ({"robot": {"source": "nosuchbot", "q0": [0.0]}}, r"robot: unknown robot 'nosuchbot'; valid: planar4"),
        ({"timing": {"dt": 2.0}}, r"timing\.dt = 2\.0 s is longer than timing\.duration"),
        ({"seed": -1}, r"seed must be >= 0"),
    ],
)
def test_bad_values_name_the_key_and_value(sections: dict[str, Any], pattern: str) -> None:
    with pytest.raises(ScenarioError, match=pattern):
        scenario_from_dict(doc(**sections))


def test_missing_robot_and_missing_source() -> None:
    with pytest.raises(ScenarioError, match=r"missing section \[robot\]"):
        scenario_from_dict(doc(robot=None))
    with pytest.raises(ScenarioError, match=r"robot\.source is missing"):
        scenario_from_dict(doc(robot={"q0": [0, 0, 0, 0]}))
    with pytest.raises(ScenarioError, match=r"missing section \[path\]"):
        scenario_from_dict(doc(path=None))
    with pytest.raises(ScenarioError, match=r"exactly one of robot\.q0"):
        scenario_from_dict(doc(robot={"source": "planar4"}))


@pytest.mark.parametrize(
    ("weights", "pattern"),
    [
        ([0.5, 0.6], r"controller\.weights = \[0\.5, 0\.6\]: the k_i must sum to 1, they sum to 1\.1"),
        ([1.0], r"controller\.weights = \[1\.0\]: k_1 = 1\.0 must satisfy 0 < k_i < 1; for one preview use"),
        ([0.0, 1.0], r"k_1 = 0\.0 must satisfy 0 < k_i < 1"),
        ([0.3, 0.65, 0.06], r"sum to 1"),
    ],
)
def test_preview_weights_are_validated(weights: list[float], pattern: str) -> None:
    with pytest.raises(ScenarioError, match=pattern):
        scenario_from_dict(doc(controller={"name": "multi", "weights": weights}))


def test_q0_wrong_length() -> None:
    with pytest.raises(ScenarioError, match=r"robot\.q0 has 3 entries; robot 'planar4' needs 4 for joints joint1"):
        scenario_from_dict(doc(robot={"source": "planar4", "q0": [0.6, 1.0, -1.2]}))


def test_q0_off_the_path_start_says_how_far() -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(doc(robot={"source": "planar4", "q0": [0.6, 1.0, -1.2, -0.9]}))
    message = str(info.value)
    # the hand moves by 2 * 0.75 * sin(0.05) = 0.0750 m when q4 changes by 0.1 rad
    assert "robot.q0 puts the hand at" in message
    assert "0.0750 m from the path start" in message and "within 0.01 m" in message


def test_q0_outside_joint_limits() -> None:
    with pytest.raises(ScenarioError, match=r"robot\.q0: joint 'joint1' = 7 rad is outside its limits"):
        scenario_from_dict(doc(robot={"source": "planar4", "q0": [7.0, 0.0, 0.0, 0.0]}))


def test_file_errors_carry_the_file_name(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD.replace("gain = 1.5", "gian = 1.5"), "typo.toml")
    with pytest.raises(ScenarioError, match=r"typo\.toml: unknown key 'controller\.gian'"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(write(tmp_path, "[robot\nsource=", "broken.toml"))
    with pytest.raises(ScenarioError, match="does not exist"):
        load_scenario(tmp_path / "nope.toml")


# ------------------------------------------------------------------------------------- CLI


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (GOOD.replace("gain = 1.5", "gian = 1.5"), "controller.gian"),
        (GOOD.replace("dt = 0.02", 'dt = "fast"'), "timing.dt"),
        (GOOD.split("[robot]")[0] + "[path]" + GOOD.split("[path]", 1)[1], "[robot]"),
    ],
)
def test_cli_run_bad_scenario_exits_2_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                    text: str, needle: str) -> None:
    path = write(tmp_path, text)
    code = main(["run", str(path), "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("previewctl: error:") and needle in lines[0]
    assert captured.out == ""
    assert not (tmp_path / "out").exists()


def test_cli_run_missing_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(tmp_path / "missing.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not exist" in err[0]
