"""Tests of :mod:`previewctl.sim.sensor`: what the simulator's sensor observes of the true motion and when it delivers
it, and a run fed only observations."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import planar_doc, tiny_planar_toml

from previewctl.cli.main import main
from previewctl.control.factory import make_controller
from previewctl.scene.motion import ConstantVelocity, Static, Turn
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.sensing.options import Sensing
from previewctl.sim.log import load_summary
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import scenario_from_dict
from previewctl.sim.sensor import Sensor

MOVING = ConstantVelocity([1.0, 0.5], [-0.1, 0.2])
SCENE = Scene((Obstacle("wall", Sphere(0.2), Static([2.0, 2.0])), Obstacle("ball", Sphere(0.1), MOVING),
               Obstacle("turner", Sphere(0.1), Turn([0.0, 1.0], [0.2, 0.0], 1.0, 1.0))))


class Recorder:
    """Stands in for a controller: records every observation handed to it."""

    def __init__(self) -> None:
        self.seen: list[dict[str, Any]] = []

    def observe(self, name: str, position: Any, t: float, **kwargs: Any) -> None:
        self.seen.append({"name": name, "position": np.array(position), "t": t, **kwargs})


def _delivered(sensor: Sensor, until: float) -> Recorder:
    recorder = Recorder()
    sensor.deliver(recorder, until)  # type: ignore[arg-type]
    return recorder


def test_samples_each_moving_obstacle_at_the_rate_and_delivers_after_the_latency() -> None:
    sensor = Sensor(SCENE, Sensing(rate=20.0, noise=0.0, latency=0.1), duration=2.0, planar=True)
    recorder = Recorder()
    assert sensor.deliver(recorder, 0.0999) == 0  # type: ignore[arg-type]  # nothing before the latency
    assert sensor.deliver(recorder, 0.1) == 2  # type: ignore[arg-type]  # t_obs = 0 of both moving obstacles
    assert sensor.deliver(recorder, 0.1) == 0  # type: ignore[arg-type]  # each observation once
    sensor.deliver(recorder, 10.0)  # type: ignore[arg-type]
    ball = [o for o in recorder.seen if o["name"] == "ball"]
    np.testing.assert_allclose([o["t"] for o in ball], np.arange(41) / 20.0)  # 0, 0.05, ..., 2.0 s
    assert {o["name"] for o in recorder.seen} == {"ball", "turner"}  # the static wall stays known, unobserved
    assert sensor.delivered == 82 and sensor.dropped_by(10.0) == 0
    np.testing.assert_allclose(np.array([o["position"] for o in ball]), MOVING.positions(np.arange(41) / 20.0)[:, :2])
    assert all(o["shape"] == Sphere(0.1) and o["rotation"].shape == (3, 3) for o in ball)
    assert [o["t"] for o in recorder.seen] == sorted(o["t"] for o in recorder.seen)  # oldest first


def test_noise_and_dropout_statistics_for_a_fixed_seed() -> None:
    sensing = Sensing(names=("ball",), rate=30.0, noise=0.005, latency=0.05, dropout=0.25, seed=3)
    sensor = Sensor(SCENE, sensing, duration=100.0, planar=False)
    recorder = _delivered(sensor, 200.0)
    made = 3001
    assert sensor.dropped_by(200.0) + len(recorder.seen) == made
    assert len(recorder.seen) / made == pytest.approx(0.75, abs=0.03)
    times = np.array([o["t"] for o in recorder.seen])
    errors = np.array([o["position"] for o in recorder.seen]) - MOVING.positions(times)
    assert errors.shape == (len(times), 3)
    np.testing.assert_allclose(errors.std(axis=0), 0.005, rtol=0.05)
    np.testing.assert_allclose(errors.mean(axis=0), 0.0, atol=0.0005)
    again = _delivered(Sensor(SCENE, sensing, duration=100.0, planar=False), 200.0)
    np.testing.assert_array_equal([o["position"] for o in again.seen], [o["position"] for o in recorder.seen])


def test_a_history_observes_before_the_run_what_the_motion_did_then() -> None:
    started = ConstantVelocity([1.0, 0.5], [-0.1, 0.2], start_time=-10.0)  # already moving when the run starts
    scene = Scene((Obstacle("ball", Sphere(0.1), started),))
    sensor = Sensor(scene, Sensing(rate=20.0, noise=0.0, latency=0.1, history=1.0), duration=2.0, planar=True)
    before = _delivered(sensor, 0.0)  # what a controller has at its first step
    np.testing.assert_allclose([o["t"] for o in before.seen], np.arange(-20, -1) / 20.0)  # -1.0 ... -0.1 s (latency)
    np.testing.assert_allclose(np.array([o["position"] for o in before.seen]),
                               started.positions(np.arange(-20, -1) / 20.0)[:, :2])
    later = _delivered(sensor, 10.0)
    assert len(before.seen) + len(later.seen) == 20 + 41  # 1 s before the run, then as without a history
    without = Sensor(scene, Sensing(rate=20.0, noise=0.0, latency=0.1), duration=2.0, planar=True)
    assert [o["t"] for o in _delivered(without, 10.0).seen] == [o["t"] for o in later.seen][-41:]


def test_a_controller_watching_before_the_run_starts_with_the_velocity() -> None:
    ball = {"name": "ball", "shape": "cylinder", "radius": 0.1, "length": 0.4,
            "motion": {"type": "constant_velocity", "position": [1.6, 1.6], "velocity": [-0.2, -0.1],
                       "start_time": -5.0}}
    doc = planar_doc(obstacles=[ball], controller={"name": "qp"}, timing={"duration": 2.0},
                     sensing={"rate": 30.0, "noise": 0.005, "latency": 0.05, "predictor": "kalman", "history": 1.0})
    scenario = scenario_from_dict(doc)
    assert scenario.sensing is not None
    cold = dataclasses.replace(scenario.sensing, history=0.0)
    errors = []
    for sensing in (scenario.sensing, cold):
        controller = make_controller(dataclasses.replace(scenario, sensing=sensing))
        Sensor(scenario.scene, sensing, 2.0, planar=True).deliver(controller, 0.0)
        assert controller.observed is not None
        controller.observed.world.advance(0.0)  # the scene the first step sees
        world = {o.name: o for o in controller.observed.world.scene.obstacles}
        truth = scenario.scene.obstacles[0].motion.positions(np.array([1.0]))[0]
        errors.append(np.linalg.norm(world["ball"].motion.positions(np.array([1.0]))[0] - truth)
                      if "ball" in world else np.inf)
    assert errors[0] < 0.02  # 1 s ahead from its first step: 30 observations gave it the velocity
    assert errors[1] == np.inf  # without a history it has seen nothing by its first step (the latency)


def test_dropped_counts_only_what_was_due() -> None:
    sensor = Sensor(SCENE, Sensing(names=("ball",), rate=10.0, latency=0.5, dropout=1.0), duration=3.0, planar=True)
    assert _delivered(sensor, 3.5).seen == []
    assert sensor.dropped_by(0.4) == 0 and sensor.dropped_by(0.5) == 1 and sensor.dropped_by(3.5) == 31


class Unreadable:
    """A motion the controller must never read (it has only observations)."""

    rotation = np.eye(3)

    def placement(self, t: float) -> Any:
        raise RuntimeError(f"the controller read the true motion at t = {t}")

    def positions(self, times: Any) -> Any:
        raise RuntimeError("the controller read the true motion")


def test_a_planar_run_with_sensing_succeeds_on_observations_alone() -> None:
    ball = {"name": "ball", "shape": "cylinder", "radius": 0.1, "length": 0.4,
            "motion": {"type": "constant_velocity", "position": [1.6, 1.6], "velocity": [-0.1, -0.1]}}
    doc = planar_doc(obstacles=[ball], controller={"name": "qp"}, timing={"duration": 2.0},
                     sensing={"rate": 30.0, "noise": 0.005, "latency": 0.05, "dropout": 0.1, "seed": 2})
    scenario = scenario_from_dict(doc)
    (obstacle,) = scenario.scene.obstacles
    blind = dataclasses.replace(scenario, scene=Scene((dataclasses.replace(obstacle, motion=Unreadable()),)))
    controller = make_controller(blind)  # the simulator samples the true motion; the controller cannot read it
    result = simulate(scenario, controller=controller)
    summary = result.summary()
    assert summary["success"], summary
    assert summary["min_clearance"] < 0.1  # the ball came near: the observed obstacle was avoided
    # 30 Hz over [0, 2] s, delivered 50 ms late: t_obs <= 1.95 s by the last step, 59 made, ~10 % dropped
    assert summary["observations"] + summary["observations_dropped"] == 59
    assert 0 < summary["observations_dropped"] < 15
    assert result.observations[:5].tolist() == [0, 0, 0, 0, 0] and result.observations[5] == 1  # the first at 50 ms
    assert controller.observed is not None and "ball" in {o.name for o in controller.observed.world.scene.obstacles}


def test_run_prints_the_observations_delivered_and_dropped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sections = """
[controller]
name = "qp"
[[obstacles]]
name = "ball"
shape = "cylinder"
radius = 0.1
length = 0.4
motion = { type = "turn", position = [1.6, 1.6], velocity = [-0.1, -0.1], turn_time = 0.5, angle = 1.0, rate = 1.0 }
[sensing]
rate = 20.0
latency = 0.1
[output]
figures = []
gif = false
"""
    scenario = tmp_path / "observed.toml"
    scenario.write_text(tiny_planar_toml("observed", sections))
    assert main(["run", str(scenario), "--out", str(tmp_path / "out")]) == 0
    # 20 Hz over [0, 1] s delivered 100 ms late: t_obs = 0 .. 0.9 s by the last step
    assert "observations              19 delivered, 0 dropped (20 Hz, noise 5 mm, latency 100 ms, dropout 0)" in \
        capsys.readouterr().out
    assert load_summary(tmp_path / "out")["observations"] == 19
