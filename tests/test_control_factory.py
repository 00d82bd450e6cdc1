"""The factory maps each controller name to one law class and its parts, refuses what a law cannot honour, and
reports (warning, ``describe()``, run log) the settings a controller does not read."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

from previewctl.control.execution import PseudoInverseExecution, QPExecution
from previewctl.control.factory import make_controller
from previewctl.control.imaginary import ArgmaxArms, RoutePoints, TrackedPeaks
from previewctl.control.laws import Gradient, Horizon, MultiPreview, Oracle, QPBaseline, Reach, SinglePreview, Tracking
from previewctl.control.params import CONTROLLER_NAMES, ControllerParams, controller_runs, execution_of
from previewctl.control.planner import PeakPlanner
from previewctl.control.sweeps import SweepRoutes
from previewctl.errors import IgnoredSettingWarning, ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import scenario_from_dict

LAW_OF = {"none": Tracking, "qp": QPBaseline, "gradient": Gradient, "single": SinglePreview, "multi": MultiPreview,
          "reach": Reach, "horizon": Horizon, "oracle": Oracle}


def _path(robot: Robot) -> HandPath:
    if robot.planar is not None:
        return HandPath(np.array([[1.5, 1.0], [1.2, 1.2]]), 2.0)
    return HandPath(np.array([[0.45, -0.2, 0.35], [0.45, 0.2, 0.35]]), 2.0)


def _made(name: str, robot: Robot, **settings: object):  # type: ignore[no-untyped-def]
    return make_controller(name, robot=robot, path=_path(robot), params=ControllerParams(**settings))  # type: ignore[arg-type]


def _planar_urdf(joints: int) -> str:
    """A planar arm of ``joints`` revolute joints about z, 0.5 m links with cylinder collision geometry, and a tip."""
    parts = ['<?xml version="1.0"?>', f'<robot name="planar{joints}">', '<link name="link0"/>']
    for i in range(1, joints + 1):
        offset = "0" if i == 1 else "0.5"
        parts += [
            f'<joint name="joint{i}" type="revolute"><parent link="link{i - 1}"/><child link="link{i}"/>'
            f'<origin xyz="{offset} 0 0"/><axis xyz="0 0 1"/>'
            '<limit lower="-6.283" upper="6.283" effort="50" velocity="1.0"/></joint>',
            f'<link name="link{i}"><inertial><origin xyz="0.25 0 0"/><mass value="1"/>'
            '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>'
            '<collision><origin xyz="0.25 0 0" rpy="0 1.5707963267948966 0"/>'
            '<geometry><cylinder radius="0.03" length="0.5"/></geometry></collision></link>',
        ]
    parts += [f'<joint name="tip_joint" type="fixed"><parent link="link{joints}"/><child link="tip"/>'
              '<origin xyz="0.5 0 0"/></joint>', '<link name="tip"/>']
    return "\n".join([*parts, "</robot>"])


@pytest.fixture(scope="module")
def planar5(tmp_path_factory: pytest.TempPathFactory) -> Robot:
    urdf = Path(tmp_path_factory.mktemp("planar5")) / "planar5.urdf"
    urdf.write_text(_planar_urdf(5))
    robot = load_robot(str(urdf))
    assert robot.planar is not None and robot.nq == 5
    return robot


@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_each_name_is_one_law_class(name: str, planar4: Robot, panda: Robot) -> None:
    for robot in (planar4, panda):
        ctrl = _made(name, robot)
        assert type(ctrl.law) is LAW_OF[name] and ctrl.name == name == ctrl.law.name
        composition = ctrl.describe()
        assert composition.controller == name and composition.law == LAW_OF[name].__name__
        assert composition.execution == ctrl.execution.name == execution_of(name, ctrl.params)
        assert composition.ignored == ()
    assert len(set(LAW_OF.values())) == len(CONTROLLER_NAMES)


@pytest.mark.parametrize(("name", "settings", "policy", "planner"), [
    ("single", {}, "peaks", None),
    ("single", {"coherent": False}, "argmax", None),
    ("multi", {}, "route", "dp"),
    ("multi", {"imaginary_arms": "peaks"}, "peaks", None),
    ("multi", {"coherent": False}, "argmax", None),
    ("reach", {}, None, "dp"),
    ("reach", {"coherent": False}, None, "sweeps"),
    ("horizon", {}, None, "dp"),
    ("oracle", {}, None, "dp"),
    ("gradient", {}, None, None),
])
def test_the_composition_names_the_parts_built(name: str, settings: dict[str, object], policy: str | None,
                                               planner: str | None, planar4: Robot) -> None:
    ctrl = _made(name, planar4, **settings)
    composition = ctrl.describe()
    assert (composition.imaginary_arms, composition.planner) == (policy, planner)
    law = ctrl.law
    if policy is not None:
        assert isinstance(law, (SinglePreview, MultiPreview))
        assert type(law.policy) is {"argmax": ArgmaxArms, "peaks": TrackedPeaks, "route": RoutePoints}[policy]
    if isinstance(law, Reach):
        assert isinstance(law.route, PeakPlanner if planner == "dp" else SweepRoutes)
    text = str(composition)
    assert text.startswith(f"{name} ({type(law).__name__}), execution qp")
    for part in (policy, planner):
        assert part is None or part in text


def test_spatial_arms_plan_by_the_sampled_search(panda: Robot) -> None:
    assert _made("multi", panda).describe().planner == "sampled"
    assert _made("reach", panda).describe().planner == "sampled"
    assert _made("reach", panda, coherent=False).describe().planner == "sweeps"


def test_none_and_qp_keep_their_own_execution(planar4: Robot) -> None:
    """none is eq. 19 alone (the pseudo-inverse), qp the same law under the QP, whatever ``execution`` says."""
    assert isinstance(_made("none", planar4).execution, PseudoInverseExecution)
    with pytest.warns(IgnoredSettingWarning):
        assert isinstance(_made("qp", planar4, execution="pseudoinverse").execution, QPExecution)
    assert isinstance(_made("gradient", planar4, execution="pseudoinverse").execution, PseudoInverseExecution)
    assert isinstance(_made("gradient", planar4).execution, QPExecution)
    assert controller_runs(["none", "qp", "multi"], ["qp", "pseudoinverse"]) == [
        ("none", "pseudoinverse"), ("qp", "qp"), ("multi", "qp"), ("multi", "pseudoinverse")]
    assert controller_runs(["none"], ["qp"]) == []


def test_a_setting_the_controller_does_not_read_is_warned_and_recorded(planar4: Robot) -> None:
    with pytest.warns(IgnoredSettingWarning, match=r"'reach' does not use with_gradient = True: ignored"):
        ctrl = _made("reach", planar4, with_gradient=True)
    assert ctrl.describe().ignored == ("with_gradient = True",)
    with pytest.warns(IgnoredSettingWarning, match=r"'qp' does not use execution = 'pseudoinverse'"):
        _made("qp", planar4, execution="pseudoinverse")
    with pytest.warns(IgnoredSettingWarning, match=r"'none' does not use .*gain = \(2\.0,\).*population = 32"):
        _made("none", planar4, gain=2.0, population=32)
    with pytest.warns(IgnoredSettingWarning, match=r"'multi' does not use imaginary_arms = 'peaks'"):
        _made("multi", planar4, coherent=False, imaginary_arms="peaks")
    with pytest.warns(IgnoredSettingWarning, match=r"'single' does not use .*weights"):
        _made("single", planar4, weights=(0.5, 0.5))


def test_settings_a_controller_reads_give_no_warning(planar4: Robot) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _made("none", planar4, execution="pseudoinverse", feedback_gain=3.0, limit_margin=0.2)
        _made("qp", planar4, influence_distance=0.2, safety_distance=0.01)
        _made("gradient", planar4, gradient_gain=2e-4, fd_step=1e-5)
        _made("single", planar4, gain=2.0, preview_time=0.5, track_radius=0.3, population=32)
        _made("multi", planar4, imaginary_arms="route", plan_latency=0.1, hysteresis=0.1, with_gradient=True)
        _made("multi", planar4, imaginary_arms="peaks", track_neighbours=4, with_gradient=True, fd_step=1e-5)
        _made("reach", planar4, replan_period=0.25, plan_window=2.0, settle_frames=5)
        _made("horizon", planar4, plan_window=2.0, replan_period=0.25, preview_time=0.5)
        _made("oracle", planar4, gain=2.0)


def test_route_needs_an_arm_the_planner_covers(planar5: Robot) -> None:
    with pytest.raises(ParameterError, match=r"imaginary_arms = 'route' needs an arm the window planner covers.*"
                                             r"'planar5' is planar with 5 joints: use imaginary_arms = 'peaks'"):
        _made("multi", planar5, imaginary_arms="route")
    by_default = _made("multi", planar5)
    assert by_default.describe().imaginary_arms == "peaks"  # the default: route where covered, else peaks
    assert _made("reach", planar5).describe().planner == "sweeps"


def test_the_run_log_records_the_composition_and_what_was_ignored() -> None:
    doc = {
        "name": "composition",
        "robot": {"source": "planar4", "q0": [1.309, 1.7104, 3.047, 1.8974]},
        "path": {"waypoints": [[0.1, 1.4], [0.3, 1.3]], "duration": 0.2},
        "controller": {"name": "reach", "with_gradient": True, "execution": "pseudoinverse"},
    }
    scenario = scenario_from_dict(doc)
    exact = Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential)
    with pytest.warns(IgnoredSettingWarning):
        result = simulate(scenario, exact_evaluator=exact)
    expected = ("reach (Reach), execution pseudoinverse, planner dp, ignored: with_gradient = True")
    assert result.composition == expected and result.summary()["composition"] == expected
    assert result.execution == "pseudoinverse"
    with pytest.warns(IgnoredSettingWarning):
        qp = simulate(dataclasses.replace(scenario, controller=dataclasses.replace(scenario.controller, name="qp")),
                      exact_evaluator=exact)
    assert qp.composition == "qp (QPBaseline), execution qp, ignored: with_gradient = True; execution = 'pseudoinverse'"
