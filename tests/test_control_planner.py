"""The window planner's measured latency (each plan arrives after its own compute time, in whole control periods),
and its plans around predicted obstacles."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np
import pytest
from helpers import planar_doc

from previewctl.control.base import ControlState
from previewctl.control.factory import make_controller
from previewctl.control.laws import Horizon
from previewctl.control.params import ControllerParams
from previewctl.control.planner import PlanTiming, WindowPlanner
from previewctl.errors import ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import integrate, kinematics
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.sensing.predictors import Stationary
from previewctl.sensing.track import Track
from previewctl.sim.paper import shipped_scenarios_dir
from previewctl.sim.scenario import Scenario, load_scenario, scenario_from_dict

DT = 0.04
"""[s] a control period that 0.1 s is not a multiple of (2.5 periods: the plan must wait 3)."""


class StandInClock:
    """A CPU clock the test sets: each plan reads it before and after, and spends the next cost of ``costs``."""

    def __init__(self, costs: list[float]) -> None:
        self._readings: Iterator[float] = iter([x for cost in costs for x in (0.0, cost)])

    def __call__(self) -> float:
        return next(self._readings)


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return load_scenario(shipped_scenarios_dir() / "paper_fitted.toml")


def _planner(scenario: Scenario, costs: list[float]) -> WindowPlanner:
    evaluator = Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential)
    timing = PlanTiming(replan_period=0.5, window=1.0, latency="measured")
    return WindowPlanner(scenario.robot, evaluator, timing, clock=StandInClock(costs))


def _state(scenario: Scenario, t: float) -> ControlState:
    q = np.array(scenario.q0, dtype=float)
    return ControlState(q, t, kinematics(scenario.robot, q[None]), scenario.path, DT, frame_due=True)


def _followed_from(planner: WindowPlanner) -> float:
    assert planner.motion is not None
    return float(planner.motion.times[0])


def test_a_plan_takes_effect_after_its_measured_cost_rounded_up_to_whole_periods(scenario: Scenario) -> None:
    """The first plan is followed at once; the one made at t0 = 0.52 s in 0.1 s of CPU from t0 + 3 dt = 0.64 s on
    (not at t0 + 0.1 s), the first one until then."""
    planner = _planner(scenario, [0.3, 0.1])
    planner.plan(_state(scenario, 0.0))
    assert _followed_from(planner) == 0.0
    t0 = 13 * DT
    assert planner.due(t0)
    planner.plan(_state(scenario, t0))
    arrival = t0 + math.ceil(0.1 / DT) * DT
    for t in t0 + np.arange(0.0, 0.2, 0.005):  # finer than dt: the plan must wait until the whole period
        planner.arrive(t)
        assert _followed_from(planner) == pytest.approx(t0 if t >= arrival - 1e-9 else 0.0), t
    assert planner.costs == [0.3, 0.1]


def test_a_plan_longer_than_the_replan_period_delays_the_next(scenario: Scenario) -> None:
    """One plan at a time: a plan made at 0.52 s costing 0.7 s (18 periods) arrives at 1.24 s, and the next is due
    only then, not at 0.52 + 0.5 s."""
    planner = _planner(scenario, [0.01, 0.7])
    planner.plan(_state(scenario, 0.0))
    t0 = 13 * DT
    planner.plan(_state(scenario, t0))
    arrival = t0 + 18 * DT
    assert not planner.due(t0 + 0.5) and not planner.due(arrival - DT)
    assert planner.due(arrival)
    planner.arrive(arrival - DT)
    assert _followed_from(planner) == 0.0
    planner.arrive(arrival)
    assert _followed_from(planner) == pytest.approx(t0)


def test_a_fixed_latency_is_unchanged_by_the_plans_cost(scenario: Scenario) -> None:
    """A number stays a fixed delay, whatever the plan cost: 0.2 s after a plan that took 0.1 s."""
    planner = _planner(scenario, [0.0, 0.1])
    planner.timing = dataclasses.replace(planner.timing, latency=0.2)
    planner.plan(_state(scenario, 0.0))
    planner.plan(_state(scenario, 0.5))
    planner.arrive(0.68)
    assert _followed_from(planner) == 0.0
    planner.arrive(0.7)
    assert _followed_from(planner) == pytest.approx(0.5)


@pytest.mark.parametrize(("value", "message"), [
    ("measure", r"^plan_latency must be a finite number or one of measured, got 'measure'$"),
    (-0.1, r"^plan_latency must be a time >= 0 \[s\] or 'measured', got -0\.1$"),
    (True, r"^plan_latency must be a finite number or one of measured, got True$"),
])
def test_the_plan_latency_names_the_bad_value_and_the_valid_ones(value: object, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        ControllerParams(plan_latency=value)  # type: ignore[arg-type]


def test_the_plan_latency_takes_a_time_or_measured() -> None:
    assert ControllerParams(plan_latency="measured").plan_latency == "measured"
    assert ControllerParams(plan_latency=0.25).plan_latency == 0.25


def test_a_controller_with_a_measured_latency_follows_each_plan_from_its_arrival() -> None:
    """A real ``horizon`` run (real CPU times): at every cycle the plan followed is the last one whose made time plus
    its recorded cost, rounded up to whole periods, has passed; the plan made meanwhile is not followed yet."""
    scenario = scenario_from_dict(planar_doc(controller={"name": "horizon", "plan_latency": "measured",
                                                         "preview_time": 0.4}))
    ctrl = make_controller(scenario)
    assert isinstance(ctrl.law, Horizon)
    planner = ctrl.law.planner
    q, dt, made = np.array(scenario.q0, dtype=float), 0.01, []
    for k in range(121):
        t = k * dt
        qdot = ctrl.step(q, t, dt)
        assert planner.planned is not None and planner.motion is not None
        if not made or made[-1] != float(planner.planned.times[0]):
            made.append(float(planner.planned.times[0]))
        arrivals = [made[0]] + [m + math.ceil(c / dt - 1e-9) * dt
                                for m, c in zip(made[1:], planner.costs[1:], strict=True)]
        expected = max(m for m, a in zip(made, arrivals, strict=True) if a <= t + 1e-9)
        assert float(planner.motion.times[0]) == pytest.approx(expected), t
        q = integrate(scenario.robot, q, qdot, dt)
    assert len(planner.costs) == len(made) >= 3 and all(c > 0 for c in planner.costs)


def test_a_plan_with_too_little_path_left_for_one_grid_step_holds_instead_of_failing(scenario: Scenario) -> None:
    """5 ms before the path's end no joint can move one 4° cell: the DP is not asked (it refuses such a step with a
    ConfigurationError, which a replan there raised: one made on arrival of a plan with a measured latency can fall
    anywhere), and the plan holds the arm (one sample, no step)."""
    planner = _planner(scenario, [0.01] * 2)
    end = scenario.path.end_time
    held = planner.plan(_state(scenario, end - 0.005))
    assert held.times.tolist() == [end - 0.005] and np.isnan(held.min_S)


def _planner_around_an_observed_ball(cap: float) -> tuple[WindowPlanner, ControlState]:
    """A 1 s window on planar4 by a stationary ball observed at rest, inflated by ``cap`` [m] (its margin: k = 1e6);
    the state at t = 0."""
    scenario = scenario_from_dict({"name": "margins", "robot": {"source": "planar4", "q0": [0.6, 1.0, -1.2, -1.0]},
                                   "path": {"waypoints": [[1.9069, 1.0417], [1.6069, 0.6417]], "duration": 5.0}})
    track = Track(Stationary(q=0.0, r=0.01), confidence=1e6, cap=cap)
    track.update(0.0, np.array([1.0, 0.8, 0.0]))
    evaluator = Evaluator(scenario.robot, Scene((Obstacle("ball", Sphere(0.15), track),)), scenario.index,
                          scenario.potential)
    planner = WindowPlanner(scenario.robot, evaluator, PlanTiming(replan_period=0.5, window=1.0))
    q = np.array(scenario.q0, dtype=float)
    return planner, ControlState(q, 0.0, kinematics(scenario.robot, q[None]), scenario.path, DT, frame_due=True)


def test_a_window_the_margins_close_is_planned_with_the_obstacle_at_its_predicted_size() -> None:
    """With a 0.2 m margin the ball reaches within 12 mm of the arm and no motion gets through the window: the plan
    is then the one made without the margin (the same bits as with no margin at all), and it is counted; with a
    0.05 m margin a motion gets through, and that plan (another one) is kept. The margins are back afterwards."""
    bare, state = _planner_around_an_observed_ball(0.0)
    closed, _ = _planner_around_an_observed_ball(0.2)
    open_, _ = _planner_around_an_observed_ball(0.05)
    plans = {name: planner.plan(state) for name, planner in (("bare", bare), ("closed", closed), ("open", open_))}
    assert (bare.plans_without_margins, closed.plans_without_margins, open_.plans_without_margins) == (0, 1, 0)
    np.testing.assert_array_equal(plans["closed"].q, plans["bare"].q)
    assert plans["closed"].min_S == plans["bare"].min_S
    assert closed.planned is not None and closed.planned.exists
    assert plans["open"].min_S != plans["bare"].min_S  # the margin counted: another route
    distance = closed.evaluator(state.q, 0.0).min_distance[0]
    assert distance == pytest.approx(bare.evaluator(state.q, 0.0).min_distance[0] - 0.2)
