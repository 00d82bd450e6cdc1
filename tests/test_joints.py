"""Tests of :mod:`previewctl.robot.joints`: the joint facts computed once per robot, and their readers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from previewctl import load_robot
from previewctl.control.nullspace import wrapped_difference
from previewctl.control.tracking import joint_velocity_bounds
from previewctl.robot.joints import JointFacts
from previewctl.robot.model import Robot

# A base link, then a continuous joint (nq = 2, nv = 1), a revolute joint limited to +-1 rad, a prismatic
# joint and a revolute joint limited to +-4 rad (more than a full turn); a small ball on the last link
# (an arm without collision geometry is refused).
MIXED_URDF = """<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"/>
  <link name="l1"/><link name="l2"/><link name="l3"/>
  <link name="l4"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <joint name="spin" type="continuous">
    <parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit effort="1" velocity="2.0"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1.0" upper="1.0" effort="1" velocity="1.5"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0.0" upper="0.2" effort="1" velocity="0.5"/>
  </joint>
  <joint name="wrist" type="revolute">
    <parent link="l3"/><child link="l4"/><origin xyz="0.1 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-4.0" upper="4.0" effort="1" velocity="3.0"/>
  </joint>
  <link name="tool"/>
  <joint name="tool_fixed" type="fixed"><parent link="l4"/><child link="tool"/><origin xyz="0.1 0 0"/></joint>
</robot>
"""


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> Robot:
    path = Path(tmp_path_factory.mktemp("urdf")) / "mixed.urdf"
    path.write_text(MIXED_URDF)
    return load_robot(path, tip="tool")


def test_planar4_every_joint_turns_a_full_circle(planar4: Robot) -> None:
    facts = planar4.joints
    assert facts.revolute.all() and facts.full_turn.all() and not facts.continuous.any()
    # limits of +-2 pi: finite (bounded) yet more than a turn
    assert facts.bounded.all()
    np.testing.assert_array_equal(facts.lower, -2 * np.pi)
    np.testing.assert_array_equal(facts.upper, 2 * np.pi)
    np.testing.assert_array_equal(facts.q_index, np.arange(4))
    assert facts.vector_space


def test_panda_joints_are_bounded(panda: Robot) -> None:
    facts = panda.joints
    assert facts.revolute.all() and facts.bounded.all()
    assert not facts.full_turn.any() and not facts.continuous.any()
    np.testing.assert_array_equal(facts.lower, panda.model.lowerPositionLimit)
    np.testing.assert_array_equal(facts.upper, panda.model.upperPositionLimit)
    np.testing.assert_array_equal(facts.velocity, panda.model.velocityLimit)
    np.testing.assert_array_equal(facts.q_index, np.arange(7))
    assert facts.vector_space


def test_continuous_joint_facts(mixed: Robot) -> None:
    assert (mixed.nq, mixed.nv) == (5, 4)
    facts = mixed.joints
    np.testing.assert_array_equal(facts.continuous, [True, False, False, False])
    np.testing.assert_array_equal(facts.revolute, [True, True, False, True])
    np.testing.assert_array_equal(facts.full_turn, [True, False, False, True])
    np.testing.assert_array_equal(facts.bounded, [False, True, True, True])
    np.testing.assert_array_equal(facts.lower, [-np.inf, -1.0, 0.0, -4.0])
    np.testing.assert_array_equal(facts.upper, [np.inf, 1.0, 0.2, 4.0])
    np.testing.assert_array_equal(facts.velocity, [2.0, 1.5, 0.5, 3.0])
    np.testing.assert_array_equal(facts.q_index, [-1, 2, 3, 4])
    assert mixed.joint_names_by_q() == ("spin", "spin", "elbow", "slide", "wrist")
    assert not facts.vector_space


def test_kinova_continuous_joints_are_full_turns(kinova: Robot) -> None:
    facts = kinova.joints
    two_entries = [kinova.model.joints[j].nq == 2 for j in range(1, kinova.model.njoints)]
    np.testing.assert_array_equal(facts.continuous, two_entries)
    assert facts.full_turn[facts.continuous].all()
    assert (facts.q_index[facts.continuous] == -1).all()
    assert facts.bounded[~facts.continuous].all()


def test_facts_are_read_only(mixed: Robot) -> None:
    with pytest.raises(ValueError, match="read-only"):
        mixed.joints.lower[0] = 0.0
    assert isinstance(JointFacts.of(mixed.model), JointFacts)


def test_wrapped_difference_wraps_only_revolute_full_turns(mixed: Robot) -> None:
    q = mixed.configuration_from_angles(np.array([3.0, 0.9, 0.1, 3.5]))
    target = mixed.configuration_from_angles(np.array([-3.0, -0.9, 0.0, -3.5]))
    diff = wrapped_difference(mixed, q, target)
    plain = pin.difference(mixed.model, q, target)
    # continuous: pin.difference already takes the short way; bounded joints: no wrapping
    np.testing.assert_allclose(diff[:3], plain[:3], atol=1e-12)
    np.testing.assert_allclose(plain[0], 2 * np.pi - 6.0, atol=1e-12)
    np.testing.assert_allclose(diff[3], 2 * np.pi - 7.0, atol=1e-12)  # -7 rad is the long way round


def test_velocity_bounds_leave_continuous_joints_free(mixed: Robot) -> None:
    q = mixed.configuration_from_angles(np.array([1.0, 0.5, 0.1, 0.0]))
    low, high = joint_velocity_bounds(mixed, q, 0.1)
    assert low[0] == -np.inf and high[0] == np.inf
    np.testing.assert_allclose(low[1:], (np.array([-1.0, 0.0, -4.0]) - [0.5, 0.1, 0.0]) / 0.1)
    np.testing.assert_allclose(high[1:], (np.array([1.0, 0.2, 4.0]) - [0.5, 0.1, 0.0]) / 0.1)
