"""Tests of :mod:`previewctl.sim.loop`, :mod:`previewctl.sim.log`, :mod:`previewctl.viz.figures` and
``previewctl run``: the loop, collisions, saving and reloading logs, figures."""

from __future__ import annotations

import contextlib
import json
import logging
import multiprocessing
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin
import pytest
from helpers import interruptible, planar_doc, tiny_planar_toml

import previewctl.control.background as background
from previewctl.bench.metrics import run_metrics
from previewctl.cli.main import main
from previewctl.control.background import WAKE_REFUSED, BackgroundOptions, real_time_priority
from previewctl.control.factory import make_controller
from previewctl.control.params import ControllerSpec
from previewctl.errors import IgnoredSettingWarning, PreviewctlError
from previewctl.robot.model import Robot
from previewctl.sim.log import NPZ_NAME, SUMMARY_NAME, RunResult, load_run, load_summary, save_run
from previewctl.sim.loop import frame_index, simulate
from previewctl.sim.scenario import Scenario, Timing, load_scenario, scenario_from_dict
from previewctl.viz.drawing import obstacle_outline
from previewctl.viz.figures import make_figures, strobe_plot

BOX = {"name": "wall", "shape": "box", "size": [0.1, 0.1, 0.2], "position": [1.0, 1.2, 0.0], "rpy": [0, 0, 0.3]}


@pytest.fixture(scope="module")
def crash() -> Scenario:
    """The hand path drives link3 into a small rotated box (at about t = 4.6 s) under the pseudo-inverse eq. 19."""
    return scenario_from_dict(planar_doc(obstacles=[BOX], controller={"execution": "pseudoinverse"}))


@pytest.fixture(scope="module")
def short_run() -> tuple[Scenario, RunResult]:
    scenario = scenario_from_dict(planar_doc(
        obstacles=[{"name": "ball", "shape": "sphere", "radius": 0.1, "motion": {
            "type": "constant_velocity", "position": [1.2, 0.2], "velocity": [0.0, 0.1]}}],
        timing={"duration": 0.6}))
    return scenario, simulate(scenario, "gradient")


def coal_link_distances(robot: Robot, q: np.ndarray, box: dict[str, Any]) -> np.ndarray:
    """Independent check: Coal distance between each guarded link's cylinder and the box."""
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, q)
    c, s = np.cos(box["rpy"][2]), np.sin(box["rpy"][2])
    box_tf = coal.Transform3s(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), np.array(box["position"], float))
    out = []
    for link in robot.guarded_links:
        joint = model.getJointId("joint" + link[-1])
        axis_tf = data.oMi[joint] * pin.SE3(pin.rpy.rpyToMatrix(0, np.pi / 2, 0), np.array([0.375, 0, 0]))
        request, result = coal.DistanceRequest(), coal.DistanceResult()
        d = coal.distance(coal.Cylinder(0.03, 0.75), coal.Transform3s(axis_tf.rotation, axis_tf.translation),
                          coal.Box(*box["size"]), box_tf, request, result)
        out.append(d)
    return np.array(out)


# ------------------------------------------------------------------------------------- the loop


def test_collision_is_detected_reported_and_stops_the_run(crash: Scenario) -> None:
    full = simulate(crash, stop_on_collision=False)
    assert full.steps == crash.timing.steps + 1
    # independent Coal check of the logged configurations: first step with a link inside the box
    independent = np.array([coal_link_distances(crash.robot, q, BOX) for q in full.q])
    first = int(np.flatnonzero((independent <= 0).any(axis=1))[0])
    link = crash.robot.guarded_links[int(np.argmin(independent[first]))]
    np.testing.assert_allclose(full.link_distances, independent, atol=1e-6)
    assert 4.0 < full.t[first] < 5.0 and link == "link3"

    run = simulate(crash)
    summary = run.summary()
    assert summary["collided"] is True
    assert summary["collision_time"] == pytest.approx(full.t[first])
    assert summary["collision_link"] == link
    assert run.steps == first + 1, "the run stops at the colliding step"
    assert run.collision[-1] and not run.collision[:-1].any()
    assert (run.qdot[-1] == 0).all()
    assert summary["min_clearance"] < 0 and summary["min_S"] < 0


def test_continue_after_collision_logs_every_step(crash: Scenario) -> None:
    run = simulate(replace(crash, timing=Timing(0.01, 0.033, 5.0)), stop_on_collision=False)
    assert run.collision.any() and run.steps == 501


def test_log_contents(short_run: tuple[Scenario, RunResult]) -> None:
    scenario, run = short_run
    T = scenario.timing.steps + 1
    assert run.steps == T and run.q.shape == (T, 4) and run.qdot.shape == (T, 4)
    assert run.link_distances.shape == (T, 4) and run.link_names == ("link1", "link2", "link3", "link4")
    np.testing.assert_allclose(run.t, np.arange(T) * 0.01)
    np.testing.assert_allclose(run.desired[:, :2], scenario.path.position(run.t), atol=1e-12)
    np.testing.assert_allclose(run.hand_error, np.linalg.norm(run.desired - run.hand, axis=1))
    # the log's q really integrates the logged q̇
    np.testing.assert_allclose(run.q[1:], run.q[:-1] + run.qdot[:-1] * 0.01, atol=1e-12)
    assert (run.cycle_time[:-1] > 0).all()
    # a camera frame every 33 ms: frames 0..18 start within 0.6 s
    assert run.frame_due[0] and run.frame_due.sum() == frame_index(0.6, 0.033) + 1
    assert np.isfinite(run.S).all() and (run.S > 0).all()
    summary = run.summary()
    assert summary["controller"] == "gradient" and summary["scenario"] == "planar_test" and summary["steps"] == T
    assert summary["max_abs_qdot"] == pytest.approx(np.abs(run.qdot).max())
    assert summary["cycle_time_median"] <= summary["cycle_time_max"]


def test_progress_is_reported(crash: Scenario) -> None:
    seen: list[tuple[float, float]] = []
    short = replace(crash, timing=Timing(0.01, 0.033, 0.2))
    simulate(short, progress=lambda f, t: seen.append((f, t)))
    fractions = [f for f, _ in seen]
    assert fractions[0] == 0.0 and fractions[-1] == 1.0 and fractions == sorted(fractions)


# ------------------------------------------------------------------------------------- saving


def test_saved_run_reloads_equal(short_run: tuple[Scenario, RunResult], tmp_path: Path) -> None:
    _, run = short_run
    npz_path, json_path = save_run(run, tmp_path / "out")
    assert npz_path.name == NPZ_NAME and json_path.name == SUMMARY_NAME
    again = load_run(tmp_path / "out")
    for f in fields(RunResult):
        a, b = getattr(run, f.name), getattr(again, f.name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype, f.name
            np.testing.assert_array_equal(a, b, err_msg=f.name)
        else:
            assert a == b, f.name
    assert again.summary() == run.summary()
    assert load_summary(tmp_path / "out") == run.summary()
    assert json.loads(json_path.read_text())["min_clearance"] is not None
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [NPZ_NAME, SUMMARY_NAME]


def test_failed_write_leaves_no_partial_file(short_run: tuple[Scenario, RunResult], tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    _, run = short_run
    out = tmp_path / "out"

    def broken_replace(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(PreviewctlError, match="No space left"):
        save_run(run, out)
    assert list(out.iterdir()) == []
    monkeypatch.undo()

    # an older complete run stays intact when the new write fails half-way (in the JSON)
    save_run(run, out)
    before = (out / NPZ_NAME).read_bytes(), (out / SUMMARY_NAME).read_bytes()
    calls = {"n": 0}
    real_replace = os.replace

    def fail_second(src: str, dst: str) -> None:
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(5, "I/O error")
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", fail_second)
    with pytest.raises(PreviewctlError, match="I/O error"):
        save_run(run, out)
    assert sorted(p.name for p in out.iterdir()) == [NPZ_NAME, SUMMARY_NAME]
    assert (out / SUMMARY_NAME).read_bytes() == before[1]
    load_run(out)  # the npz is complete


def test_load_run_of_empty_folder_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(PreviewctlError, match=r"run\.npz is missing"):
        load_run(tmp_path)


# ------------------------------------------------------------------------------------ figures


def test_figures_and_gif(crash: Scenario, tmp_path: Path) -> None:
    run = simulate(replace(crash, timing=Timing(0.02, 0.033, 5.0)))
    assert run.summary()["collided"]
    written = make_figures(run, crash, tmp_path)
    names = sorted(p.name for p in written)
    assert names == ["S.png", "clearance.png", "error.png", "run.gif", "strobe.png"]
    from PIL import Image

    with Image.open(tmp_path / "run.gif") as gif:
        assert 2 <= getattr(gif, "n_frames", 1) <= 150
    with Image.open(tmp_path / "strobe.png") as png:
        assert png.size[0] > 300


def test_obstacle_outlines_in_the_plane(crash: Scenario) -> None:
    from previewctl.scene.file import scene_from_dict

    scene = scene_from_dict([
        {"name": "box", "shape": "box", "size": [0.2, 0.4, 1.0], "position": [1, 2, 0], "rpy": [0, 0, np.pi / 2]},
        {"name": "floor", "shape": "halfspace", "normal": [0, 1, 0], "offset": -0.5},
        {"name": "cap", "shape": "capsule", "radius": 0.1, "length": 0.6, "rpy": [0, np.pi / 2, 0]},
    ])
    bounds = (-2.0, 2.0, -2.0, 2.0)
    kind, box = obstacle_outline(scene.obstacles[0], 0.0, bounds)
    assert kind == "polygon"
    np.testing.assert_allclose(np.sort(box[:, 0]), [0.8, 0.8, 1.2, 1.2], atol=1e-12)  # turned by 90 deg
    np.testing.assert_allclose(np.sort(box[:, 1]), [1.9, 1.9, 2.1, 2.1], atol=1e-12)
    kind, half = obstacle_outline(scene.obstacles[1], 0.0, bounds)
    assert half[:, 1].max() == pytest.approx(-0.5) and half[:, 1].min() == pytest.approx(-2.0)
    kind, stadium = obstacle_outline(scene.obstacles[2], 0.0, bounds)
    assert stadium[:, 0].max() == pytest.approx(0.4) and stadium[:, 1].max() == pytest.approx(0.1)


def test_spatial_strobe(tmp_path: Path) -> None:
    doc = {
        "robot": {"source": "panda", "q0": [-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785]},
        "path": {"waypoints": [[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]], "duration": 10.0},
        "obstacles": [{"name": "ball", "shape": "sphere", "radius": 0.08, "motion": {
            "type": "constant_velocity", "position": [0.06, 0.6, 0.72], "velocity": [0, -0.12, 0]}}],
        "timing": {"duration": 0.3},
    }
    scenario = scenario_from_dict(doc)
    from previewctl.index.evaluator import Evaluator

    run = simulate(scenario, exact_evaluator=Evaluator(scenario.robot, scenario.scene))
    path = strobe_plot(run, scenario, tmp_path / "strobe.png", poses=4)
    assert path.is_file() and path.stat().st_size > 10_000


# ------------------------------------------------------------------------------------------ CLI


def test_cli_run_writes_summary_log_and_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(tiny_planar_toml(
        "tiny",
        '[[obstacles]]\nname = "b"\nshape = "sphere"\nradius = 0.1\nposition = [1.0, 0.2]\n'
        "[timing]\nduration = 0.3\n",
    ))
    out = tmp_path / "run"
    assert main(["run", str(scenario), "--out", str(out), "--controller", "gradient", "--no-gif", "--seed", "1"]) == 0
    captured = capsys.readouterr()
    assert "100.0%" in captured.err
    for label in ("collision-free", "max hand error", "min clearance", "mean / min S", "max |qdot|",
                  "cycle time median / max"):
        assert label in captured.out
    assert sorted(p.name for p in out.iterdir()) == ["S.png", "clearance.png", "error.png", NPZ_NAME,
                                                     "strobe.png", SUMMARY_NAME]
    assert load_summary(out)["controller"] == "gradient"


def test_cli_default_out_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(tiny_planar_toml(
        "tiny",
        '[timing]\nduration = 0.05\n[output]\nfigures = ["S"]\ngif = false\n',
    ))
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scenario)]) == 0
    assert (tmp_path / "out" / "tiny-none" / NPZ_NAME).is_file()
    assert (tmp_path / "out" / "tiny-none" / "S.png").is_file()


def test_cli_runs_reach(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = Path(__file__).resolve().parent.parent / "scenarios" / "planar_free.toml"
    assert main(["run", str(scenario), "--controller", "reach", "--out", str(tmp_path / "o"), "--no-gif"]) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["controller"] == "reach" and not summary["collided"]
    assert summary["max_hand_error"] < 2e-3


# -------------------------------------------------------------------------------------- verdict


def test_success_needs_no_collision_and_the_hand_within_tolerance(
    crash: Scenario, short_run: tuple[Scenario, RunResult]
) -> None:
    scenario, run = short_run
    summary = run.summary()
    assert summary["success"] and summary["failure"] is None and summary["tolerance"] == 0.005
    assert summary["error_time"] is None and summary["max_hand_error"] <= 0.005
    # the same run judged with a tolerance below its largest error fails on the hand error
    tight = 0.5 * summary["max_hand_error"]
    judged = simulate(scenario, "gradient", tolerance=tight).summary()
    first = int(np.flatnonzero(run.hand_error > tight)[0])
    assert not judged["success"] and judged["failure"] == "hand error" and not judged["collided"]
    assert judged["error_time"] == pytest.approx(run.t[first]) and judged["tolerance"] == tight
    collided = simulate(crash).summary()
    assert not collided["success"] and collided["failure"] == "collision" and collided["error_time"] is None
    both = simulate(crash, tolerance=1e-12).summary()
    assert both["failure"] == "collision and hand error"
    assert both["error_time"] < both["collision_time"]
    with pytest.raises(PreviewctlError, match=r"tolerance must be > 0, got -0\.001"):
        simulate(scenario, tolerance=-0.001)


def test_scenario_tolerance_is_read_and_checked() -> None:
    assert scenario_from_dict(planar_doc(verdict={"tolerance": 0.002})).verdict.tolerance == 0.002
    with pytest.raises(PreviewctlError, match=r"verdict.tolerance must be > 0, got 0"):
        scenario_from_dict(planar_doc(verdict={"tolerance": 0}))


def test_cli_run_exit_code_says_a_run_failed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "crash.toml"
    scenario.write_text(tiny_planar_toml(
        "crash",
        "[timing]\nduration = 0.2\n[output]\nfigures = []\ngif = false\n",
    ))
    assert main(["run", str(scenario), "--out", str(tmp_path / "ok")]) == 0
    assert "success                   yes" in capsys.readouterr().out
    assert main(["run", str(scenario), "--out", str(tmp_path / "tight"), "--tolerance", "1e-12"]) == 3
    out = capsys.readouterr().out
    assert "success                   NO: hand error > 0.00 mm from t = 0.0" in out
    assert load_summary(tmp_path / "tight")["failure"] == "hand error"
    assert main(["run", str(scenario), "--tolerance", "-1"]) == 2
    assert "tolerance must be > 0, got -1.0" in capsys.readouterr().err


# -------------------------------------------------------------------------------------- self-collision

PANDA_Q0 = [-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785]
"""The Panda of ``scenarios/panda_crossing.toml``: the hand at (0.45, -0.25, 0.35) m."""
INTO_ITS_BASE = f"""name = "panda_into_its_base"
[robot]
source = "panda"
q0 = {PANDA_Q0}
[path]
waypoints = [[0.45, -0.25, 0.35], [0.05, 0.0, 0.30]]   # the hand back to the base column, 5 cm from its axis
duration = 4.0
[controller]
name = "none"
execution = "pseudoinverse"
[timing]
duration = 4.0
[output]
figures = []
gif = false
"""


@pytest.fixture(scope="module")
def into_its_base(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Scenario, RunResult]:
    path = tmp_path_factory.mktemp("self") / "into_its_base.toml"
    path.write_text(INTO_ITS_BASE)
    scenario = load_scenario(path)
    return path, scenario, simulate(scenario)


def mesh_contact(robot: Robot, q: np.ndarray, a: str, b: str) -> bool:
    """Coal's own verdict on the exact meshes of links ``a`` and ``b`` at ``q``."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    hit = False
    for ga in robot.self_pairs.geometry.geometryObjects:
        for gb in robot.self_pairs.geometry.geometryObjects:
            names = (robot.model.frames[ga.parentFrame].name, robot.model.frames[gb.parentFrame].name)
            if names != (a, b):
                continue
            pa, pb = data.oMi[ga.parentJoint] * ga.placement, data.oMi[gb.parentJoint] * gb.placement
            result = coal.CollisionResult()
            coal.collide(ga.geometry, coal.Transform3s(pa.rotation, pa.translation), gb.geometry,
                         coal.Transform3s(pb.rotation, pb.translation), coal.CollisionRequest(), result)
            hit |= result.isCollision()
    return hit


def test_the_hand_driven_into_its_own_base_fails_the_verdict_naming_both_links(
    into_its_base: tuple[Path, Scenario, RunResult],
) -> None:
    _, scenario, run = into_its_base
    summary = run.summary()
    assert not summary["success"] and summary["failure"] == "self-collision"
    assert summary["self_collided"] and not summary["collided"]  # no obstacle in the scene
    assert summary["self_collision_links"] == ["panda_link1", "panda_leftfinger"]
    assert summary["self_collision_time"] == pytest.approx(3.82, abs=0.05)
    assert summary["max_hand_error"] < 1e-3  # the pseudo-inverse tracked the path into the base
    k = run.self_collision_index
    assert k == run.steps - 1 and run.self_collision[k] and not run.self_collision[:k].any()
    assert run.self_distance[k] <= 0.0 and run.S[k] < 0.0 and np.all(run.self_distance[:k] > 0.0)
    assert run.self_pairs == scenario.exact_robot().self_pairs.links
    assert run.self_pairs[run.self_pair[k]] == ("panda_link1", "panda_leftfinger")
    # Coal on the exact meshes agrees: touching at the last step, apart one step before
    exact = scenario.exact_robot()
    assert mesh_contact(exact, run.q[k], "panda_link1", "panda_leftfinger")
    assert not mesh_contact(exact, run.q[k - 1], "panda_link1", "panda_leftfinger")


def test_the_bench_metrics_count_a_self_collision_as_a_failure(into_its_base: tuple[Path, Scenario, RunResult]) -> None:
    _, _, run = into_its_base
    metrics = run_metrics(run)
    assert metrics["collision_free"] and not metrics["self_collision_free"]
    assert metrics["self_collision_time"] == pytest.approx(float(run.t[run.self_collision_index]))
    assert not metrics["success_1mm"] and not metrics["success_5mm"]  # the hand itself stayed within 1 mm


def test_a_self_collided_run_reloads_equal_and_an_older_log_loads_without_self_pairs(
    into_its_base: tuple[Path, Scenario, RunResult], tmp_path: Path
) -> None:
    _, _, run = into_its_base
    save_run(run, tmp_path / "new")
    again = load_run(tmp_path / "new")
    assert again.self_pairs == run.self_pairs and again.summary() == run.summary()
    np.testing.assert_array_equal(again.self_pair, run.self_pair)
    with np.load(tmp_path / "new" / NPZ_NAME) as npz:
        older = {name: npz[name] for name in npz.files if not name.startswith("self_") and name != "composition"}
    (tmp_path / "old").mkdir()
    np.savez(tmp_path / "old" / NPZ_NAME, **older)
    old = load_run(tmp_path / "old")
    assert old.self_pairs == () and not old.self_collision.any() and np.all(np.isinf(old.self_distance))
    assert old.summary()["self_collided"] is False and old.summary()["min_self_distance"] is None
    assert old.composition == "" and run.composition == "none (Tracking), execution pseudoinverse"


def test_under_the_qp_the_same_path_stops_short_of_the_base_and_fails_on_hand_error(
    into_its_base: tuple[Path, Scenario, RunResult],
) -> None:
    """The QP's self dampers hold the fingers off panda_link1 (at least ``self_safety_distance`` on the search
    geometry): the exact check sees no self-collision, and the run fails because the hand left its path."""
    _, scenario, _ = into_its_base
    with pytest.warns(IgnoredSettingWarning, match="execution = 'pseudoinverse'"):  # qp runs the QP whatever it says
        qp = simulate(replace(scenario, controller=ControllerSpec("qp", scenario.controller.params)))
    summary = qp.summary()
    assert summary["failure"] == "hand error" and not summary["self_collided"] and qp.steps == scenario.timing.steps + 1
    assert summary["min_self_distance"] > 0.005 and summary["max_hand_error"] > 0.01


def test_cli_run_prints_the_self_collision_and_exits_3(into_its_base: tuple[Path, Scenario, RunResult],
                                                        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, _, _ = into_its_base
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 3
    out = capsys.readouterr().out
    assert "self-collision at t = 3.82 s: panda_link1 hits panda_leftfinger" in out
    assert re.search(r"success\s+NO: self-collision at t = 3\.820 s: panda_link1 hits panda_leftfinger", out)
    assert re.search(r"collision-free\s+yes", out)  # the obstacle line reads as before
    assert json.loads((tmp_path / "out" / SUMMARY_NAME).read_text())["failure"] == "self-collision"


# ------------------------------------------------------------------------------------------- real time

TIMING_KEYS = ("cycle_p50", "cycle_p99", "cycle_max", "deadline_misses", "plan_age_p95", "fallback_fraction")


def sane_timing(summary: dict[str, Any]) -> None:
    """The summary's cycle figures are ordered and in range."""
    assert 0 < summary["cycle_p50"] <= summary["cycle_p99"] <= summary["cycle_max"]
    assert isinstance(summary["deadline_misses"], int) and 0 <= summary["deadline_misses"] <= summary["steps"]
    assert 0.0 <= summary["fallback_fraction"] <= 1.0


def test_a_real_time_run_waits_for_the_wall_clock_and_plans_in_the_background() -> None:
    scenario = scenario_from_dict(planar_doc(controller={"name": "multi"}, timing={"duration": 1.0}))
    # results valid for the whole run: a loaded host may stall the loop past the default validity (3 frames)
    options = BackgroundOptions(arms_valid_frames=1000.0)
    start = time.perf_counter()
    with make_controller(scenario, dt=0.01, planning="background", background=options) as ctrl:
        run = simulate(scenario, controller=ctrl, rate=100.0)
    wall = time.perf_counter() - start
    assert run.dt == 0.01 and run.t[-1] >= 1.0 and wall >= run.t[-1]  # it waited for the clock
    assert run.steps <= 101 and (np.diff(run.t) > 0).all()
    # the arm integrates each command over the wall time it was applied
    np.testing.assert_allclose(run.q[1:], run.q[:-1] + run.qdot[:-1] * np.diff(run.t)[:, None], atol=1e-12)
    assert "background" in run.composition
    assert np.isfinite(run.plan_age[0])  # the clock started once the worker had answered the start state
    summary = run.summary()
    sane_timing(summary)
    assert summary["plan_age_p95"] >= 0.0
    assert summary["deadline_misses"] == int((run.loop_time > 0.01).sum())
    assert not multiprocessing.active_children()  # the worker ended with the run


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="CPU affinity on two cores or more")
def test_a_real_time_loop_runs_on_the_core_its_workers_leave_free() -> None:
    scenario = scenario_from_dict(planar_doc(controller={"name": "multi"}, timing={"duration": 0.2}))
    before, seen, policies = os.sched_getaffinity(0), [], set()
    policy = os.sched_getscheduler(0)

    def record(*_: object) -> None:
        seen.append(os.sched_getaffinity(0))
        policies.add(os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK)

    with make_controller(scenario, dt=0.01, planning="background") as ctrl:
        workers = os.sched_getaffinity(ctrl.planning.worker.pid)  # type: ignore[union-attr]
        simulate(scenario, controller=ctrl, rate=100.0, progress=record)
    assert seen and all(cores == {min(before)} for cores in seen) and not workers & {min(before)}
    assert os.sched_getaffinity(0) == before  # restored once the run ended
    with real_time_priority() as granted:
        pass
    assert policies == ({os.SCHED_FIFO} if granted else {policy})  # the real-time class when the OS grants it
    assert os.sched_getscheduler(0) == policy


def test_a_controller_with_nothing_to_plan_runs_inline_at_real_time() -> None:
    scenario = scenario_from_dict(planar_doc(controller={"name": "qp"}, timing={"duration": 0.3}))
    start = time.perf_counter()
    run = simulate(scenario, rate=50.0)
    assert time.perf_counter() - start >= run.t[-1] >= 0.3 and run.dt == 0.02
    assert "background" not in run.composition
    summary = run.summary()
    sane_timing(summary)
    assert summary["plan_age_p95"] is None and summary["fallback_fraction"] == 0.0


def test_an_inline_real_time_run_steps_once_before_its_clock_starts() -> None:
    """The first step loads the compiled kernels: it is taken at the start state, not logged, before the first tick."""
    scenario = scenario_from_dict(planar_doc(controller={"name": "qp"}, timing={"duration": 0.1}))
    controller = make_controller(scenario, dt=0.02)
    calls: list[tuple[Any, float]] = []
    step = controller.step

    def recorded(q: Any, t: float, dt: float | None = None) -> Any:
        calls.append((np.array(q), t))
        return step(q, t, dt)

    controller.step = recorded  # type: ignore[method-assign]
    run = simulate(scenario, controller=controller, rate=50.0)
    assert len(calls) == run.t.size + 1  # a step per tick, and one before them
    assert all(t == 0.0 and np.array_equal(q, scenario.q0) for q, t in calls[:2])
    assert [t for _, t in calls[1:]] == pytest.approx(run.t.tolist(), abs=0.0)


def test_a_real_time_run_warns_and_says_when_the_cores_may_not_be_kept_awake(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.setattr(background, "prompt_wake_up", lambda: contextlib.nullcontext(False))
    scenario = scenario_from_dict(planar_doc(controller={"name": "qp"}, timing={"duration": 0.1}))
    with caplog.at_level(logging.WARNING, logger="previewctl"):
        summary = simulate(scenario, rate=50.0).summary()
    assert WAKE_REFUSED in caplog.messages
    assert summary["cores_awake"] is False  # and the run says so
    with real_time_priority() as granted:
        pass
    assert summary["real_time_class"] is granted
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="previewctl"):
        summary = simulate(scenario).summary()  # simulated time: no real-time loop, nothing to warn about
    assert WAKE_REFUSED not in caplog.messages
    assert summary["real_time_class"] is None and summary["cores_awake"] is None


@pytest.mark.parametrize("rate", [0.0, -250.0, float("nan"), "fast"])
def test_a_bad_rate_is_refused(rate: Any) -> None:
    scenario = scenario_from_dict(planar_doc(timing={"duration": 0.1}))
    with pytest.raises(PreviewctlError, match="rate must be"):
        simulate(scenario, rate=rate)


def test_an_inline_summary_has_the_cycle_figures_without_planning(short_run: tuple[Scenario, RunResult]) -> None:
    _, run = short_run
    summary = run.summary()
    sane_timing(summary)
    assert (run.loop_time >= run.cycle_time).all()  # the whole cycle holds the control cycle
    assert summary["plan_age_p95"] is None and summary["fallback_fraction"] == 0.0
    assert np.isnan(run.plan_age).all() and not run.fallback.any()


def test_an_older_log_loads_as_inline_with_its_control_cycles_as_whole_cycles(
    short_run: tuple[Scenario, RunResult], tmp_path: Path
) -> None:
    _, run = short_run
    save_run(run, tmp_path / "new")
    with np.load(tmp_path / "new" / NPZ_NAME) as npz:
        older = {name: npz[name] for name in npz.files if name not in ("loop_time", "plan_age", "fallback")}
    (tmp_path / "old").mkdir()
    np.savez(tmp_path / "old" / NPZ_NAME, **older)
    old = load_run(tmp_path / "old")
    np.testing.assert_array_equal(old.loop_time, run.cycle_time)
    assert np.isnan(old.plan_age).all() and not old.fallback.any()
    assert old.summary()["cycle_max"] == pytest.approx(run.cycle_time.max())
    assert old.summary()["plan_age_p95"] is None


def realtime_scenario(folder: Path, duration: float) -> Path:
    path = folder / "rt.toml"
    path.write_text(tiny_planar_toml("rt", f'[controller]\nname = "multi"\n[timing]\nduration = {duration}\n'
                                           "[output]\nfigures = []\ngif = false\n"))
    return path


def test_cli_run_realtime_prints_and_writes_the_cycle_figures(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    scenario = realtime_scenario(tmp_path, 0.5)
    assert main(["run", str(scenario), "--realtime", "--rate", "100", "--out", str(tmp_path / "o"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)["summary"]
    assert set(TIMING_KEYS) <= set(summary) and summary == load_summary(tmp_path / "o")
    sane_timing(summary)
    assert load_run(tmp_path / "o").dt == 0.01
    assert main(["run", str(scenario), "--realtime", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert re.search(r"deadline misses +\d+ of \d+ cycles longer than 4 ms \(real time\)", out)
    # a result in use, or none ('-') when a loaded host let every result expire
    assert re.search(r"plan age p95 / fallback +(\d+ ms|-) / [\d.]+% of cycles", out)
    assert re.search(r"real-time loop +(SCHED_FIFO|ordinary class \(SCHED_FIFO refused\)), "
                     r"cores (kept awake|may halt \(refused\))", out)


@pytest.mark.parametrize(("argv", "message"), [
    (["--realtime", "--rate", "0"], "argument --rate: must be a loop rate > 0 [Hz], got '0'"),
    (["--realtime", "--rate", "-5"], "argument --rate: must be a loop rate > 0 [Hz], got '-5'"),
    (["--realtime", "--rate", "fast"], "argument --rate: must be a loop rate > 0 [Hz], got 'fast'"),
    (["--rate", "100"], "--rate 100 sets the loop rate of --realtime: add --realtime, or drop --rate"),
])
def test_cli_run_refuses_a_bad_rate_in_one_line(argv: list[str], message: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    try:
        code = main(["run", str(realtime_scenario(tmp_path, 0.1)), *argv])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1


def children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields_ = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if int(fields_[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie waiting for its parent counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_ctrl_c_during_a_real_time_run_exits_130_and_leaves_no_child(tmp_path: Path) -> None:
    scenario = realtime_scenario(tmp_path, 60.0)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    run = subprocess.Popen([sys.executable, "-m", "previewctl", "run", str(scenario), "--realtime", "--out",
                            str(tmp_path / "o")], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                           env=env, preexec_fn=interruptible)
    try:
        deadline = time.monotonic() + 60.0
        while not (workers := [p for p in children(run.pid)
                               if "spawn_main" in Path(f"/proc/{p}/cmdline").read_text(errors="replace")]):
            assert run.poll() is None and time.monotonic() < deadline, "no planning worker started"
            time.sleep(0.05)
        time.sleep(1.0)
        started = children(run.pid)
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=30.0)
    finally:
        run.kill()
    assert run.returncode == 130, err
    assert "previewctl: interrupted" in err
    deadline = time.monotonic() + 10.0
    while left := [p for p in [*workers, *started] if alive(p)]:
        assert time.monotonic() < deadline, f"processes {left} outlived the run"
        time.sleep(0.1)
    assert not (tmp_path / "o").exists()  # nothing half-written
