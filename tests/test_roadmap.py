"""The sampled reachability search of spatial arms (``previewctl.search.roadmap``), the spatial ``oracle`` that
follows it, and the spatial ``horizon`` that replans with it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from helpers import pseudoinverse

from previewctl.control.factory import make_controller
from previewctl.control.laws import Horizon, Reach
from previewctl.control.planner import HORIZON_ROADMAP, PeakPlanner
from previewctl.errors import ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import kinematics
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.search.reachability.goals import Goals
from previewctl.search.roadmap import RoadmapOptions, RoadmapResult, roadmap_over_time
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, load_scenario, scenario_from_dict

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


@pytest.fixture(scope="module")
def crossing() -> Scenario:
    """``panda_crossing`` cut to its first 5 s: plain tracking is hit at 3.65 s."""
    scenario = load_scenario(SCENARIOS / "panda_crossing.toml")
    return dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=5.0))


@pytest.fixture(scope="module")
def found(crossing: Scenario) -> tuple[Evaluator, RoadmapResult]:
    evaluator = Evaluator(crossing.robot, crossing.scene, crossing.index, crossing.potential)
    return evaluator, roadmap_over_time(crossing.robot, evaluator, crossing.path, crossing.q0, 5.0)


def test_the_motion_tracks_the_path_within_the_speed_limits_and_clear_of_the_ball(
        crossing: Scenario, found: tuple[Evaluator, RoadmapResult]) -> None:
    evaluator, result = found
    motion, opts = result.motion, RoadmapOptions()
    assert result.exists and result.reached == result.horizon == 5.0
    assert "a collision-free tracking motion was found to t = 5.00 s" in result.verdict()
    sub = opts.step / (opts.substeps + 1)
    np.testing.assert_allclose(motion.times, np.arange(len(motion.times)) * sub, atol=1e-12)
    assert motion.times[-1] == pytest.approx(5.0)
    np.testing.assert_array_equal(motion.q[0], crossing.q0)
    steps = np.abs(np.diff(motion.q, axis=0))
    assert np.all(steps <= crossing.robot.velocity_limits * opts.speed_share * sub + 1e-9)
    assert np.all(motion.q >= crossing.robot.lower_limits - 1e-12)
    assert np.all(motion.q <= crossing.robot.upper_limits + 1e-12)
    for t, q, S in zip(motion.times[1:], motion.q[1:], motion.S[1:], strict=True):
        check = evaluator(q[None], float(t))
        assert np.linalg.norm(check.tip_position[0] - crossing.path.position(float(t))) < 1e-4
        assert check.min_distance[0] > opts.margin
        assert check.S[0] == pytest.approx(S)
    assert motion.min_S == pytest.approx(motion.S[1:].min())
    assert motion.total_S == pytest.approx(motion.S[1:].sum())


def test_plain_tracking_is_hit_where_the_motion_is_clear(crossing: Scenario,
                                                         found: tuple[Evaluator, RoadmapResult]) -> None:
    """The search is needed: plain tracking by the paper's eq. 19 is hit inside the 5 s the motion passes clear."""
    summary = simulate(pseudoinverse(crossing), "none").summary()
    assert summary["collided"] and summary["collision_time"] < 5.0
    assert found[1].motion.min_S > 0


def test_the_same_seed_gives_the_same_motion_and_another_seed_another(crossing: Scenario) -> None:
    evaluator = Evaluator(crossing.robot, crossing.scene, crossing.index, crossing.potential)
    small = RoadmapOptions(beam=8, children=4)
    runs = [roadmap_over_time(crossing.robot, evaluator, crossing.path, crossing.q0, 1.0, dataclasses.replace(
        small, seed=seed)) for seed in (3, 3, 4)]
    np.testing.assert_array_equal(runs[0].motion.q, runs[1].motion.q)
    assert not np.array_equal(runs[0].motion.q, runs[2].motion.q)


def test_a_ball_on_the_path_ends_every_motion_before_the_hand_reaches_it(panda: Robot) -> None:
    """The hand must pass through a static ball at the path's end: no motion, and the dead end comes before."""
    path = HandPath(np.array([[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]]), 2.0)
    scene = Scene((Obstacle("ball", Sphere(0.08), Static(np.array([0.45, 0.25, 0.35]))),))
    q0 = np.array([-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785])
    result = roadmap_over_time(panda, Evaluator(panda, scene), path, q0, 2.0, RoadmapOptions(beam=8, children=4))
    assert not result.exists
    # the hand is 0.5 m from the ball's centre at t = 0 and reaches 0.08 m at t = 1.68 s
    assert 0.5 <= result.reached < 1.68
    assert result.verdict() == f"no motion found beyond t = {result.reached:.2f} s (the horizon is 2.00 s)"
    assert result.motion.times[-1] == pytest.approx(result.reached)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("step", 0.0, r"step must be > 0, got 0\.0"),
    ("beam", 0, r"beam must be >= 1, got 0"),
    ("children", 2.5, r"children must be an integer, got 2\.5"),
    ("speed_share", 1.5, r"speed_share must lie in \(0, 1\], got 1\.5"),
    ("margin", -0.01, r"margin must be >= 0, got -0\.01"),
])
def test_options_name_the_bad_value(field: str, value: object, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        RoadmapOptions(**{field: value})  # type: ignore[arg-type]


def test_a_bad_duration_is_named(panda: Robot) -> None:
    path = HandPath(np.array([[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]]), 2.0)
    with pytest.raises(ParameterError, match=r"duration must be a finite number > 0 \[s\], got -1\.0"):
        roadmap_over_time(panda, Evaluator(panda), path, panda.neutral(), -1.0)


def test_the_spatial_oracle_follows_its_motion_clear_of_the_ball(crossing: Scenario) -> None:
    summary = simulate(crossing, "oracle").summary()
    assert not summary["collided"] and summary["max_hand_error"] < 1e-3


def test_the_spatial_horizon_replans_with_the_smaller_search(crossing: Scenario) -> None:
    controller = make_controller(crossing, name="horizon")
    assert isinstance(controller.law, Horizon)
    planner = controller.law.planner
    assert planner.kind == "sampled"
    assert planner.timing.window == pytest.approx(3.0) and planner.roadmap == HORIZON_ROADMAP
    summary = simulate(crossing, controller=controller).summary()
    assert not summary["collided"] and summary["max_hand_error"] < 1e-3


def test_a_goal_beyond_the_speed_limits_is_not_reached(crossing: Scenario) -> None:
    """A configuration 2 rad away on every joint cannot be reached in 1 s: no goal, and the motion goes to the end."""
    evaluator = Evaluator(crossing.robot, crossing.scene, crossing.index, crossing.potential)
    far = Goals(1.0, (crossing.q0 + 2.0)[None, :], np.array([1.0]))
    result = roadmap_over_time(crossing.robot, evaluator, crossing.path, crossing.q0, 1.5,
                               RoadmapOptions(beam=8, children=4), goals=[far])
    assert result.exists and result.goal is None
    assert result.motion.times[-1] == pytest.approx(1.5)


@pytest.fixture(scope="module")
def kinova_turn(kinova: Robot) -> Scenario:
    """Kinova Jaco 2 (continuous joints): the hand moves 0.12 m in 2 s where the base joint turns through ±π."""
    start = np.array([np.pi - 0.15, 2.9, 0.85, 1.43, 3.25, 2.59])
    turned = start + np.array([0.3, 0, 0, 0, 0, 0])
    ends = kinematics(kinova, kinova.configurations_from_angles(np.stack([start, turned]))).tip_position.tolist()
    q0 = kinova.configuration_from_angles(start).tolist()
    document = {"name": "kinova_turn", "robot": {"source": "kinova", "q0": q0},
                "path": {"waypoints": ends, "duration": 2.0}, "obstacles": [], "controller": {"name": "oracle"},
                "timing": {"dt": 0.01, "duration": 2.0}, "output": {"gif": False}}
    return scenario_from_dict(document, source="kinova_turn")


def test_an_arm_with_continuous_joints_turns_through_pi(kinova_turn: Scenario) -> None:
    """The moves are taken on the joint angles: the base joint's (cos, sin) pair turns through ±π within the speed
    limits, with the hand on the path, and the oracle follows that motion."""
    robot, opts = kinova_turn.robot, RoadmapOptions(beam=8, children=4)
    evaluator = Evaluator(robot, kinova_turn.scene, kinova_turn.index, kinova_turn.potential)
    result = roadmap_over_time(robot, evaluator, kinova_turn.path, kinova_turn.q0, 2.0, opts)
    assert result.exists
    motion = result.motion
    robot.check_configurations(motion.q)  # every continuous joint a unit (cos, sin) pair
    base = robot.angles_of(motion.q)[:, 0]
    assert base[0] > 2.9 and base[-1] < -2.9  # through ±π, not back round the circle
    sub = opts.step / (opts.substeps + 1)
    steps = np.array([pin.difference(robot.model, a, b) for a, b in zip(motion.q[:-1], motion.q[1:], strict=True)])
    assert np.all(np.abs(steps) <= robot.velocity_limits * opts.speed_share * sub + 1e-9)
    hands = kinematics(robot, motion.q).tip_position
    for t, hand in zip(motion.times, hands, strict=True):
        assert np.linalg.norm(hand - kinova_turn.path.position(float(t))) < 1e-4
    summary = simulate(kinova_turn, "oracle").summary()
    assert not summary["collided"] and summary["max_hand_error"] < 1e-3


def test_coherent_reach_plans_with_the_search_on_an_arm_with_continuous_joints(kinova_turn: Scenario) -> None:
    law = make_controller(kinova_turn, name="reach").law
    assert isinstance(law, Reach) and isinstance(law.route, PeakPlanner)
    assert law.route.planner.kind == "sampled" and law.route.planner.roadmap == HORIZON_ROADMAP
