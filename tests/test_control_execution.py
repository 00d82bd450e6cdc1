"""Tests of :mod:`previewctl.control.execution`: eq. 19 as a constrained QP (dampers, limits, slack)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from helpers import control_state, track

import previewctl as pc
from previewctl.control.base import ControlState
from previewctl.control.execution import PseudoInverseExecution, QPExecution
from previewctl.control.params import ControllerParams, controller_runs
from previewctl.control.tracking import reference
from previewctl.errors import IgnoredSettingWarning, ParameterError
from previewctl.kinematics import kinematics
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.clearance import Clearance
from previewctl.types import Array

PINV = ControllerParams(execution="pseudoinverse")


def _state(robot: Robot, q: Array, path: HandPath, dt: float = 0.01, t: float = 0.0) -> ControlState:
    return control_state(robot, q, path, t=t, dt=dt)


def _hand_path(robot: Robot, q: Array, velocity: Array) -> HandPath:
    """A straight 1 s path from the hand at ``q`` with constant ``velocity`` [m/s]."""
    start = kinematics(robot, q[None, :]).tip_position[0][: 2 if robot.task == "planar" else 3]
    return HandPath(np.array([start, start + velocity]), 1.0)


@pytest.mark.parametrize("name", ["planar4", "panda"])
def test_without_active_constraints_the_qp_is_eq_19(name: str, planar4: Robot, panda: Robot) -> None:
    """No obstacle near, joints mid-range: the QP's command equals the pseudo-inverse eq. 19 to 1e-8, also
    with a null-space input."""
    robot = planar4 if name == "planar4" else panda
    rng = np.random.default_rng(3)
    lo, hi = robot.joints.lower, robot.joints.upper
    execution = QPExecution(robot, pc.Scene(), ControllerParams())
    for _ in range(10):
        q = lo + (hi - lo) * rng.uniform(0.3, 0.7, robot.nq)
        path = _hand_path(robot, q, rng.normal(0.0, 0.05, 2 if name == "planar4" else 3))
        state = _state(robot, q, path)
        v = rng.normal(0.0, 0.1, robot.nv)
        expected, info = track(robot, state, v, PINV)
        assert info.executed.scale == 1.0 and not info.executed.clamped  # no limit active
        assert info.executed.null_scale == 1.0
        report = execution(state, info.reference)
        np.testing.assert_allclose(report.qdot, expected, atol=1e-8)
        assert report.execution == "qp" and report.dampers == 0 and report.slack == 0.0


def _near_ball(robot: Robot) -> tuple[Array, pc.Scene]:
    """A configuration of ``robot`` and a scene with a ball moving at 0.3 m/s at its elbow, 0.3 m above it at t = 0."""
    q = np.array([0.3, -0.4, 0.2, -1.8, 0.1, 1.6, 0.5])
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    elbow = data.oMi[4].translation
    motion = pc.ConstantVelocity(elbow + np.array([0.0, 0.0, 0.3]), np.array([0.0, 0.0, -0.3]))
    return q, pc.Scene((pc.Obstacle("ball", pc.Sphere(0.05), motion),))


def test_each_damper_row_matches_finite_differences_of_the_coal_distance(panda: Robot) -> None:
    """``ḋ_k = n_kᵀ (v_obs − J_k q̇)``, the rate the damper bounds, against central differences of Coal's distance
    over ``(q + q̇ ε, t + ε)``."""
    q, scene = _near_ball(panda)
    execution = QPExecution(panda, scene, ControllerParams())
    t, eps = 0.6, 1e-6
    rows = execution.dampers(q, t)
    n = rows.pairs.size  # the obstacle rows come first
    assert n >= 2, "the ball should be within the influence distance of several links"
    obstacle_rate = rows.h[:n] - ControllerParams().damper_gain * (rows.distance[:n] - 0.02) / (0.3 - 0.02)  # n·v_obs
    clearance, data = Clearance(panda, scene), panda.model.createData()

    def distances(qq: Array, tt: float) -> Array:
        pin.forwardKinematics(panda.model, data, qq)
        clearance.set_time(tt)
        return np.array(clearance.pair_distances(data))[rows.pairs]

    for qdot in np.random.default_rng(0).normal(0.0, 0.5, (3, panda.nv)):
        plus = distances(pin.integrate(panda.model, q, qdot * eps), t + eps)
        minus = distances(pin.integrate(panda.model, q, -qdot * eps), t - eps)
        rate = (plus - minus) / (2 * eps)
        np.testing.assert_allclose(rate, obstacle_rate - rows.G[:n] @ qdot, atol=1e-5)


def test_each_self_damper_row_matches_finite_differences_of_the_coal_distance(panda: Robot) -> None:
    """A self pair's two links both move: ``ḋ_k = n_kᵀ (J_b − J_a) q̇ = −G_k q̇``, against central differences of
    Coal's distance between the pair's two geometries, at configurations where some pairs are near each other."""
    params = ControllerParams()
    execution = QPExecution(panda, pc.Scene(), params)
    self_clearance, data = execution.clearance.self_clearance, panda.model.createData()
    rng = np.random.default_rng(3)
    checked = 0
    for q in panda.random_configurations(rng, 200):
        rows = execution.dampers(q, 0.0)
        near = (rows.distance > 0.005) & (rows.distance < params.self_influence_distance)
        if not near.any():
            continue
        np.testing.assert_allclose(
            rows.h, params.damper_gain * (rows.distance - params.self_safety_distance)
            / (params.self_influence_distance - params.self_safety_distance))

        def distances(qq: Array, pairs: Array) -> Array:
            pin.forwardKinematics(panda.model, data, qq)
            return self_clearance.pair_distances(data)[pairs]

        eps = 1e-6
        for qdot in rng.normal(0.0, 0.5, (2, panda.nv)):
            rate = (distances(pin.integrate(panda.model, q, qdot * eps), rows.self_pairs)
                    - distances(pin.integrate(panda.model, q, -qdot * eps), rows.self_pairs)) / (2 * eps)
            np.testing.assert_allclose(rate[near], -(rows.G @ qdot)[near], atol=1e-4)
        checked += int(near.sum())
        if checked >= 10:
            break
    assert checked >= 10, f"only {checked} self rows near enough to check"


def test_an_approaching_ball_never_beats_the_damper(panda: Robot) -> None:
    """A ball flies at the elbow while the hand holds still: at every step the distance falls no faster than the
    damper allows (to the discretisation error of dt = 5 ms), and the link never touches it."""
    q, scene = _near_ball(panda)
    params = ControllerParams()
    path = _hand_path(panda, q, np.array([0.0, 0.0, 1e-6]))
    ctrl = pc.make_controller("qp", robot=panda, path=path, scene=scene, params=params)
    clearance, data = Clearance(panda, scene), panda.model.createData()
    dt, previous, closest, held = 0.005, None, np.inf, 0
    for k in range(200):
        t = k * dt
        pin.forwardKinematics(panda.model, data, q)
        clearance.set_time(t)
        d = np.array(clearance.pair_distances(data))
        closest = min(closest, float(d.min()))
        if previous is not None:
            near = previous < params.influence_distance
            bound = -params.damper_gain * (previous - params.safety_distance) / (
                params.influence_distance - params.safety_distance)
            assert np.all(((d - previous) / dt)[near] >= bound[near] - 0.02)
            held += int(near.sum())
        qdot = ctrl.step(q, t, dt)
        assert ctrl.last_info.executed.slack == 0.0
        q = pc.integrate(panda, q, qdot, dt)
        previous = d
    assert held > 100 and closest > 0.5 * params.safety_distance
    assert ctrl.last_info.hand_error < 1e-3


def test_an_obstacle_faster_than_the_arm_is_reported_as_slack(planar4: Robot) -> None:
    """A disc at 5 m/s against link 2 of an arm limited to 0.1 rad/s: the dampers are infeasible, the QP is
    solved with slack and says so."""
    q = np.array([0.5, 0.5, 0.5, 0.5])
    data = planar4.model.createData()
    pin.forwardKinematics(planar4.model, data, q)
    elbow = (data.oMi[2].translation + data.oMi[3].translation) / 2
    normal = np.array([-np.sin(1.0), np.cos(1.0), 0.0])  # across link 2 (at 1 rad)
    ball = pc.Obstacle("ball", pc.Sphere(0.05), pc.ConstantVelocity(elbow + 0.2 * normal, -5.0 * normal))
    params = ControllerParams(velocity_scale=0.1)
    path = _hand_path(planar4, q, np.array([1e-6, 0.0]))
    state = _state(planar4, q, path)
    report = QPExecution(planar4, pc.Scene((ball,)), params)(state, reference(planar4, state, np.zeros(4), params))
    assert report.slack > 1.0 and report.dampers >= 1
    assert np.all(np.abs(report.qdot) <= 0.1 * planar4.joints.velocity + 1e-12)


def test_when_the_dampers_cannot_all_hold_the_links_come_before_the_hand(planar4: Robot) -> None:
    """A disc at 0.2 m/s, 7 cm from link 2, against an arm at 0.3 of its speed limits: the dampers are infeasible.
    Holding the hand would take a slack of 0.068 m/s (what penalising the slack inside the task QP gave); giving
    the hand up takes 0.0006 m/s. The QP must take the smallest slack, whatever the hand's weight, and keep every
    damper within it."""
    q = np.array([0.3, 1.2, -0.8, 1.0])
    data = planar4.model.createData()
    pin.forwardKinematics(planar4.model, data, q)
    a, b = data.oMi[2].translation, data.oMi[3].translation
    along = (b - a) / np.linalg.norm(b - a)
    normal = np.array([-along[1], along[0], 0.0])
    disc = pc.Obstacle("disc", pc.Sphere(0.05), pc.ConstantVelocity((a + b) / 2 + 0.07 * normal, -0.2 * normal))
    path = _hand_path(planar4, q, np.array([0.05, -0.05]))
    state = _state(planar4, q, path)
    slacks = []
    for weight in (1e4, 1e-6):
        params = ControllerParams(velocity_scale=0.3, task_weight=weight)
        execution = QPExecution(planar4, pc.Scene((disc,)), params)
        report = execution(state, reference(planar4, state, np.zeros(4), params))
        rows = execution.dampers(q, 0.0)
        assert np.all(rows.G @ report.qdot <= rows.h + report.slack + 1e-8)
        slacks.append(report.slack)
    assert 0.0 < slacks[0] < 1e-3
    assert slacks[0] == pytest.approx(slacks[1], abs=1e-6)


def test_a_joint_at_its_limit_is_saturated_and_the_others_hold_the_hand(panda: Robot) -> None:
    """Joint 1 at its upper limit and a reference (no limit-avoidance term) that pushes it further: the QP holds
    joint 1 and moves the hand exactly with the other six (clamping joint 1 alone would lose the hand)."""
    q = np.array([2.8973, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])  # joint 1 at its upper limit
    velocity = np.array([0.1, -0.1, 0.0])
    state = _state(panda, q, _hand_path(panda, q, velocity))
    params = ControllerParams(limit_gain=0.0)
    ref = reference(panda, state, np.zeros(panda.nv), params)
    requested = ref.qdot_task + ref.qdot_null
    assert requested[0] > 0.05  # eq. 19 wants joint 1 to go on
    J = state.kin.J_task[0]
    clamped = requested.copy()
    clamped[0] = 0.0
    assert np.linalg.norm(J @ clamped - velocity) > 0.01  # clamping it alone would lose the hand
    report = QPExecution(panda, pc.Scene(), params)(state, ref)
    qdot = report.qdot
    np.testing.assert_array_equal(report.requested, requested)
    assert qdot[0] <= 1e-12 and report.clamped
    np.testing.assert_allclose(J @ qdot, velocity, atol=1e-3 * np.linalg.norm(velocity))


def test_qp_always_runs_the_qp_none_the_pseudoinverse_and_the_others_their_setting(planar4: Robot) -> None:
    """``qp`` is always the QP and ``none`` always the paper's eq. 19 (the pseudo-inverse), whatever ``execution``
    says; every other controller runs the execution its setting names (the QP by default)."""
    q = np.array([1.2, 1.8, -2.9, 1.5])
    path = _hand_path(planar4, q, np.array([0.1, 0.0]))
    with pytest.warns(IgnoredSettingWarning, match="'qp' does not use execution = 'pseudoinverse'"):
        qp = pc.make_controller("qp", robot=planar4, path=path, params=PINV)
    assert isinstance(qp.execution, QPExecution) and qp.execution.name == "qp"
    for params in (PINV, ControllerParams()):  # the default execution is the QP: none still runs eq. 19
        none = pc.make_controller("none", robot=planar4, path=path, params=params)
        assert isinstance(none.execution, PseudoInverseExecution) and none.execution.name == "pseudoinverse"
        none.step(q, 0.0)
        assert none.last_info.executed.execution == "pseudoinverse"
    assert pc.make_controller("gradient", robot=planar4, path=path).execution.name == "qp"
    assert pc.make_controller("gradient", robot=planar4, path=path, params=PINV).execution.name == "pseudoinverse"
    # so a matrix of controllers and executions holds none and qp once each
    assert controller_runs(["none", "qp"], ["qp", "pseudoinverse"]) == [("none", "pseudoinverse"), ("qp", "qp")]


def test_safety_distance_must_be_below_the_influence_distance() -> None:
    with pytest.raises(ParameterError, match=r"safety_distance = 0\.4 \[m\] must be smaller than influence_distance "
                                             r"= 0\.3 \[m\]"):
        ControllerParams(safety_distance=0.4)
    with pytest.raises(ParameterError, match=r"self_safety_distance = 0\.2 \[m\] must be smaller than "
                                             r"self_influence_distance = 0\.1 \[m\]"):
        ControllerParams(self_safety_distance=0.2)
    with pytest.raises(ParameterError, match="execution"):
        dataclasses.replace(ControllerParams(), execution="fast")


def test_bounds_brake_linearly_within_the_margin_and_leave_continuous_joints_their_speed(
    panda: Robot, kinova: Robot
) -> None:
    """Closed form: towards a limit at distance a, min(q̇max, q̇max · a / (0.1 · range), a / dt)."""
    execution = QPExecution(panda, pc.Scene(), ControllerParams())
    q = np.array([0.0, 0.0, 0.0, -0.0698 - 0.05, 0.0, 1.8, 0.0])  # joint 4, 5 cm below its upper limit
    lower, upper = execution.bounds(q, 0.01)
    span = -0.0698 + 3.0718
    assert upper[3] == pytest.approx(2.175 * 0.05 / (0.1 * span), rel=1e-12)
    assert lower[3] == pytest.approx(-2.175) and upper[0] == pytest.approx(2.175)
    _, tight = execution.bounds(q, 0.2)  # a long period: a / dt binds first
    assert tight[3] == pytest.approx(0.05 / 0.2, rel=1e-12)
    lower, upper = QPExecution(kinova, pc.Scene(), ControllerParams()).bounds(pin.neutral(kinova.model), 0.01)
    continuous = kinova.joints.continuous
    assert continuous.any() and np.isfinite(upper).all()
    np.testing.assert_allclose(upper[continuous], kinova.joints.velocity[continuous])
    np.testing.assert_allclose(lower[continuous], -kinova.joints.velocity[continuous])


def test_a_step_the_qp_limits_still_leaves_the_error_of_the_continuous_law(panda: Robot) -> None:
    """The law corrects eq. 19's step for the command it asks for; when the speed limits bind, the QP runs another
    one and corrects the step again for it: held for dt, the executed q̇ leaves e(t + dt) = exp(−K_p dt) e(t)."""
    q, dt = np.array([0.3, -0.4, 0.2, -1.8, 0.1, 1.6, 0.5]), 0.01
    path = _hand_path(panda, q, np.array([0.05, 0.02, 0.0]))
    params = ControllerParams(velocity_scale=0.5)
    state = _state(panda, q, path, dt, t=0.3)
    ref = reference(panda, state, np.array([3.0, -2.4, 3.0, 1.8, -3.0, 2.4, 3.0]), params)
    report = QPExecution(panda, pc.Scene(), params)(state, ref)
    assert report.clamped  # the null-space motion is cut by the speed limits
    after = kinematics(panda, pc.integrate(panda, q, report.qdot, dt)[None, :]).tip_position[0]
    miss = np.linalg.norm(path.position(0.3 + dt) - after - np.exp(-params.feedback_gain * dt) * ref.task_error)
    assert miss < 1e-7
