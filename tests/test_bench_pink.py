"""The pink baselines (previewctl/bench/pink.py): pink's solve_ik stepped by the simulator, its barrier against Coal,
the sweep's matrix and report, and the one-line message without pink.

The tests that run pink skip, saying why, when pink (``pin-pink``, in the ``bench`` extra) is not installed; the
others run without it.
"""

from __future__ import annotations

import sys
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
from helpers import PLANAR_START, planar_doc

from previewctl.bench.pink import BARRIER_GAINS, EXECUTION, barrier_gain, make_pink_controller
from previewctl.bench.report import write_report
from previewctl.bench.sweep import Sweep
from previewctl.cli.main import main
from previewctl.errors import MissingExtraError, UnknownNameError
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, scenario_from_dict

DISC = {"name": "disc", "shape": "cylinder", "radius": 0.08, "length": 0.4, "position": [1.0, 1.2, 0.0]}
"""A static disc on planar4's path that plain tracking (``none``) runs a link into."""


def needs_pink() -> None:
    pytest.importorskip("pink", reason="pink (pin-pink) is not installed: pip install 'previewctl[bench]'")


def _disc_scenario() -> Scenario:
    return scenario_from_dict(planar_doc(obstacles=[DISC], timing={"duration": 5.0}))


@pytest.mark.parametrize("name", list(BARRIER_GAINS))
def test_pink_avoids_a_static_disc_that_plain_tracking_hits(name: str) -> None:
    needs_pink()
    scenario = _disc_scenario()
    assert simulate(scenario, "none").collision_index is not None
    params = scenario.controller.params
    controller = make_pink_controller(name, scenario.robot, scenario.path, scenario.scene, params, scenario.timing.dt)
    result = simulate(scenario, controller=controller)
    assert result.collision_index is None and result.steps == scenario.timing.steps + 1  # ran to the end
    assert result.hand_error.max() < 1e-3  # the hand on the path all the way
    assert result.min_distance.min() > params.safety_distance - 1e-3  # the barrier held d_min (to a step's drift)
    assert (result.controller, result.execution) == (name, "pink")
    assert controller.execution.no_solution == 0
    assert f"barrier gain {BARRIER_GAINS[name]:g}" in result.composition


def test_a_cycle_without_a_solution_holds_the_arm_and_is_counted() -> None:
    """A link 1 cm from a disc (inside ``d_min`` = 2 cm) and speed limits too low to leave at the barrier's rate:
    pink finds no solution, and the arm holds still instead of the run failing."""
    needs_pink()
    disc = {**DISC, "radius": 0.05, "position": [PLANAR_START[0] + 0.09, PLANAR_START[1], 0.0]}
    scenario = scenario_from_dict(planar_doc(obstacles=[disc], timing={"duration": 0.2},
                                             controller={"velocity_scale": 1e-3}))
    controller = make_pink_controller("pink-g100", scenario.robot, scenario.path, scenario.scene,
                                      scenario.controller.params, scenario.timing.dt)
    result = simulate(scenario, controller=controller)
    execution = controller.execution
    assert -0.015 < execution.barrier.compute_barrier(execution.configuration).min() < -0.005  # d - d_min, pink's
    assert result.collision_index is None
    assert execution.no_solution == result.steps == 21
    np.testing.assert_array_equal(result.q, np.repeat(result.q[:1], result.steps, axis=0))
    assert execution.record()["pink_no_solution"] == 21


def _barrier_rows_against_central_differences(robot: Robot, scene: Scene, q: np.ndarray) -> int:
    """Check every row of pink's barrier at ``q`` against central differences of its pair's Coal distance; the
    number of rows checked."""
    from previewctl.bench.pink import PinkExecution

    params = scenario_from_dict(planar_doc()).controller.params
    execution = PinkExecution(robot, scene, params, gain=barrier_gain("pink"))
    configuration, barrier, geometry = execution.configuration, execution.barrier, execution.geometry
    configuration.update(q)
    h, J = barrier.compute_barrier(configuration), barrier.compute_jacobian(configuration)
    data, gdata = robot.model.createData(), geometry.createData()
    for request in gdata.distanceRequests:  # the reference: GJK converged far below the differences' step
        request.gjk_tolerance = 1e-12
        request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess

    def distances(x: np.ndarray) -> np.ndarray:
        pin.computeDistances(robot.model, data, geometry, gdata, x)
        return np.array([r.min_distance for r in gdata.distanceResults])

    d = distances(q)
    order = np.argpartition(-d, -len(d))  # the barrier's rows are the pairs in this order (all pairs: dim = P)
    np.testing.assert_allclose(h, d[order] - params.safety_distance, atol=2e-6)  # pink's GJK: its default tolerance
    eps = 1e-5
    numeric = np.stack([(distances(pin.integrate(robot.model, q, eps * e)) -
                         distances(pin.integrate(robot.model, q, -eps * e))) / (2 * eps)
                        for e in np.eye(robot.nv)], axis=1)
    # pink reads the nearest points of Coal's GJK at its default tolerance: on planar4's cylinders they are off by
    # up to ~3e-4 m/rad in a row; a wrong frame, sign or lever arm would be off by the row's size (0.3-0.8)
    np.testing.assert_allclose(J, numeric[order], atol=1e-3)
    return len(d)


def test_barrier_rows_match_finite_differences_of_the_coal_distance_planar(planar4: Robot) -> None:
    needs_pink()
    scene = _disc_scenario().scene
    rng = np.random.default_rng(3)
    checked = 0
    for q in planar4.random_configurations(rng, 20):
        if np.min(_coal_distances(planar4, scene, q)) > 0.05:  # clear of the disc: the distance is smooth
            checked += _barrier_rows_against_central_differences(planar4, scene, q)
    assert checked >= 4 * 3  # a few configurations, every link paired with the disc


def test_barrier_rows_match_finite_differences_of_the_coal_distance_panda_with_self_pairs(panda: Robot) -> None:
    """The Panda's rows: link-sphere pairs and the self pairs (link-link, both moving)."""
    needs_pink()
    scene = Scene((Obstacle("ball", Sphere(0.1), Static(np.array([0.3, 0.4, 0.6]))),))
    q = np.array([0.1, -0.4, 0.2, -2.0, 0.1, 1.8, 0.6])
    assert np.min(_coal_distances(panda, scene, q)) > 0.01
    rows = _barrier_rows_against_central_differences(panda, scene, q)
    assert rows > len(panda.self_pairs) > 0  # the ball's pairs and the self pairs


def _coal_distances(robot: Robot, scene: Scene, q: np.ndarray) -> np.ndarray:
    from previewctl.bench.pink import barrier_geometry

    geometry, _ = barrier_geometry(robot, scene)
    gdata = geometry.createData()
    pin.computeDistances(robot.model, robot.model.createData(), geometry, gdata, q)
    return np.array([r.min_distance for r in gdata.distanceResults])


def test_the_sweep_runs_pink_under_the_qp_only_and_once_per_scene() -> None:
    needs_pink()
    sweep = Sweep(robots=("planar4",), scenes=2, controllers=("qp", "pink", "pink-g100", "multi"), seeds=(0, 1))
    runs = {(r.scene, r.seed, r.controller, r.execution) for r in sweep.runs()}
    assert {(s, c, e) for s, _, c, e in runs if c.startswith("pink")} == {
        (s, name, EXECUTION) for s in (0, 1) for name in BARRIER_GAINS}
    assert all(seed == 0 for _, seed, c, _ in runs if c.startswith("pink"))
    assert not Sweep(controllers=("pink",), executions=("pseudoinverse",)).runs()


def test_an_unknown_controller_lists_the_pink_baselines() -> None:
    listed = r"unknown controller 'pinky'; valid: none, .*, oracle, pink, pink-g100$"
    with pytest.raises(UnknownNameError, match=listed):
        Sweep(controllers=("pinky",))
    with pytest.raises(UnknownNameError, match=r"unknown pink baseline 'pink-g5'; valid: pink, pink-g100$"):
        barrier_gain("pink-g5")


def test_bench_without_pink_is_one_line_naming_the_bench_extra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "pink", None)  # `import pink` fails as if it were not installed
    assert main(["bench", "--controller", "qp,pink", "--scenes", "1", "--out", str(tmp_path / "b")]) == 2
    assert capsys.readouterr().err == ("previewctl: error: the pink baseline needs pink, which is not installed: "
                                       "pip install 'previewctl[bench]'\n")
    assert not (tmp_path / "b").exists()  # refused before a cluster or a folder
    scenario = _disc_scenario()
    with pytest.raises(MissingExtraError, match=r"^the pink baseline needs pink"):
        make_pink_controller("pink", scenario.robot, scenario.path, scenario.scene, scenario.controller.params, 0.01)


def _record(scene: int, controller: str, ok: bool, seed: int = 0) -> dict[str, object]:
    record: dict[str, object] = {
        "robot": "planar4", "scene": scene, "seed": seed, "controller": controller, "execution": "qp",
        "success_1mm": ok, "success_5mm": ok, "collision_free": ok, "self_collision_free": True,
        "max_hand_error": 1e-4, "cycle_time_median": 1e-3, "cycle_time_p95": 2e-3, "wall_time": 1.0, "cpu_time": 0.5}
    if controller in BARRIER_GAINS:
        record |= {"cycle_time_median": 4e-3, "pink_time_median": 3e-3, "pink_time_p95": 5e-3,
                   "pink_no_solution": scene}
    return record


def test_report_sets_pink_beside_qp_and_preview_against_pink_with_a_note(tmp_path: Path) -> None:
    records = [_record(0, "qp", False), _record(0, "pink", True), _record(0, "multi", True),
               _record(1, "qp", True), _record(1, "pink", False), _record(1, "multi", True),
               _record(2, "qp", True), _record(2, "pink", True), _record(2, "multi", False)]
    text = write_report(records, [], tmp_path)[0].read_text()
    assert "| pink | qp | 3 | 67% | 67% | 67% | 100% | 0.10 | 4.00 / 2.00 | 0.5 |" in text
    assert "## Preview and pink against the `qp` baseline" in text
    assert "| planar4 | pink | qp | 0:0 | 1:0 |" in text and "| planar4 | multi | qp | 0:0 | 2:0 |" in text
    assert "## Preview against the `pink` baseline" in text
    assert "| planar4 | multi | qp | 1:0 | 2:0 |" in text.split("against the `pink` baseline")[1]
    assert "`pink` γ = 20 1/s" in text and "pink-g100" not in text
    assert "does not know how fast an obstacle comes" in text
    assert "`previewctl bench --robot planar4 --scenes 3 --scene-seed 0 --controller qp,multi,pink --execution qp` |" \
        in text
    assert "| planar4 | pink | 3 | 4.00 | 3.00 | 3 |" in text and "| planar4 | qp | 3 | 1.00 | - | - |" in text
    plain = write_report([r for r in records if r["controller"] != "pink"], [], tmp_path)[0].read_text()
    assert "pink" not in plain and "## Preview against the `qp` baseline" in plain
