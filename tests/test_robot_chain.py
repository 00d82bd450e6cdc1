"""Which joints are the arm (previewctl/robot/chain.py): floating bases and grippers locked, trees refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from previewctl.cli import robots as robots_command
from previewctl.cli.main import main
from previewctl.errors import RobotLoadError
from previewctl.index.load import load_robot

Joint = tuple[str, str, str, str, str]
"""(name, type, parent link, child link, origin xyz)."""


def urdf(tmp_path: Path, joints: list[Joint], name: str = "tree") -> Path:
    """A URDF of links (a small box on each) joined by ``joints``: about z if named ``shoulder``, else about y."""
    links = {"base"} | {j[3] for j in joints}
    box = '<collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision>'
    parts = [f'<robot name="{name}">'] + [f'<link name="{link}">{box}</link>' for link in sorted(links)]
    for joint, kind, parent, child, xyz in joints:
        limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>' if kind in ("revolute", "prismatic") else ""
        parts.append(f'<joint name="{joint}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
                     f'<origin xyz="{xyz}"/><axis xyz="{"0 0 1" if joint == "shoulder" else "0 1 0"}"/>{limit}</joint>')
    path = tmp_path / f"{name}.urdf"
    path.write_text("\n".join([*parts, "</robot>"]))
    return path


ARM: list[Joint] = [
    ("shoulder", "revolute", "base", "l1", "0 0 0.1"),
    ("elbow", "revolute", "l1", "l2", "0.1 0 0.4"),
    ("wrist", "revolute", "l2", "l3", "0 0 0.4"),
    ("flange_joint", "fixed", "l3", "flange", "0 0 0.1"),
]


def test_gripper_joints_are_locked_and_the_hand_is_the_gripper_base(tmp_path: Path) -> None:
    path = urdf(tmp_path, [*ARM, ("jointGripper", "revolute", "flange", "jaw", "0 0 0.05"),
                           ("jaw_tip_joint", "fixed", "jaw", "jaw_tip", "0 0 0.1")])
    robot = load_robot(path)
    assert robot.joint_names == ("shoulder", "elbow", "wrist")
    assert robot.tip_frame == "flange"  # where the gripper hangs, not the jaw's tip
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.zeros(3))
    np.testing.assert_allclose(data.oMf[robot.tip_frame_id].translation, [0.1, 0.0, 1.0], atol=1e-12)


def test_unnamed_finger_pair_is_locked(tmp_path: Path) -> None:
    path = urdf(tmp_path, [*ARM, ("left", "prismatic", "flange", "pad_l", "0 0.02 0.05"),
                           ("right", "prismatic", "flange", "pad_r", "0 -0.02 0.05")])
    assert load_robot(path).joint_names == ("shoulder", "elbow", "wrist")


def test_floating_base_is_locked(tmp_path: Path) -> None:
    path = urdf(tmp_path, [("root_joint", "floating", "base", "trunk", "0 0 0"),
                           *[(n, k, "trunk" if p == "base" else p, c, xyz) for n, k, p, c, xyz in ARM]])
    robot = load_robot(path)
    assert robot.joint_names == ("shoulder", "elbow", "wrist")


def test_legs_are_refused_with_their_chains(tmp_path: Path) -> None:
    legs = [(f"{side}_hip", "revolute", "base", f"{side}_thigh", "0 0 -0.1") for side in ("left", "right")]
    legs += [(f"{side}_knee", "revolute", f"{side}_thigh", f"{side}_shin", "0 0 -0.4") for side in ("left", "right")]
    with pytest.raises(RobotLoadError, match=r"robot 'tree' is not a serial arm: its joints branch into 2 chains "
                       r"\(left_hip..left_knee, right_hip..right_knee\); keep one with lock="):
        load_robot(urdf(tmp_path, legs))
    with pytest.raises(RobotLoadError, match="has no control point"):  # one leg kept: past the branch check
        load_robot(urdf(tmp_path, legs), lock=["right_hip", "right_knee"])


def test_a_drone_is_refused(tmp_path: Path) -> None:
    path = urdf(tmp_path, [("root_joint", "floating", "base", "body", "0 0 0"),
                           ("rotor_joint", "fixed", "body", "rotor", "0.2 0 0")])
    with pytest.raises(RobotLoadError, match="robot 'tree' is not an arm: no joint is left to move once the "
                       "floating base root_joint are locked"):
        load_robot(path)


def test_an_arm_without_control_point_is_refused(tmp_path: Path) -> None:
    path = urdf(tmp_path, [("yaw", "revolute", "base", "l1", "0 0 0"), ("pitch", "revolute", "l1", "l2", "0 0 0")])
    with pytest.raises(RobotLoadError, match="has no control point: no joint origin between the base and the hand "
                       "'l2' moves"):
        load_robot(path, task="planar")


@pytest.mark.parametrize(("name", "joints", "tip"), [
    ("z1", ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6"), "gripperStator"),
    ("so100", ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"), "gripper"),
    ("talos_arm", tuple(f"arm_left_{k}_joint" for k in range(2, 8)), "gripper_left_base_link"),
])
def test_example_arms_with_grippers(name: str, joints: tuple[str, ...], tip: str) -> None:
    """The issue's cases: z1's jointGripper, so100's free-flyer and gripper, talos_arm's gripper."""
    robot = load_robot(name, geometry="capsules")
    assert robot.joint_names == joints
    assert robot.tip_frame == tip


@pytest.mark.parametrize(("name", "why"), [
    ("hector", "is not an arm: its only joint is a floating base"),
    ("anymal_c", "is not a serial arm: its joints branch into 4 chains"),
    ("talos_legs", "is not a serial arm: its joints branch into 2 chains"),
    ("double_pendulum", "has no control point"),
    ("cassie", "example-robot-data could not load 'cassie'"),
])
def test_example_robots_that_are_not_arms(name: str, why: str) -> None:
    with pytest.raises(RobotLoadError, match=f"robot '{name}' {why}" if "example" not in why else why):
        load_robot(name)


def test_robots_command_lists_arms_and_says_why_the_others_are_not(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(robots_command, "example_robot_names", lambda: ("z1", "hector", "anymal"))
    assert main(["robots", "--all", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    arms = [(r["name"], r["dof"], r["tip"]) for r in report["arms"]]
    assert arms == [("planar4", 4, "tip"), ("z1", 6, "gripperStator")]
    # how many link pairs each arm checks against itself: none for planar4 (its SRDF), sampled for z1
    assert [(r["self_pairs"], r["self_pairs_from"]) for r in report["arms"]] == [(0, "SRDF"), (14, "sampled")]
    assert [r["name"] for r in report["not_arms"]] == ["hector", "anymal"]
    assert main(["robots", "--all"]) == 0
    listing = capsys.readouterr().out
    assert "2 more do not load as arms (hector, anymal); --verbose says why" in listing
    assert "self pairs (link pairs checked)" in listing and "14 (sampled)" in listing
    assert main(["robots", "--all", "--verbose"]) == 0
    out = capsys.readouterr().out
    assert "not arms (2):" in out
    assert "robot 'hector' is not an arm: its only joint is a floating base" in out
    assert "robot 'anymal' is not a serial arm: its joints branch into 4 chains" in out
