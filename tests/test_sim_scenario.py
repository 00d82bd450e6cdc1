"""Tests of :mod:`previewctl.sim.scenario`: TOML scenario files and their error messages."""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

import numpy as np
import pydantic
import pytest
from helpers import PLANAR_START, planar_doc

from previewctl.cli.main import main
from previewctl.control.params import ControllerParams
from previewctl.errors import ParameterError, PreviewctlError, ScenarioError
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.kinematics import kinematics
from previewctl.robot.model import Robot
from previewctl.robot.reach import reach_of
from previewctl.search.explore import explore
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
    with pytest.raises(PreviewctlError,
                       match=r"unknown key 'obstacles\[0\]\.positon' \(did you mean 'obstacles\[0\]\.position'"):
        scenario_from_dict(bad)


@pytest.mark.parametrize(
    ("sections", "pattern"),
    [
        ({"timing": {"dt": "fast"}}, r"timing\.dt must be a finite number, got 'fast'"),
        ({"controller": {"name": "multi", "weights": "0.3,0.7"}}, r"controller\.weights must be a list"),
        ({"controller": {"name": "fancy"}}, r"controller\.name = 'fancy' is not valid; valid: none, qp, gradient"),
        ({"controller": {"preview_time": -1}}, r"controller\.preview_time must be > 0, got -1"),
        ({"controller": {"population": 2.5}}, r"controller\.population must be an integer, got 2\.5"),
        ({"output": {"gif": "yes"}}, r"output\.gif must be true or false"),
        ({"controller": {"name": "multi", "with_gradient": 1}}, r"controller\.with_gradient must be true or false"),
        ({"output": {"figures": ["strobe", "movie"]}},
         r"output\.figures\[1\] = 'movie' is not valid; valid: strobe, S"),
        ({"index": {"weights": [1.0, 1.0]}}, r"index\.weights has 2 entries; robot 'planar4' has 3 control points"),
        ({"potential": {"gain": 2.0}}, r"potential\.gain must lie in \(0, 1\]"),
        ({"path": {"waypoints": [[1.9069, 1.0417, 0.0], [1.8, 1.0, 0.0]], "duration": 1.0}},
         r"path\.waypoints\[0\] must have 2 entries"),
        ({"path": {"waypoints": [[1.9069, 1.0417], [1.8, 1.0]], "duration": 0}}, r"path\.duration must be > 0"),
        ({"robot": {"source": "planar4", "q0": [0.6, 1.0, -1.2, -1.0], "geometry": "exact"}},
         r"robot\.geometry = 'exact' is not valid; valid: convex, capsules, mesh"),
        ({"robot": {"source": "nosuchbot", "q0": [0.0]}}, r"robot: unknown robot 'nosuchbot'; valid: planar4"),
        ({"timing": {"dt": 2.0}}, r"\[timing\] dt = 2\.0 s is longer than duration = 1\.0 s"),
        ({"seed": -1}, r"seed must be >= 0"),
    ],
)
def test_bad_values_name_the_key_and_value(sections: dict[str, Any], pattern: str) -> None:
    with pytest.raises(ScenarioError, match=pattern):
        scenario_from_dict(doc(**sections))


@pytest.mark.parametrize(
    ("sections", "expected"),
    [
        # a bad value in each section
        ({"name": ""}, "scenario: name must not be empty"),
        ({"description": 3}, "scenario: description must be a string, got 3"),
        ({"seed": 1.5}, "scenario: seed must be an integer, got 1.5"),
        ({"robot": {**BASE["robot"], "task": "orientation"}},
         "robot.task = 'orientation' is not valid; valid: planar, position, pose"),
        ({"robot": {**BASE["robot"], "guarded_links": 3}},
         "robot.guarded_links must be a list of strings or one of all, intermediate, got 3"),
        ({"robot": {**BASE["robot"], "q0": [0.6, "1.0", -1.2, -1.0]}},
         "robot.q0[1] must be a finite number, got '1.0'"),
        ({"path": {**BASE["path"], "start_time": float("nan")}}, "path.start_time must be finite, got nan"),
        ({"path": {**BASE["path"], "orientation_rpy": [0.0, 0.0]}}, "path.orientation_rpy must have 3 entries, got 2"),
        ({"path": {**BASE["path"], "waypoints": [[1.9069, 1.0417]]}}, "path.waypoints needs at least 2 points, got 1"),
        ({"obstacles": [{"shape": "box", "size": [0.1, 0.2]}]}, "obstacles[0].size must have 3 entries, got 2"),
        ({"obstacles": [{"shape": "sphere", "radius": 0.1}, {"shape": "spere", "radius": 0.1}]},
         "obstacles[1].shape = 'spere' is not valid; valid: sphere, box, capsule, cylinder, halfspace, plane, mesh "
         "(did you mean 'sphere'?)"),
        ({"obstacles": [{"shape": "sphere", "radius": 0.1, "position": [1, 1], "motion": {"type": "static",
                                                                                          "position": [1, 1]}}]},
         "obstacles[0] gives both 'motion' and 'position'/'rpy'; give one of them"),
        ({"obstacles": [{"shape": "sphere", "radius": 0.1},
                        {"shape": "sphere", "radius": 0.1, "motion": {"type": "constant_velocity", "position": [1, 1],
                                                                       "velocity": [1, "fast"]}}]},
         "obstacles[1].motion.velocity[1] must be a finite number, got 'fast'"),
        ({"obstacles": [{"shape": "sphere", "radius": 0.1, "motion": {"type": "periodic", "center": [1, 1],
                                                                       "amplitude": [0, 1], "period": -2}}]},
         "obstacles[0].motion.period must be > 0 [s], got -2.0"),
        ({"controller": {"gain": [1.0, 2.0]}}, "controller.gain has 2 entries; give one number or 4"),
        ({"controller": {"damping": -0.1}}, "controller.damping must be >= 0, got -0.1"),
        ({"controller": {"velocity_scale": 0}}, "controller.velocity_scale must lie in (0, 1], got 0.0"),
        ({"controller": {"population": 3}}, "controller.population must be >= 4, got 3"),
        ({"controller": {"population": 6}}, "[controller] elite + top_k must be below population: 2 + 4 >= 6"),
        ({"controller": {"ga": {"immigrants": 0.7}}}, "controller.ga.immigrants must lie in [0, 0.5], got 0.7"),
        ({"controller": {"ga": {"mutaton_scale": 0.1}}},
         "unknown key 'controller.ga.mutaton_scale' (did you mean 'controller.ga.mutation_scale'?); valid keys in "
         "[controller.ga]: mutation_scale, niche_radius, immigrants, tournament, crossover_rate, blend, branch_flip"),
        ({"controller": {"ga": {"population": 8}}}, "unknown key 'controller.ga.population'"),
        ({"timing": {"frame": 0}}, "timing.frame must be > 0, got 0"),
        ({"timing": {"duration": "long"}}, "timing.duration must be a finite number, got 'long'"),
        ({"index": {"length_unit": -0.01}}, "index.length_unit must be > 0, got -0.01"),
        ({"index": {"weights": [1.0, -1.0, 1.0]}}, "index.weights[1] must be >= 0, got -1.0"),
        ({"index": {"rank_tolerance": 0.1}}, "unknown key 'index.rank_tolerance'; valid keys in [index]: weights, "
                                             "length_unit"),
        ({"potential": {"collision_value": 1}}, "potential.collision_value must be < 0, got 1"),
        ({"potential": {"influence_distance": "far"}}, "potential.influence_distance must be a finite number"),
        ({"output": {"strobe_poses": 1}}, "output.strobe_poses must be >= 2, got 1"),
        ({"output": {"figures": "S"}}, "output.figures must be a list of names among strobe, S, clearance, error"),
        # unknown keys, with a suggestion
        ({"robot": {**BASE["robot"], "geometyr": "mesh"}},
         "unknown key 'robot.geometyr' (did you mean 'robot.geometry'?)"),
        ({"path": {**BASE["path"], "duraton": 1.0}}, "unknown key 'path.duraton' (did you mean 'path.duration'?)"),
        ({"timing": {"dt": 0.01, "fram": 0.05}}, "unknown key 'timing.fram' (did you mean 'timing.frame'?)"),
        ({"potential": {"gian": 0.5}}, "unknown key 'potential.gian' (did you mean 'potential.gain'?)"),
        ({"output": {"gifs": True}}, "unknown key 'output.gifs' (did you mean 'output.gif'?)"),
        ({"obstacles": [{"shape": "sphere", "radius": 0.1, "motion": {"type": "static", "positon": [1, 1]}}]},
         "unknown key 'obstacles[0].motion.positon' (did you mean 'obstacles[0].motion.position'?); valid keys in "
         "obstacles[0].motion (type = 'static'): type, position, rpy"),
        # a wrong type for a whole section
        ({"timing": 0.01}, "timing must be a table, got 0.01"),
        ({"obstacles": {"shape": "sphere"}}, "obstacles must be a list of tables, got {'shape': 'sphere'}"),
    ],
)
def test_every_section_names_the_key_the_value_and_the_choices(sections: dict[str, Any], expected: str) -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(doc(**sections))
    assert expected in str(info.value)
    assert not isinstance(info.value, pydantic.ValidationError)


@pytest.mark.parametrize(
    ("key", "value"),
    [("gain", 0.0), ("gradient_gain", [1.0, -1.0]), ("feedback_gain", -1), ("singular_threshold", 0),
     ("velocity_scale", 1.5), ("preview_time", "5"), ("weights", [0.5, 0.6]), ("previews", 0), ("population", 2),
     ("elite", 0), ("top_k", 1.0), ("fd_step", float("inf")), ("with_gradient", "yes")],
)
def test_controller_keys_obey_the_same_rule_in_a_file_and_in_the_api(key: str, value: object) -> None:
    """The ``[controller]`` table is made from ControllerParams' fields: one bound, one message."""
    with pytest.raises(ParameterError) as api:
        ControllerParams(**{key: value})
    with pytest.raises(ScenarioError) as file:
        scenario_from_dict(doc(controller={key: value}))
    assert str(file.value) == f"scenario: controller.{api.value}"


def test_missing_robot_and_missing_source() -> None:
    with pytest.raises(ScenarioError, match=r"missing section \[robot\]"):
        scenario_from_dict(doc(robot=None))
    with pytest.raises(ScenarioError, match=r"robot\.source is missing"):
        scenario_from_dict(doc(robot={"q0": [0, 0, 0, 0]}))
    with pytest.raises(ScenarioError, match=r"missing section \[path\]"):
        scenario_from_dict(doc(path=None))
    with pytest.raises(ScenarioError, match=r"robot needs exactly one of q0 \[rad\] or q0_deg \[deg\]"):
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
    with pytest.raises(ScenarioError, match=r"scenario file '.*nope\.toml' does not exist"):
        load_scenario(tmp_path / "nope.toml")
    latin1 = tmp_path / "latin1.toml"
    latin1.write_bytes('name = "côte"\n'.encode("latin-1"))
    with pytest.raises(ScenarioError, match=r"scenario file '.*latin1\.toml' cannot be read: 'utf-8' codec"):
        load_scenario(latin1)


def test_robot_srdf_is_read_relative_to_the_scenario_file(tmp_path: Path) -> None:
    """``[robot] srdf``: a path relative to the scenario file, as the URDF's; the exact (mesh) robot reads it too."""
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "adjacent.srdf").write_text(
        '<robot name="planar4"><disable_collisions link1="link1" link2="link2"/>'
        '<disable_collisions link1="link2" link2="link3"/><disable_collisions link1="link3" link2="link4"/></robot>')
    text = GOOD.replace('source = "planar4"', 'source = "planar4"\nsrdf = "robots/adjacent.srdf"')
    scenario = load_scenario(write(tmp_path, text))
    expected = f"SRDF {tmp_path / 'robots' / 'adjacent.srdf'}"
    assert scenario.robot_spec.srdf == str(tmp_path / "robots" / "adjacent.srdf")
    for robot in (scenario.robot, scenario.exact_robot()):
        assert robot.self_pairs.source == expected and len(robot.self_pairs.links) == 3
    with pytest.raises(PreviewctlError, match=r"SRDF file '.*robots/missing\.srdf' does not exist"):
        load_scenario(write(tmp_path, text.replace("adjacent.srdf", "missing.srdf"), "missing.toml"))


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


# ------------------------------------------------------------------------- reach and start

TWO_LINK = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/>
    <axis xyz="0 0 1"/><limit lower="-6.3" upper="6.3" effort="1" velocity="1"/></joint>
  <link name="link1"><collision><origin xyz="0.5 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.02" length="1.0"/></geometry></collision></link>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="1.0 0 0"/><axis xyz="0 0 1"/><limit lower="-6.3" upper="6.3" effort="1" velocity="1"/></joint>
  <link name="link2"><collision><origin xyz="0.2 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.02" length="0.4"/></geometry></collision></link>
  <joint name="tip_joint" type="fixed"><parent link="link2"/><child link="tip"/><origin xyz="0.4 0 0"/></joint>
  <link name="tip"/>
</robot>
"""


def test_a_waypoint_beyond_reach_is_refused_before_simulating() -> None:
    doc = planar_doc(path={"waypoints": [PLANAR_START, [5.0, 5.0]], "duration": 1.0})
    with pytest.raises(ScenarioError, match=re.escape(
            "path.waypoints[1] = [5.0, 5.0] m is 7.0711 m from the base of robot 'planar4' (its first joint, at "
            "[0.0, 0.0] m), beyond its reach of 3.0000 m")):
        scenario_from_dict(doc)


def test_the_reach_shell_of_a_planar_arm_is_exact_and_its_hole_is_checked(tmp_path: Path) -> None:
    urdf = tmp_path / "two_link.urdf"
    urdf.write_text(TWO_LINK)
    robot = load_robot(urdf)
    reach = reach_of(robot)
    assert (reach.inner, reach.outer) == (pytest.approx(0.6), pytest.approx(1.4))  # |1.0 - 0.4|, 1.0 + 0.4
    # closed form reached: the hand over a grid of both joints spans exactly [0.6, 1.4] m
    grid = np.stack(np.meshgrid(np.linspace(-np.pi, np.pi, 73), np.linspace(-np.pi, np.pi, 73)), -1).reshape(-1, 2)
    distances = np.linalg.norm(kinematics(robot, grid).tip_position, axis=1)
    assert distances.min() == pytest.approx(0.6, abs=1e-12) and distances.max() == pytest.approx(1.4, abs=1e-12)
    start = kinematics(robot, np.array([[0.0, 0.5]])).tip_position[0, :2]
    doc = {"robot": {"source": str(urdf), "q0": [0.0, 0.5]},
           "path": {"waypoints": [start.tolist(), [-1.0, 0.0]], "duration": 2.0}}
    with pytest.raises(ScenarioError, match=r"path segment 0-1 passes 0\.\d+ m from the base of robot 'two_link' "
                       r"\(at \[0\.0, 0\.0\] m\); the hand cannot come closer than 0\.6000 m"):
        scenario_from_dict(doc)


def test_q0_auto_starts_from_the_best_collision_free_configuration(planar4: Robot) -> None:
    ball = {"name": "ball", "shape": "sphere", "radius": 0.2, "position": [1.0, 1.3]}
    scenario = scenario_from_dict(planar_doc(robot={"source": "planar4", "q0": "auto"}, obstacles=[ball]))
    hand = kinematics(planar4, scenario.q0[None, :]).tip_position[0, :2]
    np.testing.assert_allclose(hand, PLANAR_START, atol=1e-6)
    evaluator = Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential)
    best = explore(scenario.robot, evaluator, PLANAR_START).best
    np.testing.assert_allclose(scenario.q0, best.q)
    assert evaluator(scenario.q0).S[0] == pytest.approx(best.S) and best.S > 0
    with pytest.raises(ScenarioError, match=r"robot.q0 must be a list of numbers \[rad\] or \"auto\", got 'automatic'"):
        scenario_from_dict(planar_doc(robot={"source": "planar4", "q0": "automatic"}))
    # the file's q0 off the path: refused, with the way out in the message
    with pytest.raises(ScenarioError, match=r"robot.q0 puts the hand at \[3\., 0\.\] m, 1\.5100 m from the path start"
                       r".*set q0 = \"auto\" \(previewctl run --q0 auto\)"):
        scenario_from_dict(planar_doc(robot={"source": "planar4", "q0": [0.0, 0.0, 0.0, 0.0]}))


def test_cli_run_q0_auto(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "off.toml"
    path.write_text('[robot]\nsource = "planar4"\nq0 = [0.0, 0.0, 0.0, 0.0]\n'
                    "[path]\nwaypoints = [[1.9069, 1.0417], [1.8069, 1.0417]]\nduration = 0.2\n"
                    "[output]\nfigures = []\ngif = false\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "--q0 auto" in capsys.readouterr().err
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--q0", "auto"]) == 0
    assert "success                   yes" in capsys.readouterr().out
