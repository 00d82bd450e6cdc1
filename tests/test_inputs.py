"""Bad input never ends in a traceback: one line on stderr and exit 2 on the command line, a typed
:class:`~previewctl.errors.PreviewctlError` in Python, each naming the bad value and what is valid
(the list of issue 13, one test per item)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import planar_doc

import previewctl
from previewctl.cli import run as run_command
from previewctl.cli.main import main
from previewctl.control.params import ControllerParams
from previewctl.errors import (
    ConfigurationError,
    ParameterError,
    PreviewctlError,
    RobotLoadError,
    ScenarioError,
    SceneError,
)
from previewctl.index.amsi import IndexParams
from previewctl.robot.model import Robot
from previewctl.scene.motion import ConstantVelocity, Periodic, Static, Waypoints
from previewctl.scene.shapes import Box, Halfspace, Obstacle, Scene, Sphere
from previewctl.sim.scenario import scenario_from_dict
from previewctl.sim.schema import Timing


def fails_with(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``previewctl argv`` exits 2 with exactly one line on stderr that contains ``message`` (argparse's usage
    errors exit through ``SystemExit``)."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code  # type: ignore[assignment]
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("previewctl: error: "), err
    assert message in err, err


def toml(doc: dict[str, Any]) -> str:
    """A scenario document as TOML (top-level keys, tables, and arrays of tables; values as JSON literals)."""
    lines = [f"{k} = {json.dumps(v)}" for k, v in doc.items() if not isinstance(v, (dict, list))]
    for key, value in doc.items():
        for table in [value] if isinstance(value, dict) else value if isinstance(value, list) else []:
            lines.append(f"[{key}]" if isinstance(value, dict) else f"[[{key}]]")
            lines += [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def scenario_file(tmp_path: Path, **sections: Any) -> str:
    """A planar4 scenario file (:func:`helpers.planar_doc`) with ``sections`` replaced."""
    path = tmp_path / "scenario.toml"
    path.write_text(toml(planar_doc(**sections)))
    return str(path)


# -------------------------------------------------------------------------------- command line


@pytest.mark.parametrize(("robot", "why"), [
    ("anymal_c", "robot 'anymal_c' is not a serial arm: its joints branch into 4 chains"),
    ("b1_z1", "robot 'b1_z1' is not a serial arm: its joints branch into 5 chains"),
    ("cassie", "example-robot-data could not load 'cassie'"),
    ("centauro", "robot 'centauro' is not a serial arm: its joints branch into 8 chains"),
])
def test_index_of_a_robot_that_is_not_an_arm(robot: str, why: str, capsys: pytest.CaptureFixture[str]) -> None:
    fails_with(["index", "--robot", robot, "--q", "0"], why, capsys)


@pytest.mark.parametrize("command", ["run", "paper"])
def test_negative_seed(command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", scenario_file(tmp_path)] if command == "run" else ["paper", "--controller", "none"]
    fails_with([*argv, "--seed", "-3", "--out", str(tmp_path / "out")],
               "argument --seed: must be an integer >= 0, got '-3'", capsys)


@pytest.mark.parametrize(("timing", "periods"),
                         [({"duration": 1e9}, "1e+11"), ({"dt": 1e-12, "duration": 1.0}, "1e+12")])
def test_step_count_is_checked_before_anything_is_allocated(
    timing: dict[str, float], periods: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fails_with(["run", scenario_file(tmp_path, timing=timing)],
               f"{periods} control periods, more than 1,000,000; valid: duration / dt <= 1,000,000", capsys)
    with pytest.raises(ParameterError, match="more than 1,000,000"):
        Timing(dt=1e-12, duration=1.0)


def test_map_resolution_too_fine(capsys: pytest.CaptureFixture[str]) -> None:
    fails_with(["map", "--target", "1.5,1.0", "--resolution", "0.0001"],
               "resolution_deg = 0.0001 makes 25,920,000,000,000 candidates, more than 2,097,152; use "
               "resolution_deg >= 0.36", capsys)


def test_map_output_is_checked_before_the_map_is_computed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nowhere" / "d" / "m.png"
    fails_with(["map", "--target", "1.5,1.0", "--out", str(missing)],
               f"output file '{missing}': folder '{missing.parent}' does not exist; create it first", capsys)
    fails_with(["map", "--target", "1.5,1.0", "--out", str(tmp_path)],
               f"output file '{tmp_path}' is a folder; give a file name", capsys)


def test_obstacle_shape_of_the_wrong_type(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = scenario_file(tmp_path, obstacles=[{"name": "b", "shape": ["sphere"], "radius": 0.1,
                                               "position": [3.0, 3.0]}])
    fails_with(["run", path], "obstacles[0].shape = ['sphere'] is not valid; valid: sphere, box", capsys)


@pytest.mark.parametrize(("controller", "message"), [
    ({"name": "multi", "population": 10**9}, "controller.population must be <= 10000, got 1000000000"),
    ({"name": "multi", "previews": 7}, "previews = 7 but weights = [0.3, 0.65, 0.05] has 3: multi and reach use "
                                       "one preview per weight k_i; give 7 weights or leave previews out"),
    ({"name": "multi", "elite": 0}, "controller.elite must be >= 1, got 0"),
])
def test_controller_settings_are_checked_with_the_scenario(
    controller: dict[str, Any], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fails_with(["run", scenario_file(tmp_path, controller=controller), "--out", str(tmp_path / "o")], message, capsys)


def test_run_output_is_checked_before_the_simulation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_simulation(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated before checking --out")

    monkeypatch.setattr(run_command, "simulate", no_simulation)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    fails_with(["run", scenario_file(tmp_path), "--out", str(blocker)],
               f"output folder '{blocker}' is a file; give a folder", capsys)
    fails_with(["run", scenario_file(tmp_path), "--out", str(blocker / "sub")],
               f"output folder '{blocker / 'sub'}': cannot create '{blocker}'", capsys)


def test_index_refuses_a_configuration_outside_the_limits(capsys: pytest.CaptureFixture[str]) -> None:
    fails_with(["index", "--robot", "planar4", "--q", "10,0,0,0"],
               "joint 'joint1' = 10 is outside its limits; valid: [-6.28319, 6.28319] [rad or m]", capsys)


def test_index_of_a_continuous_joint(capsys: pytest.CaptureFixture[str]) -> None:
    """kinova: 6 joint angles, or the 9 entries of q with unit (cos, sin) pairs."""
    fails_with(["index", "--robot", "kinova", "--q", "3,4,1,1,1,0,1,1,0"],
               "q[0, 0:2] = (3, 4) of continuous joint 'j2s6s200_joint_1' must be a (cos, sin) pair: "
               "cos^2 + sin^2 = 1 to 1e-06, got norm 5", capsys)
    fails_with(["index", "--robot", "kinova", "--q", "1,2,3"],
               "--q has 3 values; robot 'kinova' needs one angle per joint (6: j2s6s200_joint_1, ", capsys)
    assert main(["index", "--robot", "kinova", "--q", "90,180,180,0,180,0", "--degrees", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(report["q"][:2], [0.0, 1.0], atol=1e-12)  # 90 deg as (cos, sin)


def test_map_prints_joint_angles_not_cos_sin(capsys: pytest.CaptureFixture[str], kinova: Robot) -> None:
    assert main(["map", "--robot", "kinova", "--target", "0.4,0.1,0.5", "--samples", "40", "--json"]) == 0
    best = json.loads(capsys.readouterr().out)["best"]
    assert len(best["q"]) == kinova.nq == 9 and len(best["q_deg"]) == kinova.nv == 6
    angles = kinova.angles_of(np.array([best["q"]]))[0]
    np.testing.assert_allclose(best["q_deg"], np.degrees(angles), atol=1e-3)


# ------------------------------------------------------------------------------------- the API


def test_load_robot_of_none() -> None:
    with pytest.raises(RobotLoadError, match="robot source must be a URDF path or a robot name"):
        previewctl.load_robot(None)  # type: ignore[arg-type]


def test_avoidance_of_an_empty_batch(planar4: Robot, panda: Robot) -> None:
    for robot in (planar4, panda):
        result = previewctl.avoidance(robot, np.zeros((0, robot.nq)))
        assert result.amsi.shape == (0,) and result.N.shape == (0, robot.nv, robot.nv)
        assert result.volumes.shape == (0, len(robot.control_points))


@pytest.mark.parametrize("value", [1e7, 1e300, -1e20])
def test_huge_joint_values(value: float, planar4: Robot, kinova: Robot) -> None:
    with pytest.raises(ConfigurationError, match=re.escape(f"q[0, 0] = {value:g} (joint 'joint1') is out of range; "
                                                           "valid: |q| <= 1e+06 [rad or m]")):
        previewctl.avoidance(planar4, np.array([value, 0.0, 0.0, 0.0]))
    q = kinova.neutral()
    q[0] = value
    with pytest.raises(ConfigurationError, match="out of range"):
        previewctl.avoidance(kinova, q)


def test_continuous_joint_pair_off_the_unit_circle(kinova: Robot) -> None:
    q = kinova.neutral()
    q[:2] = (3.0, 4.0)
    with pytest.raises(ConfigurationError, match=re.escape("q[0, 0:2] = (3, 4) of continuous joint "
                                                           "'j2s6s200_joint_1' must be a (cos, sin) pair")):
        previewctl.evaluate(kinova, None, q)


@pytest.mark.parametrize(("make", "message"), [
    (lambda: Sphere(float("nan")), "radius must be finite, got nan"),
    (lambda: Sphere(-0.1), "radius must be > 0, got -0.1"),
    (lambda: Box((-1.0, 1.0, 1.0)), "size[0] must be > 0, got -1"),
    (lambda: Halfspace((0.0, 0.0, 0.0)), "normal must be non-zero, got [0.0, 0.0, 0.0]"),
])
def test_api_obstacles_are_validated(make: Any, message: str) -> None:
    with pytest.raises(SceneError, match=re.escape(message)):
        make()


def test_index_weights_must_be_finite() -> None:
    with pytest.raises(ParameterError, match=re.escape("weights[0] must be finite, got nan")):
        IndexParams(weights=(float("nan"),) * 3)


def test_population_cap() -> None:
    with pytest.raises(ParameterError, match="population must be <= 10000, got 1000000000"):
        ControllerParams(population=10**9)


def test_every_error_here_is_a_previewctl_error() -> None:
    for error in (ConfigurationError, ParameterError, RobotLoadError, SceneError):
        assert issubclass(error, PreviewctlError)


# ------------------------------------------------------------------- found while reproducing the list


@pytest.mark.parametrize(("argv", "message"), [
    (["index", "--q", "0,0,0,0", "--time", "nan"], "t must be finite, got nan"),
    (["map", "--target", "1.5,1.0", "--samples", "-5"], "samples must be an integer >= 1, got -5"),
    (["map", "--target", "1.5,1.0", "--seed", "-1"], "argument --seed: must be an integer >= 0, got '-1'"),
    (["reach-map", str(Path(__file__).parent.parent / "scenarios" / "planar_free.toml"), "--resolution", "0.001"],
     "resolution_deg = 0.001 and steps = 50 make 52,876,946,880,102 grid nodes (720001 x 720001 cells x 2 "
     "branches x 51 layers), more than 33,554,432: use a coarser resolution or fewer steps"),
])
def test_more_bad_options(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    fails_with(argv, message, capsys)


def test_huge_prismatic_values(tmp_path: Path) -> None:
    """A slide with limits of +-1e9 m loads (sampling stays within |q| <= 1e6) and evaluates up to the cap."""
    box = '<collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision>'
    joint = ('<joint name="{0}" type="{1}"><parent link="{2}"/><child link="{3}"/><origin xyz="{4}"/>'
             '<axis xyz="{5}"/><limit lower="{6}" upper="{7}" effort="1" velocity="1"/></joint>')
    path = tmp_path / "slide.urdf"
    path.write_text("".join([
        '<robot name="slide"><link name="base"/>', *(f'<link name="l{k}">{box}</link>' for k in (1, 2, 3)),
        '<link name="hand"/>',
        joint.format("slide", "prismatic", "base", "l1", "0 0 0.1", "1 0 0", -1e9, 1e9),
        joint.format("j1", "revolute", "l1", "l2", "0 0 0.1", "0 0 1", -3, 3),
        joint.format("j2", "revolute", "l2", "l3", "0.4 0 0", "0 1 0", -3, 3),
        joint.format("j3", "revolute", "l3", "hand", "0.4 0 0", "0 1 0", -3, 3), "</robot>"]))
    robot = previewctl.load_robot(path)
    for value in (1e3, 9.9e5):
        assert np.isfinite(previewctl.avoidance(robot, np.array([value, 0.3, 0.2, 0.1])).amsi)
    with pytest.raises(ConfigurationError, match=re.escape("q[0, 0] = 2e+06 (joint 'slide') is out of range")):
        previewctl.avoidance(robot, np.array([2e6, 0.3, 0.2, 0.1]))


# ------------------------------------------------------------------------- issue 30: scenes and --out


def test_scene_of_one_obstacle_says_to_pass_a_tuple() -> None:
    ball = Obstacle("ball", Sphere(0.1), Static([0.5, 0.5, 0.5]))
    with pytest.raises(SceneError, match=re.escape("Scene takes a tuple of obstacles, got one Obstacle 'ball': "
                                                   "pass a tuple, Scene((obstacle,))")):
        Scene(ball)  # type: ignore[arg-type]
    assert Scene([ball]).obstacles == (ball,)  # a list is taken as its tuple


@pytest.mark.parametrize(("obstacles", "message"), [
    (["ball"], "Scene obstacles[0] must be an Obstacle, got str 'ball': build it with Obstacle(name, shape, motion)"),
    ((Obstacle("a", Sphere(0.1)), {"name": "b"}), "Scene obstacles[1] must be an Obstacle, got dict {'name': 'b'}"),
    ("ball", "Scene takes a tuple of obstacles, got str 'ball': pass a tuple of Obstacle"),
    (None, "Scene takes a tuple of obstacles, got NoneType None"),
])
def test_scene_of_something_else_names_the_element_and_its_type(obstacles: Any, message: str) -> None:
    with pytest.raises(SceneError, match=re.escape(message)):
        Scene(obstacles)


PLANAR_MOTIONS = [
    (Static([0.5, 0.5]), "position [0.5, 0.5]"),
    (ConstantVelocity([0.5, 0.5, 0.5], [0.1, 0.0]), "velocity [0.1, 0.0]"),
    (Waypoints([0.0, 1.0], [[0.5, 0.5], [0.6, 0.5]]), "waypoints [[0.5, 0.5], [0.6, 0.5]]"),
    (Periodic([0.5, 0.5], [0.0, 0.1, 0.0], 4.0), "center [0.5, 0.5]"),
]


@pytest.mark.parametrize(("motion", "given"), PLANAR_MOTIONS)
def test_a_2d_obstacle_around_a_spatial_arm_is_refused(motion: Any, given: str, planar4: Robot, panda: Robot) -> None:
    scene = Scene((Obstacle("ball", Sphere(0.05), motion),))
    message = (f"obstacle 'ball': {given} is 2-D, but robot 'panda' is spatial (task 'position'): give 3-D positions "
               "[x, y, z] [m] (2-D ones are for planar arms)")
    with pytest.raises(SceneError, match=re.escape(message)):
        previewctl.Evaluator(panda, scene)
    path = previewctl.HandPath([[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]], duration=10.0)
    with pytest.raises(SceneError, match=re.escape(message)):
        previewctl.make_controller("none", robot=panda, path=path, scene=scene)
    previewctl.Evaluator(planar4, scene)  # a planar arm moves in z = 0: 2-D is what it means


def test_a_2d_obstacle_in_a_spatial_scenario_file_is_refused_when_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = {"name": "flat", "robot": {"source": "panda", "q0": [-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147,
                                                               0.785]},
           "path": {"waypoints": [[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]], "duration": 10.0},
           "obstacles": [{"name": "ball", "shape": "sphere", "radius": 0.08, "position": [0.06, 0.6]}]}
    message = ("obstacle 'ball': position [0.06, 0.6] is 2-D, but robot 'panda' is spatial (task 'position'): give "
               "3-D positions [x, y, z] [m]")
    with pytest.raises(ScenarioError, match=re.escape(f"flat.toml: {message}")):
        scenario_from_dict(doc, source="flat.toml")
    path = tmp_path / "flat.toml"
    path.write_text(toml(doc))
    out = tmp_path / "out"
    fails_with(["run", str(path), "--out", str(out)], f"{path}: {message}", capsys)
    assert not out.exists()


@pytest.mark.parametrize("argv", [["run", "SCENARIO", "--out", "/proc/previewctl-out"],
                                  ["map", "--target", "1.5,1.0", "--out", "/proc/previewctl-map.png"]])
def test_an_output_where_nothing_can_be_written_is_refused_before_anything_runs(
    argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """/proc passes os.access for root, yet nothing can be made there: the folder and the OS's reason, exit 2."""
    def no_simulation(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated before checking --out")

    monkeypatch.setattr(run_command, "simulate", no_simulation)
    argv = [scenario_file(tmp_path) if a == "SCENARIO" else a for a in argv]
    kind = "output folder" if argv[0] == "run" else "output file"
    fails_with(argv, f"{kind} {argv[-1]!r}: cannot write in folder '/proc': ", capsys)
    assert not Path(argv[-1]).exists()
