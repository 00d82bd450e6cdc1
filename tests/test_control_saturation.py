"""Joint limits in the pseudo-inverse execution: saturation in the null space (SNS) and limit avoidance."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from helpers import control_state, track

from previewctl.control.base import ControlState
from previewctl.control.nullspace import limit_avoidance
from previewctl.control.params import ControllerParams
from previewctl.control.saturation import saturate, task_scaling
from previewctl.control.tracking import damped_pseudo_inverse, velocity_box
from previewctl.index.amsi import null_space_projector
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import kinematics
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import scenario_from_dict
from previewctl.types import Array


def exact_inverse(J: Array) -> Array:
    return np.linalg.pinv(J)


def planar_jacobian(q: Array, lengths: Array) -> Array:
    """Closed-form hand Jacobian ``(2, n)`` of a planar chain with link ``lengths`` [m]."""
    angles = np.cumsum(q)
    J = np.zeros((2, len(q)))
    for j in range(len(q)):
        J[0, j] = -np.sum(lengths[j:] * np.sin(angles[j:]))
        J[1, j] = np.sum(lengths[j:] * np.cos(angles[j:]))
    return J


def test_a_joint_at_its_limit_is_held_and_the_others_keep_the_hand_on_the_path() -> None:
    # planar 3R arm, unit links; joint 1 sits at its upper limit (it may not move up: high = 0)
    J = planar_jacobian(np.array([0.3, 0.9, -0.6]), np.ones(3))
    xdot = np.array([0.2, 0.3])
    free_solution = np.linalg.pinv(J) @ xdot
    assert free_solution[0] > 0, "the minimum-norm solution should push joint 1 past its limit"
    low, high = np.full(3, -10.0), np.full(3, 10.0)
    high[0] = 0.0
    result = saturate(J, xdot, np.zeros(3), low, high, exact_inverse)
    expected = np.concatenate([[0.0], np.linalg.solve(J[:, 1:], xdot)])  # closed form: 2 joints, 2 rows
    np.testing.assert_allclose(result.qdot, expected, atol=1e-12)
    np.testing.assert_allclose(J @ result.qdot, xdot, atol=1e-12)
    assert result.task_scale == 1.0
    assert result.saturated.tolist() == [True, False, False]


def test_an_infeasible_task_is_scaled_along_its_direction() -> None:
    # 2R arm (no redundancy): q̇ = s J⁻¹ ẋ with s the largest factor that fits every speed bound
    J = planar_jacobian(np.array([0.4, 1.1]), np.array([1.0, 0.8]))
    xdot = np.array([1.0, -0.5])
    full = np.linalg.solve(J, xdot)
    bound = 0.5 * np.abs(full).min()
    low, high = np.full(2, -bound), np.full(2, bound)
    result = saturate(J, xdot, np.zeros(2), low, high, exact_inverse)
    s = float(np.min(bound / np.abs(full)))
    assert result.task_scale == pytest.approx(s, rel=1e-12)
    np.testing.assert_allclose(J @ result.qdot, s * xdot, atol=1e-12)
    assert np.all(np.abs(result.qdot) <= bound * (1 + 1e-12))


def test_task_scaling_closed_form() -> None:
    a, b = np.array([2.0, -1.0, 0.0]), np.array([0.5, 0.0, 0.1])
    low, high = np.array([-1.0, -0.4, -1.0]), np.array([1.0, 1.0, 1.0])
    # joint 1: 2 s + 0.5 <= 1 -> s <= 0.25; joint 2: -s >= -0.4 -> s <= 0.4
    assert task_scaling(a, b, low, high) == (pytest.approx(0.25), 0)
    # a joint out of its box whatever s: nothing fits, and that joint is the one to saturate
    assert task_scaling(a, np.array([0.0, 0.0, 2.0]), low, high) == (0.0, 2)


def test_random_saturations_stay_in_the_box_and_keep_the_task_direction() -> None:
    rng = np.random.default_rng(3)
    kinds = set()
    for _ in range(200):
        J = rng.normal(size=(2, 5))
        xdot, secondary = rng.normal(size=2), rng.normal(size=5)
        low, high = -rng.uniform(0.0, 1.0, 5), rng.uniform(0.0, 1.0, 5)
        result = saturate(J, xdot, secondary, low, high, exact_inverse)
        assert np.all(result.qdot >= low - 1e-12) and np.all(result.qdot <= high + 1e-12)
        assert 0.0 <= result.task_scale <= 1.0
        # the hand moves along ẋ at s times its speed: the secondary term never moves it
        np.testing.assert_allclose(J @ result.qdot, result.task_scale * xdot, atol=1e-10)
        sat = result.saturated
        assert np.all((result.qdot[sat] == high[sat]) | (result.qdot[sat] == low[sat])), "saturated joints at a bound"
        kinds.add((bool(sat.any()), result.task_scale < 1.0))
    assert kinds == {(False, False), (True, False), (True, True)}, "every regime should be drawn"


# ----------------------------------------------------- within eq. 19 and the pseudo-inverse execution


def _state(robot: Robot, q: Array, velocity: Array, t: float = 0.0) -> ControlState:
    start = kinematics(robot, q[None, :]).tip_position[0]
    path = HandPath(np.array([start, start + velocity]), 1.0)
    return control_state(robot, q, path, t=t, frame_due=False)


def test_track_is_the_plain_eq19_when_no_limit_is_active(panda: Robot) -> None:
    params = ControllerParams(step_correction=False)  # eq. 19 as printed
    lo, hi = panda.lower_limits, panda.upper_limits
    rng = np.random.default_rng(11)
    for _ in range(50):
        q = rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))  # outside the avoidance margin
        state = _state(panda, q, rng.normal(scale=0.05, size=3), t=0.1)
        v = rng.normal(scale=0.1, size=7)
        qdot, info = track(panda, state, v, params)
        J = state.kin.J_task[0]
        J_sharp = damped_pseudo_inverse(J, params.damping, params.singular_threshold)[0]
        xdot = state.path.velocity(0.1) + params.feedback_gain * info.reference.task_error
        old = J_sharp @ xdot + null_space_projector(J) @ v
        assert not info.executed.clamped and info.executed.scale == 1.0 and info.executed.null_scale == 1.0
        np.testing.assert_allclose(qdot, old, rtol=0, atol=1e-12)


def test_track_holds_the_hand_when_a_joint_is_at_its_limit(panda: Robot) -> None:
    q = np.array([-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785])
    q[3] = panda.upper_limits[3]  # the elbow at its upper limit
    params = ControllerParams(feedback_gain=0.0, step_correction=False)
    J = kinematics(panda, q[None, :]).J_task[0]
    pushes = np.linalg.pinv(J)[3]  # hand directions that drive the elbow up under the minimum-norm solution
    velocity = 0.1 * pushes / np.linalg.norm(pushes)
    qdot, info = track(panda, _state(panda, q, velocity), np.zeros(7), params)
    assert info.reference.qdot_task[3] > 0 and qdot[3] == 0.0 and info.executed.clamped
    np.testing.assert_allclose(J @ qdot, velocity, atol=1e-12)
    assert info.executed.scale == 1.0
    low, high = velocity_box(panda, q, 0.01)
    assert np.all(qdot >= low) and np.all(qdot <= high)


def test_limit_avoidance_is_minus_the_gradient_of_the_margin_cost(kinova: Robot) -> None:
    params = ControllerParams(limit_gain=2.0, limit_margin=0.1)
    facts = kinova.joints
    angles = np.array([0.3, facts.lower[1] + 0.2, facts.upper[2] - 0.1, 1.0, 3.0, -2.0])
    q = kinova.configuration_from_angles(angles)

    def cost(a: Array) -> float:
        qq = kinova.configuration_from_angles(a)[facts.q_index]
        bounded = np.isfinite(facts.lower) & np.isfinite(facts.upper)
        rho = 0.1 * np.where(bounded, facts.upper - facts.lower, 0.0)
        lo_gap = np.where(bounded, np.maximum(0, rho - (qq - facts.lower)), 0.0)
        hi_gap = np.where(bounded, np.maximum(0, rho - (facts.upper - qq)), 0.0)
        return 0.5 * float(np.sum(lo_gap**2 + hi_gap**2))

    h = 1e-6
    gradient = np.array([(cost(angles + h * e) - cost(angles - h * e)) / (2 * h) for e in np.eye(6)])
    push = limit_avoidance(kinova, q, params)
    np.testing.assert_allclose(push, -2.0 * gradient, atol=1e-6)
    assert push[1] > 0 and push[2] < 0 and np.count_nonzero(push) == 2  # only the two joints in their margin
    assert not limit_avoidance(kinova, q, replace(params, limit_gain=0.0)).any()


WRIST_SRDF = """<?xml version="1.0"?>
<!-- Issue 13's start folds the Kinova's wrist: the meshes of links 3, 5 and 6 touch there (its sampled self pairs
     keep these pairs). This test is about the joint limits, not self-collision, so it leaves them out. -->
<robot name="kinova">
  <disable_collisions link1="j2s6s200_link_3" link2="j2s6s200_link_5" reason="Test"/>
  <disable_collisions link1="j2s6s200_link_3" link2="j2s6s200_link_6" reason="Test"/>
  <disable_collisions link1="j2s6s200_link_4" link2="j2s6s200_link_6" reason="Test"/>
</robot>
"""


@pytest.mark.parametrize("execution", ["pseudoinverse", "qp"])
def test_kinova_keeps_its_hand_on_the_path_with_joint_5_held_at_its_limit(kinova: Robot, execution: str,
                                                                          tmp_path: Path) -> None:
    # issue 13's case: minimum-norm tracking drives joint 5 into its 0.524 rad lower limit; clamping it
    # alone left the hand 43 mm off the path, the other joints can hold it (SNS in the pseudo-inverse, run by
    # none; the QP, run by qp, brakes joint 5 just before its limit and re-solves the task with the others)
    start = kinova.configuration_from_angles(np.array([2.48, 2.783, 3.645, -2.988, 0.574, 2.633]))
    end = kinova.configuration_from_angles(np.array([1.887, 2.739, 3.466, -2.678, -0.026, 1.981]))
    hands = kinematics(kinova, np.stack([start, end])).tip_position
    (tmp_path / "wrist.srdf").write_text(WRIST_SRDF)
    scenario = scenario_from_dict({
        "robot": {"source": "kinova", "q0": start.tolist(), "srdf": str(tmp_path / "wrist.srdf")},
        "path": {"waypoints": hands.tolist(), "duration": 4.0},
        "controller": {"name": "none" if execution == "pseudoinverse" else "qp", "execution": execution},
        "timing": {"duration": 4.5},
    })
    run = simulate(scenario, exact_evaluator=Evaluator(scenario.robot, scenario.scene))
    assert run.execution == execution
    joint5 = kinova.angles_of(run.q)[:, 4]
    assert joint5.min() == pytest.approx(kinova.joints.lower[4], abs=1e-9 if execution == "pseudoinverse" else 5e-3)
    assert (joint5 >= kinova.joints.lower[4] - 1e-9).all()
    assert run.hand_error.max() < 1e-3
