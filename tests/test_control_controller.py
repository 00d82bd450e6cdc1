"""Tests of :mod:`previewctl.control.controller` and :func:`previewctl.make_controller`: a loop the user owns."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

import previewctl as pc
from previewctl.control.controller import frame_index
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.sim.scenario import Scenario

Array = NDArray[np.float64]
Q0 = [0.6, 1.0, -1.2, -1.0]  # [rad]; the hand at START
START, END = [1.9069, 1.0417], [1.6069, 0.6417]  # [m]
FRAME = 0.033  # [s]


def planar_scenario(controller: str = "multi", duration: float = 1.0) -> Scenario:
    """planar4 along a 0.5 m line, a ball 7 cm from link 2: the null-space input has work to do."""
    return pc.scenario_from_dict({
        "name": "loop_test",
        "robot": {"source": "planar4", "q0": Q0},
        "path": {"waypoints": [START, END], "duration": 5.0},
        "obstacles": [{"name": "ball", "shape": "sphere", "radius": 0.15, "position": [1.0, 0.6]}],
        "controller": {"name": controller},
        "timing": {"duration": duration},
    })


@dataclass(frozen=True)
class Best:
    q: Array
    S: float


class CountingSearch:
    """A stand-in for the 1-step GA: returns a fixed configuration and counts its generations."""

    def __init__(self, q: Array) -> None:
        self.best = Best(np.array(q, dtype=float), 1.0)
        self.times: list[float] = []

    def step(self, target: Array, t: float) -> Best:
        self.times.append(t)
        return self.best

    def peaks(self) -> tuple[Best, ...]:
        return (self.best,)

    def seed(self, q: Array) -> None:
        pass


def counting_controller(robot: Robot, mode: str = "single") -> tuple[pc.Controller, CountingSearch]:
    search = CountingSearch(np.array(Q0))
    path = pc.HandPath([START, END], 5.0)
    ctrl = pc.make_controller(mode, robot=robot, path=path, search_factory=lambda i, rng: search)
    return ctrl, search


# ---------------------------------------------------------------------------- same numbers as the simulator


@pytest.mark.parametrize("mode", ["gradient", "multi"])
def test_step_gives_what_the_simulator_applies(mode: str) -> None:
    scenario = planar_scenario(mode)
    run = pc.simulate(scenario, exact_evaluator=Evaluator(scenario.robot, scenario.scene))
    ctrl = pc.make_controller(scenario)
    assert np.abs(run.qdot).max() > 0.01 and run.frame_due.sum() == 31  # moving, one frame per 33 ms
    for k in range(run.steps):
        qdot = ctrl.step(run.q[k], run.t[k], scenario.timing.dt)
        np.testing.assert_array_equal(qdot, run.qdot[k])
        assert ctrl.last_info.frame_due == run.frame_due[k]
        assert ctrl.last_info.hand_error == pytest.approx(run.hand_error[k], abs=1e-15)


@pytest.mark.parametrize("mode", ["qp", "multi"])
def test_a_rehearsal_changes_nothing(mode: str) -> None:
    scenario = planar_scenario(mode)
    run = pc.simulate(scenario, exact_evaluator=Evaluator(scenario.robot, scenario.scene))
    ctrl = pc.make_controller(scenario)
    ctrl.rehearse()  # before the first step: nothing to rehearse
    dampers = 0
    for k in range(run.steps):
        qdot = ctrl.step(run.q[k], run.t[k], scenario.timing.dt)
        np.testing.assert_array_equal(qdot, run.qdot[k])
        assert ctrl.last_info.hand_error == pytest.approx(run.hand_error[k], abs=1e-15)
        info = ctrl.last_info
        ctrl.rehearse()
        ctrl.rehearse()
        assert ctrl.last_info is info  # what the cycle reported stays
        dampers += info.executed.dampers
    assert dampers > 0  # the rehearsals ran the QP's damper rows too


def test_step_without_dt_uses_the_time_elapsed() -> None:
    ctrl = pc.make_controller(planar_scenario("none"))
    q = np.array(Q0)
    ctrl.step(q, 0.0)
    assert ctrl.last_info.executed.dt == ctrl.dt == 0.01  # the first call: the scenario's control period
    ctrl.step(q, 0.004)
    assert ctrl.last_info.executed.dt == pytest.approx(0.004)
    ctrl.step(q, 0.004)  # t did not advance: the nominal period again
    assert ctrl.last_info.executed.dt == 0.01
    ctrl.step(q, 0.5, dt=0.002)
    assert ctrl.last_info.executed.dt == 0.002


# ---------------------------------------------------------------------------------------- camera frames


def test_a_frame_is_due_exactly_when_floor_t_over_frame_changes(planar4: Robot) -> None:
    ctrl, search = counting_controller(planar4)
    # uneven steps, a repeated time, a jump over frames, and a step back at the end
    times = [0.0, 0.01, 0.02, 0.032, 0.033, 0.05, 0.0659, 0.066, 0.07, 0.3, 0.3, 0.31, 1.0, 0.95]
    due = []
    for t in times:
        predicted = ctrl.frame_due(t)
        ctrl.step(np.array(Q0), t)
        assert ctrl.last_info.frame_due == predicted
        due.append(ctrl.last_info.frame_due)
    frames = [math.floor(t / FRAME + 1e-9) for t in times]
    assert due == [k == 0 or frames[k] != frames[k - 1] for k in range(len(times))]
    assert due == [True, False, False, False, True, False, False, True, False, True, False, False, True, True]
    # one generation per due frame, for the preview time t + t~
    assert search.times == pytest.approx([t + 1.0 for t, d in zip(times, due, strict=True) if d])


@pytest.mark.parametrize("dt", [0.004, 0.05])
def test_any_loop_rate_tracks_the_path_with_one_generation_per_frame(dt: float) -> None:
    scenario = planar_scenario("multi")
    robot = scenario.robot
    ctrl = pc.make_controller(scenario)
    q, worst, generations = np.array(scenario.q0), 0.0, 0
    times = np.arange(0.0, 1.0 + 1e-9, dt)
    for t in times:
        qdot = ctrl.step(q, t)
        q = pc.integrate(robot, q, qdot, dt)
        worst, generations = max(worst, ctrl.last_info.hand_error), generations + ctrl.last_info.frame_due
    assert worst < max(1e-3, 0.1 * dt)  # the hand moves 0.1 m/s: 5 mm per step at 20 Hz
    assert generations == len({frame_index(t, FRAME) for t in times})
    assert generations == (len(times) if dt > FRAME else 31)  # 0.000 .. 0.990 s: frames 0 .. 30


# -------------------------------------------------------------------------------------------- seeding


def test_seeds_reproduce_and_a_generator_is_used_as_given() -> None:
    scenario = planar_scenario("single")

    def run(**kwargs: Any) -> Array:
        ctrl, q = pc.make_controller(scenario, **kwargs), np.array(Q0)
        return np.array([ctrl.step(q, k * 0.033) for k in range(5)])

    default = run()
    np.testing.assert_array_equal(default, run(seed=scenario.seed))
    np.testing.assert_array_equal(run(seed=7), run(seed=np.random.default_rng(7)))
    assert not np.array_equal(run(seed=7), default)


# ------------------------------------------------------------------------------------------ the factory


def test_make_controller_from_a_scenario_takes_overrides() -> None:
    scenario = planar_scenario("multi")
    ctrl = pc.make_controller(scenario)
    assert ctrl.name == "multi" and ctrl.params is scenario.controller.params
    assert (ctrl.frame, ctrl.dt) == (scenario.timing.frame, scenario.timing.dt)
    other = pc.make_controller(scenario, name="gradient", params=pc.ControllerParams(feedback_gain=2.0), frame=0.05)
    assert other.name == "gradient" and other.params.feedback_gain == 2.0 and other.frame == 0.05
    assert "gradient" in repr(other)


def test_step_does_not_modify_q_and_accepts_a_list(planar4: Robot) -> None:
    ctrl, _ = counting_controller(planar4, "none")
    q = np.array(Q0)
    np.testing.assert_array_equal(ctrl.step(q, 0.0), ctrl.step(list(Q0), 0.0))
    np.testing.assert_array_equal(q, Q0)


# ------------------------------------------------------------------------------------------ bad inputs


def test_bad_configurations_are_configuration_errors_naming_the_value(planar4: Robot) -> None:
    ctrl, _ = counting_controller(planar4)
    with pytest.raises(pc.ConfigurationError, match=r"q has shape \(3,\); robot 'planar4' needs \(4,\)"):
        ctrl.step(np.zeros(3), 0.0)
    with pytest.raises(pc.ConfigurationError, match=r"q\[0, 2\] = nan \(joint 'joint3'\) is not finite"):
        ctrl.step(np.array([0.1, 0.2, np.nan, 0.3]), 0.0)
    with pytest.raises(pc.ConfigurationError, match=r"one configuration \(4,\).*\(2, 4\)"):
        ctrl.step(np.zeros((2, 4)), 0.0)
    with pytest.raises(pc.PreviewctlError, match="no control cycle yet"):
        _ = ctrl.last_info


@pytest.mark.parametrize(
    ("t", "dt", "message"),
    [(math.nan, None, "t must be finite, got nan"), ("0.1", None, "t must be a real number, got '0.1'"),
     (0.0, 0.0, r"dt must be a time > 0 \[s\], got 0.0"), (0.0, -1.0, "dt must be a time > 0")],
)
def test_bad_times_are_parameter_errors(planar4: Robot, t: Any, dt: Any, message: str) -> None:
    ctrl, _ = counting_controller(planar4)
    with pytest.raises(pc.ParameterError, match=message):
        ctrl.step(np.array(Q0), t, dt)


def test_make_controller_rejects_bad_arguments_with_the_choices(planar4: Robot) -> None:
    path = pc.HandPath([START, END], 5.0)
    with pytest.raises(pc.UnknownNameError, match="unknown controller 'mutli'; valid: none, qp, gradient"):
        pc.make_controller("mutli", robot=planar4, path=path)
    with pytest.raises(pc.UnknownNameError, match="unknown controller 'fancy'"):
        pc.make_controller(planar_scenario(), name="fancy")
    with pytest.raises(pc.ParameterError, match=r"make_controller\('multi'\) needs path="):
        pc.make_controller("multi", robot=planar4)
    with pytest.raises(pc.ParameterError, match=r"a scenario or a controller name .*got 3"):
        pc.make_controller(3, robot=planar4, path=path)  # type: ignore[arg-type]
    with pytest.raises(pc.ParameterError, match=r"seed must be an int >= 0 or a numpy\.random\.Generator, got -1"):
        pc.make_controller("multi", robot=planar4, path=path, seed=-1)
    with pytest.raises(pc.ParameterError, match="frame must be a time > 0"):
        pc.make_controller("none", robot=planar4, path=path, frame=0.0)
    with pytest.raises(pc.ParameterError, match="given twice"):
        pc.make_controller("none", name="multi", robot=planar4, path=path)
