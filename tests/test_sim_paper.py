"""Tests of :mod:`previewctl.sim.paper`: the canonical planar scene end to end (``previewctl paper``)
and a short preview run."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest

from previewctl.cli.main import main
from previewctl.control.params import CONTROLLER_NAMES, ControllerSpec
from previewctl.errors import PreviewctlError
from previewctl.kinematics import kinematics
from previewctl.sim.loop import simulate
from previewctl.sim.paper import (
    CANONICAL_SCENES,
    PAPER_CONTROLLERS,
    canonical_scenario,
    paper_runs,
    run_paper_scenes,
    with_controller,
)


@pytest.mark.parametrize("name", CANONICAL_SCENES)
def test_canonical_scenes_match_the_paper_numbers(name: str) -> None:
    scenario = canonical_scenario(name)
    waypoints = np.asarray(scenario.path.waypoints)
    np.testing.assert_allclose(waypoints[0], [0.10, 1.40])  # A
    segments = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    np.testing.assert_allclose(segments, 0.75, atol=5e-4)  # five 0.75 m segments (fitted ones to 0.1 mm)
    assert len(waypoints) == 6 and scenario.path.duration == 50.0
    np.testing.assert_allclose(scenario.path.waypoint_times(), [0, 10, 20, 30, 40, 50], atol=1e-3)
    assert scenario.robot.name == "planar4" and scenario.name == name


def test_paper_controllers_use_the_paper_parameters() -> None:
    scenario = canonical_scenario("paper_planar")
    # start from values that are not the paper's (the scenario file already holds multi's), so the
    # paper's values are seen to come from with_controller, which leaves every other parameter alone
    params = dataclasses.replace(scenario.controller.params, preview_time=1.0, weights=(0.5, 0.5), gain=(3.0,))
    other = dataclasses.replace(scenario, controller=ControllerSpec("none", params))
    for name in ("none", "gradient"):
        assert with_controller(other, name).controller == ControllerSpec(name, params)
    single = with_controller(other, "single").controller.params
    assert single == dataclasses.replace(params, preview_time=10.0)  # section 7.1: t~ = 10 s
    for name in ("multi", "reach"):  # section 7.2: t~ = 5 s, k = (0.3, 0.65, 0.05)
        got = with_controller(other, name).controller.params
        assert got == dataclasses.replace(params, preview_time=5.0, weights=(0.3, 0.65, 0.05))
    # the paper's comparison covers every controller the package offers
    assert tuple(PAPER_CONTROLLERS) == CONTROLLER_NAMES
    with pytest.raises(PreviewctlError, match=r"unknown controller 'fast'; valid: none, qp, gradient, single, multi"):
        with_controller(scenario, "fast")


def test_paper_command_runs_both_canonical_scenes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Both scenes, fitted first; on the staircase the paper's eq. 19 keeps the elbow-right family and hits the trap."""
    out = tmp_path / "paper"
    report = tmp_path / "site" / "paper.md"
    argv = ["paper", "--controller", "none", "--execution", "pseudoinverse", "--out", str(out), "--no-gif",
            "--publish", str(report)]
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary) == list(CANONICAL_SCENES) == ["paper_fitted", "paper_planar"]
    assert all(list(runs) == ["none-pinv"] for runs in summary.values())
    assert json.loads((out / "paper_fitted" / "summary.json").read_text()) == summary["paper_fitted"]
    assert (out / "paper_fitted" / "none-pinv" / "run.npz").is_file()
    none = summary["paper_planar"]["none-pinv"]
    assert none["collided"] and none["collision_link"] == "link3"
    assert 28.0 < none["collision_time"] < 30.5  # link 3 meets the corner at C as the hand nears D
    assert none["max_hand_error"] < 1e-3
    assert (out / "paper_planar" / "none-pinv" / "run.npz").is_file()
    assert (out / "paper_planar" / "none-pinv" / "strobe.png").is_file()
    assert (out / "paper_planar" / "none-pinv" / "replay.html").stat().st_size > 100_000  # each run's 3-D replay
    table = capsys.readouterr().out
    assert table.index("paper_fitted (") < table.index("paper_planar (") and "link3" in table
    published = report.read_text()  # the docs' page: provenance, then one table per scene, in order
    assert re.search(r"^Generated \d{4}-\d\d-\d\dT\S+Z by `previewctl paper` at commit `\S+`, seed of each "
                     r"scenario file\.", published, re.MULTILINE)
    assert published.index("## paper_fitted") < published.index("## paper_planar")
    assert re.search(r"^\| none-pinv \| NO: collision at t = 2\d\.\d\d s \(link3\) \| 0\.\d\d \|", published,
                     re.MULTILINE)


def test_paper_publish_refuses_a_file_that_is_not_markdown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["paper", "--out", str(tmp_path), "--publish", str(tmp_path / "paper.txt")]) == 2
    assert "--publish takes a Markdown file name ending in .md, got" in capsys.readouterr().err


def test_short_multi_preview_run_tracks_without_collision() -> None:
    """The first 5 s of the paper scene with three-preview control on the GA's tracked peaks: on the path, no
    contact."""
    scenario = with_controller(canonical_scenario("paper_planar"), "multi")
    params = dataclasses.replace(scenario.controller.params, imaginary_arms="peaks")
    short = dataclasses.replace(scenario, controller=dataclasses.replace(scenario.controller, params=params),
                                timing=dataclasses.replace(scenario.timing, duration=5.0))
    result = simulate(short, "multi")
    summary = result.summary()
    assert not summary["collided"]
    assert summary["max_hand_error"] < 2e-3
    assert summary["min_S"] > 0 and summary["max_qdot_ratio"] <= 1.0 + 1e-9
    # the log keeps the imaginary arms: each puts its hand on the path at its own time t_f + i t~,
    # t_f the camera frame that computed them (targets are held between frames)
    assert result.targets.shape == (len(result.t), 3, short.robot.nq) and result.target_S.shape == (len(result.t), 3)
    frames = np.flatnonzero(result.frame_due)
    for k in (0, len(result.t) // 2, len(result.t) - 1):
        t_frame = result.t[frames[frames <= k][-1]]
        hands = kinematics(short.robot, result.targets[k]).tip_position[:, :2]
        expected = [short.path.position(t_frame + 5.0 * i) for i in (1, 2, 3)]
        np.testing.assert_allclose(hands, expected, atol=1e-6)
        assert np.all(result.target_S[k] > 0)


def test_paper_runs_label_each_distinct_run_once() -> None:
    runs = paper_runs(["none", "qp", "multi"])
    assert runs == {"qp": ("qp", "qp"), "multi": ("multi", "qp"), "none-pinv": ("none", "pseudoinverse"),
                    "multi-pinv": ("multi", "pseudoinverse")}
    # none runs under the pseudo-inverse only and qp under the QP only: asked for under the other, they do not run
    assert paper_runs(["none"], ["qp"]) == {}
    assert paper_runs(["qp"], ["pseudoinverse"]) == {}
    assert paper_runs(["none", "qp"], ["qp"]) == {"qp": ("qp", "qp")}
    assert paper_runs(["none", "qp"], ["pseudoinverse"]) == {"none-pinv": ("none", "pseudoinverse")}
    with pytest.raises(PreviewctlError, match=r"unknown execution 'fast'; valid: qp, pseudoinverse"):
        run_paper_scenes("unused", executions=["fast"])
