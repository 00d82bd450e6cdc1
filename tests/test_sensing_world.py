"""The observed world (previewctl.sensing.world) and its tracks: validation, adding, dropping, late observations, and
the margin the distance computations add."""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest

import previewctl as pc
from previewctl.errors import ObservationError, UnknownNameError
from previewctl.index.evaluator import Evaluator, Method
from previewctl.robot.model import Robot
from previewctl.scene.clearance import Clearance
from previewctl.sensing.track import Track
from previewctl.sensing.world import World

BALL = pc.Sphere(0.1)


def world(**sensing: object) -> World:
    """A scene with a static wall and a moving ball; the ball is observed."""
    scene = pc.Scene((pc.Obstacle("wall", pc.Box((0.1, 1.0, 0.4)), pc.Static([2.0, 0.0])),
                      pc.Obstacle("ball", BALL, pc.ConstantVelocity([1.0, 0.6], [0.1, 0.0]))))
    return World(scene, pc.Sensing(**sensing))  # type: ignore[arg-type]


def test_moving_obstacles_are_observed_and_enter_the_scene_when_first_observed() -> None:
    w = world()
    assert w.scene.names == ("wall",)
    w.observe("ball", [1.0, 0.6], 0.0)  # the scenario knows its shape
    assert w.scene.names == ("wall",)  # until the next step
    changes = w.advance(0.01)
    assert changes.added == ("ball",) and changes.changed and w.scene.names == ("wall", "ball")
    ball = w.scene.obstacles[1]
    assert isinstance(ball.motion, Track) and ball.shape == BALL
    np.testing.assert_allclose(ball.motion.positions([0.0]), [[1.0, 0.6, 0.0]])
    assert w.advance(0.02) == type(changes)()  # nothing new


def test_a_new_name_needs_a_shape_and_is_added_with_it() -> None:
    w = world()
    with pytest.raises(ObservationError, match=r"'crate' is observed for the first time at t = 0\.5 s without a shape"):
        w.observe("crate", [0.5, 0.5, 0.0], 0.5)
    w.observe("crate", [0.5, 0.5, 0.0], 0.5, shape=pc.Box((0.2, 0.2, 0.2)))
    assert w.advance(0.6).added == ("crate",)
    w.forget("crate")
    w.observe("crate", [0.5, 0.5, 0.0], 0.7)  # seen before: its shape is remembered
    assert w.advance(0.7).added == ("crate",)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"position": [np.nan, 0.0]}, "position of 'ball' must be finite"),
    ({"position": [1.0, 2.0, 3.0, 4.0]},
     r"position of 'ball' must have 2 or 3 entries, got shape \(4,\): \[1\., 2\., 3\., 4\.\]"),
    ({"position": "here"}, "position of 'ball' must be an array of real numbers, got 'here'"),
    ({"t": np.inf}, "t must be finite, got inf"),
    ({"t": "now"}, "t must be a real number, got 'now'"),
    ({"velocity": [0.1, np.nan, 0.0]}, "velocity of 'ball' must be finite"),
    ({"rotation": np.eye(3) * 2}, r"rotation of 'ball' must be a rotation matrix"),
    ({"shape": "sphere"}, "shape of 'ball' must be one of Sphere, Box, .*, got str 'sphere'"),
    ({"name": "wall"}, "obstacle 'wall' is known from the scene and not observed; observed: ball"),
    ({"name": ""}, "an observation needs an obstacle name"),
    ({"t": -2.0}, "observation of 'ball' at t = -2 s is 3 s before its last one at t = 1 s, more than the "
                  "timeout 1 s: did the clock go back"),
])
def test_every_bad_observation_is_a_typed_error_naming_the_value_and_changes_nothing(
        kwargs: dict[str, object], message: str) -> None:
    w = world()
    w.observe("ball", [1.0, 0.6], 1.0)
    w.advance(1.0)
    track = w.scene.obstacles[1].motion
    assert isinstance(track, Track)
    ahead = np.array([1.0, 1.5])
    before = (track.revision, track.last, track.positions(ahead), track.margin(ahead))
    call = {"name": "ball", "position": [1.1, 0.6], "t": 1.1, **kwargs}
    with pytest.raises(ObservationError, match=message):
        w.observe(call.pop("name"), call.pop("position"), call.pop("t"), **call)  # type: ignore[arg-type]
    assert (track.revision, track.last) == before[:2]
    np.testing.assert_array_equal(track.positions(ahead), before[2])
    np.testing.assert_array_equal(track.margin(ahead), before[3])
    assert w.advance(1.1) == type(w.advance(1.1))(late=0)


def test_late_observations_are_ignored_and_counted() -> None:
    w = world()
    w.observe("ball", [1.0, 0.6], 1.0)
    w.observe("ball", [9.0, 9.0], 0.9)  # older than the last: late
    w.observe("ball", [9.0, 9.0], 0.5)
    changes = w.advance(1.0)
    assert changes.late == 2
    track = w.scene.obstacles[1].motion
    assert isinstance(track, Track) and track.last == 1.0 and track.revision == 1
    np.testing.assert_allclose(track.positions([1.0]), [[1.0, 0.6, 0.0]])
    w.observe("ball", [1.0, 0.6], 1.0)  # as old as the last one: taken
    assert w.advance(1.0).late == 2 and track.revision == 2


def test_an_obstacle_not_observed_for_longer_than_the_timeout_is_dropped_at_the_step() -> None:
    w = world(timeout=0.5)
    w.observe("ball", [1.0, 0.6], 0.0)
    assert w.advance(0.5).added == ("ball",)  # 0.5 s old: not longer than the timeout
    changes = w.advance(0.51)
    assert changes.dropped == ("ball",) and changes.changed and w.scene.names == ("wall",)


def test_forget_and_forget_all() -> None:
    w = world()
    with pytest.raises(UnknownNameError, match=r"unknown observed obstacle 'ball'; valid: $"):
        w.forget("ball")
    w.observe("ball", [1.0, 0.6], 0.0)
    w.observe("crate", [0.5, 0.5], 0.0, shape=BALL)
    w.forget("ball")
    assert w.observed == ("crate",)
    w.forget_all()
    changes = w.advance(0.1)
    assert changes.added == ("ball", "crate") and changes.dropped == ("ball", "crate") and w.observed == ()


def test_names_must_be_obstacles_of_the_scene() -> None:
    with pytest.raises(UnknownNameError, match=re.escape("unknown observed obstacle (Sensing.names) 'bal'; valid: "
                                                         "wall, ball")):
        world(names=("bal",))
    w = world(names=("wall",))  # a static obstacle may be observed when named
    assert w.scene.names == ("ball",)


def test_sensing_refuses_an_unknown_predictor() -> None:
    with pytest.raises(UnknownNameError, match="unknown predictor 'kalmann'; valid: kalman, imm, stationary"):
        pc.Sensing(predictor="kalmann")
    with pytest.raises(pc.ParameterError, match="predictor must be one of kalman, imm, stationary or a Predictor"):
        pc.Sensing(predictor=3)
    with pytest.raises(pc.ParameterError, match="timeout"):
        pc.Sensing(timeout=0.0)


def test_the_margin_is_the_capped_uncertainty() -> None:
    track = Track(pc.ConstantVelocityKalman(q=0.05, r=0.01), confidence=2.0, cap=0.1)
    track.update(0.0, np.zeros(3))
    times = np.array([0.0, 0.5, 5.0])
    np.testing.assert_allclose(track.margin(times), np.minimum(0.1, 2.0 * track.predictor.sigma(times)))
    assert track.margin(times)[0] == pytest.approx(0.02) and track.margin(times)[-1] == 0.1


def inflated(robot: Robot, margin_cap: float) -> tuple[pc.Scene, pc.Scene]:
    """An observed ball (its margin the cap: k = 1e6) and the same ball with the cap added to its radius."""
    track = Track(pc.Stationary(q=0.0, r=0.01), confidence=1e6, cap=margin_cap)
    track.update(0.0, np.array([1.0, 0.6, 0.0]))
    observed = pc.Scene((pc.Obstacle("ball", pc.Sphere(0.1), track),))
    grown = pc.Scene((pc.Obstacle("ball", pc.Sphere(0.1 + margin_cap), pc.Static([1.0, 0.6, 0.0])),))
    return observed, grown


def test_distances_to_an_observed_obstacle_are_those_to_it_inflated_by_its_margin(planar4: Robot) -> None:
    """A sphere inflated by m is a sphere of radius + m: pair distances, screened distances, witnesses and the
    planar evaluator's distances all match that sphere's."""
    observed, grown = inflated(planar4, 0.07)
    rng = np.random.default_rng(2)
    Q = rng.uniform(-np.pi, np.pi, (40, planar4.nq))
    a, b = Clearance(planar4, observed), Clearance(planar4, grown)
    data = planar4.model.createData()
    for q in Q[:5]:
        pin.framesForwardKinematics(planar4.model, data, q)
        np.testing.assert_allclose(a.pair_distances(data), b.pair_distances(data), atol=1e-9)
        (near_a, wa), (near_b, wb) = a.witnesses(data, 0.3), b.witnesses(data, 0.3)
        np.testing.assert_array_equal(near_a, near_b)
        np.testing.assert_allclose(wa.obstacle_point, wb.obstacle_point, atol=1e-6)
    general = [Evaluator(planar4, s, method="general") for s in (observed, grown)]
    np.testing.assert_allclose(general[0](Q, 0.3).link_distances, general[1](Q, 0.3).link_distances, atol=1e-9)
    np.testing.assert_allclose(general[0](Q, 0.3, exact_below=0.05).link_distances,
                               general[1](Q, 0.3, exact_below=0.05).link_distances, atol=1e-9)
    planar = [Evaluator(planar4, s, method="planar") for s in (observed, grown)]
    np.testing.assert_allclose(planar[0](Q, 0.3).link_distances, planar[1](Q, 0.3).link_distances, atol=1e-9)


@pytest.mark.parametrize("method", ["general", "planar"])
def test_without_margins_an_observed_obstacle_counts_at_its_predicted_size(planar4: Robot, method: Method) -> None:
    """Inside ``without_margins`` the distances are those to the bare ball, outside (and after an error inside) those
    to the inflated one; a scene with no prediction has nothing to drop."""
    observed, grown = inflated(planar4, 0.07)
    bare = pc.Scene((pc.Obstacle("ball", pc.Sphere(0.1), pc.Static([1.0, 0.6, 0.0])),))
    Q = np.random.default_rng(3).uniform(-np.pi, np.pi, (20, planar4.nq))
    evaluator, to_bare, to_grown = (Evaluator(planar4, s, method=method) for s in (observed, bare, grown))
    assert evaluator.predicts and not to_bare.predicts
    with evaluator.without_margins():
        np.testing.assert_allclose(evaluator(Q, 0.3).link_distances, to_bare(Q, 0.3).link_distances, atol=1e-9)
    np.testing.assert_allclose(evaluator(Q, 0.3).link_distances, to_grown(Q, 0.3).link_distances, atol=1e-9)
    with pytest.raises(RuntimeError), evaluator.without_margins():
        raise RuntimeError("a search failed")
    np.testing.assert_allclose(evaluator(Q, 0.3).link_distances, to_grown(Q, 0.3).link_distances, atol=1e-9)


def test_a_new_observation_moves_the_obstacle_at_the_same_time(planar4: Robot) -> None:
    """The clearance reads a track again after an observation, even at a time it was already placed for."""
    track = Track(pc.Stationary(q=0.0, r=0.01), confidence=0.0, cap=0.0)
    track.update(0.0, np.array([1.0, 0.6, 0.0]))
    evaluator = Evaluator(planar4, pc.Scene((pc.Obstacle("ball", BALL, track),)), method="general")
    q = np.array([0.6, 1.0, -1.2, -1.0])
    before = evaluator(q, 1.0).min_distance[0]
    track.update(1.0, np.array([3.0, 3.0, 0.0]))  # with q = 0: the mean of the two
    after = evaluator(q, 1.0).min_distance[0]
    moved = Evaluator(planar4, pc.Scene((pc.Obstacle("ball", BALL, pc.Static([2.0, 1.8])),)), method="general")
    assert after != before and after == pytest.approx(moved(q, 1.0).min_distance[0])


def test_around_a_spatial_arm_a_2d_observation_is_refused() -> None:
    w = World(pc.Scene(), pc.Sensing(), spatial="panda")
    with pytest.raises(ObservationError, match=r"position of 'ball' \[0\.5, 0\.2\] is 2-D, but robot 'panda' is "
                                               r"spatial: give \[x, y, z\]"):
        w.observe("ball", [0.5, 0.2], 0.0, shape=BALL)
    w.observe("ball", [0.5, 0.2, 0.3], 0.0, shape=BALL)
    assert w.advance(0.0).added == ("ball",)
