"""A controller fed observations (Controller.observe, issue 33): it never reads the true motion, reports what comes
and goes in last_info, rebuilds its parts on a new scene, and plans around observed obstacles in the background."""

from __future__ import annotations

import multiprocessing
import time
from typing import Any

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

import previewctl as pc
from previewctl.control.background import ObservedSide, PlanningSide
from previewctl.control.factory import _side_on
from previewctl.errors import ObservationError, UnknownNameError
from previewctl.index.evaluator import Evaluator
from previewctl.sensing.track import Track

Q0 = [0.6, 1.0, -1.2, -1.0]  # [rad]; the hand at START
START, END = [1.9069, 1.0417], [1.6069, 0.6417]  # [m]
DT = 0.004  # [s]
WAIT = 180.0  # [s] of wall time the worker may take to start and answer on a loaded host


class Forbidden:
    """A motion that raises if anything reads it: the controller must predict from the observations alone."""

    def placement(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        raise AssertionError(f"the true motion was read at t = {t}")

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        raise AssertionError(f"the true motion was read at times {times}")


def truth(t: float) -> np.ndarray:
    """Where the ball really is at ``t`` [s]: moving down past link 2."""
    return np.array([1.0, 0.8 - 0.05 * t])


def scenario(controller: str = "multi", motion: object = None, **sensing: Any) -> pc.Scenario:
    """planar4 along a 0.5 m line, a ball near link 2 whose motion is ``motion`` (default: forbidden to read)."""
    base = pc.scenario_from_dict({
        "name": "sensing_test",
        "robot": {"source": "planar4", "q0": Q0},
        "path": {"waypoints": [START, END], "duration": 5.0},
        "controller": {"name": controller},
        "timing": {"duration": 1.0},
        "sensing": sensing,
    })
    ball = pc.Obstacle("ball", pc.Sphere(0.15), motion if motion is not None else Forbidden())  # type: ignore[arg-type]
    return pc.Scenario(**{**base.__dict__, "scene": pc.Scene((ball,))})


@pytest.mark.parametrize("name", ["qp", "multi", "reach", "horizon"])
def test_a_controller_fed_observations_never_reads_the_true_motion(name: str) -> None:
    """The QP dampers, the imaginary arms' searches and the DP planner all predict the ball from its observations."""
    s = scenario(name)
    ctrl = pc.make_controller(s)
    q = np.array(s.q0)
    for k in range(40):
        t = k * DT
        if k % 8 == 0:
            ctrl.observe("ball", truth(t), t, shape=pc.Sphere(0.15))
        q = pc.integrate(s.robot, q, ctrl.step(q, t, DT), DT)
        assert ctrl.last_info.obstacles_added == (("ball",) if k == 0 else ())
    assert ctrl.last_info.hand_error < 1e-3
    assert ctrl.observed is not None and ctrl.observed.world.observed == ("ball",)


def test_the_scenario_sensing_table_and_its_errors() -> None:
    s = scenario("qp", timeout=0.5, predictor="stationary", confidence=1.0)
    assert s.sensing == pc.Sensing(predictor="stationary", timeout=0.5, confidence=1.0)
    with pytest.raises(pc.ScenarioError, match=r"sensing\.timeout must be > 0, got -1"):
        scenario("qp", timeout=-1.0)
    with pytest.raises(pc.ScenarioError, match=r"sensing\.predictor"):
        scenario("qp", predictor="kalmann")


def test_obstacles_that_come_and_go_show_in_last_info() -> None:
    s = scenario("qp", timeout=0.1)
    ctrl = pc.make_controller(s)
    q = np.array(s.q0)
    ctrl.step(q, 0.0)
    law = ctrl.law
    info = ctrl.last_info
    assert (info.obstacles_added, info.obstacles_dropped, info.late_observations) == ((), (), 0)
    ctrl.observe("ball", truth(0.0), 0.0)  # the scenario knows its shape
    ctrl.observe("crate", [0.3, 0.9], 0.0, shape=pc.Box((0.1, 0.1, 0.4)))
    ctrl.step(q, 0.01)
    assert ctrl.last_info.obstacles_added == ("ball", "crate") and ctrl.law is not law  # rebuilt on the new scene
    assert ctrl.execution.scene.names == ("ball", "crate")  # type: ignore[attr-defined]
    law = ctrl.law
    ctrl.observe("ball", truth(0.05), 0.05)
    ctrl.observe("ball", truth(0.02), 0.02)  # late
    ctrl.step(q, 0.06)
    assert ctrl.last_info.late_observations == 1 and ctrl.last_info.obstacles_added == () and ctrl.law is law
    ctrl.step(q, 0.12)  # the crate, last seen at 0 s, is 0.12 s old: timed out
    assert ctrl.last_info.obstacles_dropped == ("crate",)
    ctrl.forget("ball")
    ctrl.step(q, 0.13)
    assert ctrl.last_info.obstacles_dropped == ("ball",) and ctrl.execution.scene.names == ()  # type: ignore[attr-defined]
    with pytest.raises(UnknownNameError, match=r"unknown observed obstacle 'ball'; valid: "):
        ctrl.forget("ball")
    ctrl.observe("ball", truth(0.2), 0.2)
    ctrl.forget_all()
    ctrl.step(q, 0.2)
    assert ctrl.last_info.obstacles_added == ("ball",) and ctrl.last_info.obstacles_dropped == ("ball",)
    assert ctrl.last_info.late_observations == 1


def test_a_controller_without_sensing_refuses_observations() -> None:
    robot = pc.load_robot("planar4")
    ctrl = pc.make_controller("qp", robot=robot, path=pc.HandPath([START, END], duration=5.0))
    with pytest.raises(ObservationError, match=r"controller .qp. observes nothing: make it with .*sensing="):
        ctrl.observe("ball", [1.0, 0.8], 0.0)
    with pytest.raises(ObservationError, match="observes nothing"):
        ctrl.forget_all()


def test_the_qp_guards_against_the_observed_obstacle_inflated() -> None:
    """With the ball observed right by link 2 the QP has damper rows for it; its margin counts: a larger cap, a
    smaller distance."""
    distances = []
    for cap in (0.0, 0.05):
        ctrl = pc.make_controller(scenario("qp", confidence=1e6, margin_cap=cap))
        ctrl.observe("ball", [0.95, 0.45], 0.0)
        ctrl.step(np.array(Q0), 0.0)
        assert ctrl.last_info.executed.dampers > 0
        witnesses = ctrl.execution.dampers(np.array(Q0), 0.0)  # type: ignore[attr-defined]
        distances.append(witnesses.distance.min())
    assert distances[1] == pytest.approx(distances[0] - 0.05)


def test_the_worker_side_takes_the_loops_tracks_and_rebuilds_on_a_new_set() -> None:
    s = scenario("multi", motion=pc.Static([1.0, 0.8]), names=["ball"])
    loop = pc.make_controller(s)
    side = ObservedSide(lambda scene: _side_on(s.controller, s.robot, s.path, s.index, s.potential,
                                               np.random.default_rng(0), 0.033, None, scene), pc.Scene())
    first = side.side
    assert isinstance(first, PlanningSide)
    loop.observe("ball", [1.0, 0.8], 0.0)
    loop.step(np.array(Q0), 0.0)
    assert loop.observed is not None
    side.sync(loop.observed.world.observed_obstacles())
    rebuilt = side.side
    assert rebuilt is not first
    ball = rebuilt.part.arms.searches[0].evaluator.scene.obstacles[0]  # type: ignore[union-attr]
    assert ball.name == "ball" and isinstance(ball.motion, Track)
    loop.observe("ball", [1.2, 0.8], 0.5)
    side.sync(loop.observed.world.observed_obstacles())
    assert side.side is rebuilt and ball.motion.revision == 2 and ball.motion.last == 0.5
    mine = loop.observed.world.scene.obstacles[0].motion
    np.testing.assert_allclose(ball.motion.positions([0.5]), mine.positions([0.5]))


def test_a_background_controller_plans_around_observed_obstacles() -> None:
    """Without the ball, multi's imaginary arms head through where it is observed; with it observed, the worker's
    targets keep clear of it (S > 0 against the true ball), and the worker's scene has it."""
    ball = [0.8, -0.35]
    true_scene = pc.Scene((pc.Obstacle("ball", pc.Sphere(0.1), pc.Static(ball)),))
    s = scenario("multi", motion=pc.Static(ball))
    s = pc.Scenario(**{**s.__dict__, "scene": true_scene})
    check = Evaluator(s.robot, true_scene, s.index, s.potential)
    blind = pc.make_controller(s, sensing=pc.Sensing(names=("ball",)))  # never told: the ball stays unknown
    q = np.array(s.q0)
    for k in range(200):
        q = pc.integrate(s.robot, q, blind.step(q, k * DT, DT), DT)
    assert blind.last_info.targets is not None and check(blind.last_info.targets).collision.any()
    with pc.make_controller(s, planning="background", sensing=pc.Sensing(names=("ball",))) as ctrl:
        q, k, valid = np.array(s.q0), 0, 0
        deadline = time.monotonic() + WAIT
        while valid < 20:
            t = k * DT
            ctrl.observe("ball", ball, t)
            q = pc.integrate(s.robot, q, ctrl.step(q, t, DT), DT)
            k += 1
            info = ctrl.last_info
            assert info.worker_error is None
            if not info.fallback:
                valid += 1
                assert info.targets is not None
                found = check(info.targets)
                assert (found.S > 0).all() and not found.collision.any(), (k, found.min_distance)
            assert time.monotonic() < deadline, f"no valid plan after {WAIT} s: {info}"
            time.sleep(0.01)
        assert not check(q).collision.any()
    assert not multiprocessing.active_children()
