"""Tests of :mod:`previewctl.bench.profiles` and :mod:`previewctl.bench.robots`: the bench on an arm it has no
hand-written profile for (a URDF file written here, built from primitives), its name, seed and hash in the results,
and its bad input."""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from helpers import arm_urdf

from previewctl.bench.profiles import PROFILES, TEMPLATES, derived_profile
from previewctl.bench.results import read_records
from previewctl.bench.robots import cached_robot, profile, robot_label, urdf_digest
from previewctl.bench.runs import settings_hash
from previewctl.bench.scenes import draw_document, generate
from previewctl.bench.settings import SceneSettings
from previewctl.bench.sweep import Sweep
from previewctl.cli.main import main
from previewctl.errors import ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Scene

ROOT = Path(__file__).resolve().parents[1]
SHORT = SceneSettings(duration=3.0, witness_samples=64)
ARM7_REACH = 0.3 + 0.32 + 0.32 + 0.2 + 0.1 - 0.3
"""[m] from the first joint (0.3 m above the base) to the hand of :func:`helpers.arm_urdf`'s arm, stretched."""


def planar_urdf(joints: int) -> str:
    """URDF text of a planar arm of ``joints`` 0.5 m links about z (cylinders in the plane), hand frame ``tip``."""
    parts = ['<?xml version="1.0"?>', f'<robot name="planar{joints}">', '  <link name="link0"/>']
    for k in range(1, joints + 1):
        offset = 0.0 if k == 1 else 0.5
        parts += [f'  <joint name="joint{k}" type="revolute"><parent link="link{k - 1}"/><child link="link{k}"/>',
                  f'    <origin xyz="{offset} 0 0"/><axis xyz="0 0 1"/>',
                  '    <limit lower="-6.28" upper="6.28" effort="50" velocity="1.0"/></joint>',
                  f'  <link name="link{k}"><collision><origin xyz="0.25 0 0" rpy="0 1.5707963267948966 0"/>',
                  '    <geometry><cylinder radius="0.03" length="0.5"/></geometry></collision></link>']
    parts += [f'  <joint name="tip_joint" type="fixed"><parent link="link{joints}"/><child link="tip"/>',
              '    <origin xyz="0.5 0 0"/></joint>', '  <link name="tip"/>', "</robot>"]
    return "\n".join(parts) + "\n"


@pytest.fixture(scope="module")
def arm7_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("arms") / "arm7.urdf"
    path.write_text(arm_urdf())
    return path


def _hand(arm: Robot, q: np.ndarray) -> np.ndarray:
    data = arm.model.createData()
    pin.framesForwardKinematics(arm.model, data, q)
    return np.array(data.oMf[arm.tip_frame_id].translation)


def test_planar4_derives_its_hand_written_profile_but_the_nominal_pose(planar4: Robot) -> None:
    """The planar template scaled by planar4's own reach (3 m) is the template: the rule reproduces it."""
    assert profile("planar4") is PROFILES["planar4"]  # the shipped robots keep their hand-written profiles
    derived = derived_profile(planar4)
    assert dataclasses.replace(derived, q0_center=PROFILES["planar4"].q0_center) == PROFILES["planar4"]


def test_derived_profile_scales_the_panda_template_by_the_reach_and_starts_where_the_arm_is_free(
        arm7_file: Path) -> None:
    arm = cached_robot(str(arm7_file))
    prof = derived_profile(arm)
    template, k = PROFILES["panda"], ARM7_REACH / TEMPLATES[False][1]
    for name in ("reach", "height", "segment_length", "radius", "speed"):
        assert getattr(prof, name) == pytest.approx(tuple(k * v for v in getattr(template, name)), abs=1e-4), name
    assert (prof.segments, prof.duration, prof.controller, prof.q0_spread) == (
        template.segments, template.duration, template.controller, (0.4,) * 7)
    # the nominal pose: no self-collision, the hand in the workspace, the q0 box within the joint limits, and more
    # avoidance manipulability than most configurations
    q0 = np.array(prof.q0_center)
    found = Evaluator(arm, Scene(()))(q0, 0.0)
    hand = _hand(arm, q0)
    assert not found.self_collision[0]
    assert prof.reach[0] <= np.hypot(hand[0], hand[1]) <= prof.reach[1]
    assert prof.height is not None and prof.height[0] <= hand[2] <= prof.height[1]
    assert np.all(np.abs(q0) <= 2.6 - 0.4 + 1e-4)
    others = Evaluator(arm, Scene(()))(arm.random_configurations(np.random.default_rng(5), 200), 0.0).amsi
    assert found.amsi[0] > np.quantile(others, 0.9)


def test_a_continuous_joint_is_drawn_as_an_angle_and_stored_as_its_cos_sin_pair(tmp_path: Path) -> None:
    path = tmp_path / "arm7c.urdf"
    path.write_text(arm_urdf().replace('name="joint1" type="revolute"', 'name="joint1" type="continuous"'))
    arm = cached_robot(str(path))
    assert (arm.nq, arm.nv) == (8, 7)
    prof = profile(str(path))
    assert len(prof.q0_center) == 7 and all(abs(v) <= 2.2 + 1e-4 for v in prof.q0_center[1:])
    document = draw_document(arm, str(path), prof, np.random.default_rng(0), SHORT, name="x")
    q0 = np.array(document["robot"]["q0"])
    angles = arm.angles_of(q0[None, :])[0]
    assert q0.shape == (8,) and np.hypot(q0[0], q0[1]) == pytest.approx(1.0)
    assert np.all(np.abs(angles - np.array(prof.q0_center)) <= 0.4 + 1e-9)


def test_a_planar_arm_of_three_joints_gets_planar4s_profile_at_half_the_scale(tmp_path: Path) -> None:
    path = tmp_path / "planar3.urdf"
    path.write_text(planar_urdf(3))
    prof = profile(str(path))
    assert prof.height is None and prof.reach == pytest.approx((0.5, 1.3)) and prof.radius == (0.04, 0.075)
    scene = generate(str(path), 0, 0, SHORT)
    assert "reachability DP" in scene.witness and "the oracle followed it" in scene.witness


def test_a_urdf_scene_passes_its_witness_and_a_moved_file_draws_the_same_scene(
        arm7_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    scene = generate(str(arm7_file), 0, 0, SHORT)
    digest = urdf_digest(str(arm7_file))
    assert digest is not None and len(digest) == 12
    assert scene.document["name"] == f"arm7-{digest[:8]}_000_s0" == f"{robot_label(str(arm7_file))}_000_s0"
    assert scene.document["robot"]["source"] == str(arm7_file)
    assert "; the oracle followed it (max hand error" in scene.witness
    assert scene.document["obstacles"][0]["shape"] == "sphere"
    # a copy elsewhere, named relative to the working folder: the same label, so the same scene
    (tmp_path / "elsewhere").mkdir()
    moved = tmp_path / "elsewhere" / "arm7.urdf"
    shutil.copy(arm7_file, moved)
    monkeypatch.chdir(tmp_path)
    assert Sweep(robots=(os.path.join("elsewhere", "arm7.urdf"),)).robots == (str(moved),)
    again = generate(os.path.join("elsewhere", "arm7.urdf"), 0, 0, SHORT)
    assert again.document["robot"]["source"] == str(moved)
    assert {**again.document, "robot": scene.document["robot"]} == scene.document
    # an edited URDF is another robot: another label, another settings hash
    before = settings_hash(str(moved), 0, SHORT)
    moved.write_text(moved.read_text().replace("<robot ", "<!-- edited -->\n<robot "))
    assert robot_label(str(moved)) != robot_label(str(arm7_file))
    assert settings_hash(str(moved), 0, SHORT) != before


def test_bench_runs_on_a_urdf_file_end_to_end(
        arm7_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("PYTHONPATH", str(ROOT))  # the worker processes import this worktree's previewctl
    out = tmp_path / "bench"
    assert main(["bench", "--robot", str(arm7_file), "--scenes", "1", "--duration", "3", "--controllers", "none,qp",
                 "--workers", "1", "--keep", "1", "--out", str(out)]) == 0
    assert "2 runs done" in capsys.readouterr().out
    records = read_records(out / "results.jsonl")
    assert sorted((r["robot"], r["controller"], r["execution"]) for r in records) == [
        (str(arm7_file), "none", "pseudoinverse"), (str(arm7_file), "qp", "qp")]
    assert {r["settings"] for r in records} == {settings_hash(str(arm7_file), 0, SceneSettings(duration=3.0))}
    (scene,) = read_records(out / "scenes.jsonl")
    assert scene["robot"] == str(arm7_file) and "the oracle followed it" in scene["witness"]
    assert str(arm7_file) in (out / "report.md").read_text()
    label = robot_label(str(arm7_file))
    assert sorted(p.name for p in (out / "runs").iterdir()) == [f"{label}_000_s0_none_pseudoinverse",
                                                                f"{label}_000_s0_qp_qp"]


@pytest.mark.parametrize(("write", "message"), [
    (None, r"URDF file '.*missing\.urdf' does not exist; valid: planar4, panda, xarm7, a URDF file, any arm"),
    ("some notes\n", r"URDF file '.*arm\.urdf' is not valid XML"),
    ("<sdf version='1.6'/>\n", r"URDF file '.*arm\.urdf' has root <sdf>, expected <robot>"),
    (arm_urdf((("0 0 1", 0.3), ("0 1 0", 0.0), ("0 1 0", 0.4)), name="arm3"),
     r"robot 'arm' has no redundancy: 3 joints for a 3-row 'position' task; valid: arms with more joints than task "
     r"rows"),
    (planar_urdf(5), r"robot 'arm' is a planar arm of 5 joints; valid planar arms: 3 or 4 joints"),
    (planar_urdf(2), r"robot 'arm' has no redundancy: 2 joints for a 2-row 'planar' task"),
])
def test_bench_robot_bad_input_is_one_line_and_exit_2(
        write: str | None, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / ("missing.urdf" if write is None else "arm.urdf")
    if write is not None:
        path.write_text(write)
    out = tmp_path / "out"
    assert main(["bench", "--robot", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and re.search(message, err), err
    assert not out.exists()


def test_a_sweep_refuses_an_arm_without_redundancy(tmp_path: Path) -> None:
    path = tmp_path / "arm3.urdf"
    path.write_text(arm_urdf((("0 0 1", 0.3), ("0 1 0", 0.0), ("0 1 0", 0.4)), name="arm3"))
    with pytest.raises(ParameterError, match=r"^robot 'arm3' has no redundancy: 3 joints for a 3-row 'position' task"):
        Sweep(robots=(str(path),))
