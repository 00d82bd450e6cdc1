"""Tests of :mod:`previewctl.control` (params, tracking, nullspace, the laws, factory): eq. 19 tracking,
null-space input, limits, eqs. 20-21 with stand-in searches, the reachability route."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, get_args

import numpy as np
import pinocchio as pin
import pytest
from helpers import PLANAR_Q0, PLANAR_START, control_state, planar_doc, track
from numpy.typing import NDArray

from previewctl.control.base import ControlLaw, ControlState
from previewctl.control.factory import compose, make_controller
from previewctl.control.laws import Gradient, MultiPreview, Reach, SinglePreview
from previewctl.control.nullspace import AmsipGradient, LimitAvoidance, preview_pull, wrapped_difference
from previewctl.control.params import (
    CONTROLLER_NAMES,
    PREVIEW_MODES,
    ControllerName,
    ControllerParams,
    ControllerSpec,
)
from previewctl.control.planner import PeakPlanner
from previewctl.control.sweeps import SweepRoutes
from previewctl.control.tracking import _SQUARE, _resolved, damped_pseudo_inverse, null_space_budget, reference
from previewctl.errors import ParameterError
from previewctl.index.amsi import RANK_TOLERANCE, null_space_projector
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.kinematics import integrate, kinematics
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.file import scene_from_dict
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.search.ga import OneStepGA
from previewctl.search.maps import redundancy_map
from previewctl.search.planar import PlanarRedundancy
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, scenario_from_dict

Array = NDArray[np.float64]
TRACKING_TOLERANCE = 1e-3
"""Largest hand error [m] accepted for eq. 19 tracking with nothing in the way."""

PANDA_Q0 = [-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785]


@pytest.fixture(scope="module")
def panda_scenario() -> Scenario:
    """Panda, hand along a horizontal line with a ball nearby (never touching in 3 s)."""
    doc = {
        "name": "panda_test",
        "robot": {"source": "panda", "q0": PANDA_Q0},
        "path": {"waypoints": [[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]], "duration": 10.0},
        "obstacles": [{"name": "ball", "shape": "sphere", "radius": 0.08, "position": [0.1, 0.25, 0.75]}],
        "controller": {"name": "none", "gradient_gain": 1e-3},
        "timing": {"duration": 3.0},
    }
    return scenario_from_dict(doc)


def state_for(robot: Robot, q: Array, path: HandPath, *, t: float = 0.0, dt: float = 0.01,
              frame_due: bool = True) -> ControlState:
    return control_state(robot, q, path, t=t, dt=dt, frame_due=frame_due)


def law_on(robot: Robot, name: str, params: ControllerParams, searches: list[Any], *,
           scene: Scene | None = None) -> ControlLaw:
    """The law of controller ``name`` on stand-in ``searches`` (one per imaginary arm), as the factory builds it."""
    return compose(ControllerSpec(name, params), robot, scene or Scene(), Evaluator(robot, scene or Scene()),
                   np.random.default_rng(0), search_factory=lambda i, rng: searches[i]).law


def quick(scenario: Scenario, controller: str) -> Any:
    """Simulate with the search geometry as the 'exact' check (skips the mesh reload)."""
    ev = Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential)
    return simulate(scenario, controller, exact_evaluator=ev)


# ------------------------------------------------------------------------------- eq. 19 tracking


def test_eq19_tracks_planar_path_and_gradient_does_not_disturb_the_hand() -> None:
    scenario = scenario_from_dict(planar_doc(
        obstacles=[{"name": "ball", "shape": "sphere", "radius": 0.15, "position": [1.0, 0.6]}],
        timing={"duration": 2.0}))
    none, grad = quick(scenario, "none"), quick(scenario, "gradient")
    assert none.hand_error.max() < TRACKING_TOLERANCE
    assert grad.hand_error.max() < TRACKING_TOLERANCE
    # the null-space input really moved the arm and raised S, yet the hand followed the same path
    assert np.abs(grad.q - none.q).max() > 0.05
    assert grad.S.mean() > none.S.mean()
    np.testing.assert_allclose(grad.hand[:, :2], none.hand[:, :2], atol=2 * TRACKING_TOLERANCE)


def test_eq19_tracks_panda_path_none_and_gradient(panda_scenario: Scenario) -> None:
    none, grad = quick(panda_scenario, "none"), quick(panda_scenario, "gradient")
    assert none.hand_error.max() < TRACKING_TOLERANCE
    assert grad.hand_error.max() < 2 * TRACKING_TOLERANCE
    assert np.abs(grad.q - none.q).max() > 0.05
    assert not none.collision.any() and not grad.collision.any()


def test_null_space_part_does_not_move_the_hand(panda_scenario: Scenario) -> None:
    s = panda_scenario
    ev = Evaluator(s.robot, s.scene, s.index, s.potential)
    params = s.controller.params
    law = Gradient(AmsipGradient(s.robot, ev, params))
    rng = np.random.default_rng(3)
    for q in [s.q0, *(s.q0 + rng.normal(0, 0.2, 7) for _ in range(3))]:
        q = np.clip(q, s.robot.lower_limits, s.robot.upper_limits)
        state = state_for(s.robot, q, s.path, t=0.5)
        ref = reference(s.robot, state, law.null_input(state).v, params)
        J = state.kin.J_task[0]
        assert np.linalg.norm(ref.qdot_null) > 1e-3
        assert np.linalg.norm(J @ ref.qdot_null) < 1e-10 * np.linalg.norm(ref.qdot_null) + 1e-14


def test_gradient_matches_directional_derivative(planar4: Robot) -> None:
    scene = scene_from_dict([{"name": "b", "shape": "sphere", "radius": 0.2, "position": [1.2, 0.5]}])
    ev = Evaluator(planar4, scene)
    ascent = AmsipGradient(planar4, ev, ControllerParams(fd_step=1e-5))
    q = np.array(PLANAR_Q0)
    g = ascent.gradient(q, 0.0)
    d = np.array([0.3, -0.2, 0.5, 0.1])
    h = 1e-6
    numeric = (ev(q + h * d).S[0] - ev(q - h * d).S[0]) / (2 * h)
    assert g @ d == pytest.approx(numeric, rel=1e-4)


def test_damped_inverse_is_exact_away_from_singularities_and_bounded_at_one(planar4: Robot) -> None:
    q = np.array(PLANAR_Q0)
    J = kinematics(planar4, q[None, :]).J_task[0]
    J_sharp, lam = damped_pseudo_inverse(J, 0.05, 0.05)
    assert lam == 0.0
    np.testing.assert_allclose(J_sharp, np.linalg.pinv(J), atol=1e-12)
    # fully stretched arm: the y row is non-zero, the x row is zero -> sigma_min = 0
    J0 = kinematics(planar4, np.zeros((1, 4))).J_task[0]
    J0_sharp, lam0 = damped_pseudo_inverse(J0, 0.05, 0.05)
    assert lam0 == pytest.approx(0.05)
    assert np.isfinite(J0_sharp).all()
    path = HandPath(np.array([[3.0, 0.0], [2.9, 0.0]]), 1.0)  # pull the hand inwards along x
    qdot, info = track(planar4, state_for(planar4, np.zeros(4), path), np.zeros(4), ControllerParams())
    assert np.isfinite(qdot).all() and np.abs(info.reference.qdot_task).max() < 10.0


def _numpy_eq19(J: NDArray[np.float64], xdot: NDArray[np.float64], v: NDArray[np.float64], damping: float,
                threshold: float) -> tuple[NDArray[np.float64], float, NDArray[np.float64], NDArray[np.float64]]:
    """Eq. 19's linear algebra as numpy expressions: what the compiled kernel replaced, whose bits it must keep."""
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    smin = float(s[-1])
    lam2 = damping**2 * (1.0 - (smin / threshold) ** 2) if smin < threshold else 0.0
    denom = s**2 + lam2
    J_sharp = (Vt.T * np.divide(s, denom, out=np.zeros_like(s), where=denom > 0)) @ U.T
    return J_sharp, math.sqrt(lam2), null_space_projector(J) @ v, J_sharp @ xdot


@pytest.mark.parametrize("shape", [(2, 3), (2, 4), (3, 6), (3, 7), (6, 7), (6, 9)])
def test_compiled_eq19_keeps_the_bits_of_numpy(shape: tuple[int, int]) -> None:
    """The kernel equals numpy's expressions bit for bit (the golden runs rely on it), near singularities too, where
    ``λ²``'s squares are libm's ``pow`` (one in a few thousand differs from ``x * x`` in the last bit)."""
    rng = np.random.default_rng(7)
    m, n = shape
    damped = 0
    for k in range(1500):
        J = rng.normal(size=shape) * rng.choice([1e-3, 0.05, 1.0])
        if k % 3 == 0:  # two rows almost parallel: sigma_min below the threshold, so damped
            J[-1] = J[0] * (1.0 + 1e-4 * rng.normal())
        xdot, v = rng.normal(size=m), rng.normal(size=n)
        expected = _numpy_eq19(J, xdot, v, 0.05, 0.05)
        got = _resolved(J, xdot, v, 0.05, 0.05, RANK_TOLERANCE, _SQUARE)
        for name, a, b in zip(("J#", "lambda", "N v", "J# xdot"), expected, got, strict=True):
            assert np.array_equal(a, b), f"{name} differs at draw {k}: {a} != {b}"
        J_sharp, lam = damped_pseudo_inverse(J, 0.05, 0.05)
        assert np.array_equal(J_sharp, expected[0]) and lam == expected[1]
        damped += lam > 0.0
    assert damped > 300  # the damped branch is checked too


@pytest.mark.parametrize("name", ["planar4", "panda"])
def test_compiled_plan_pull_keeps_the_bits_of_pin_difference(name: str, request: pytest.FixtureRequest) -> None:
    """On an arm of 1-dof joints, the pull toward a plan's points (every index kept) is compiled: it equals the sum of
    ``k_i`` times ``pin.difference`` bit for bit, signed zeros included (the golden runs rely on it)."""
    robot: Robot = request.getfixturevalue(name)
    assert robot.joints.vector_space
    rng = np.random.default_rng(11)
    every = tuple(range(robot.nv))
    for k in range(2000):
        q = rng.uniform(-4.0, 4.0, robot.nq)
        targets = rng.uniform(-4.0, 4.0, (int(rng.integers(1, 5)), robot.nq))
        if k % 4 == 0:
            targets[0] = q  # zero differences
        weights = rng.uniform(0.0, 2.0, len(targets)) * rng.choice([0.0, 1.0, 1e-300], len(targets))
        expected = np.zeros(robot.nv)
        for weight, target in zip(weights, targets, strict=True):
            expected += weight * pin.difference(robot.model, q, target)
        got = preview_pull(robot, q, targets, weights, keep=every)
        assert np.array_equal(got, expected) and np.array_equal(np.signbit(got), np.signbit(expected)), k


# ----------------------------------------------------------------------------------- limits


def test_velocity_limits_keep_the_hand_on_its_direction_in_a_run() -> None:
    doc = planar_doc(controller={"name": "none", "velocity_scale": 0.05, "feedback_gain": 20.0,
                                 "execution": "pseudoinverse"},
                     path={"waypoints": [PLANAR_START, [1.0, 0.3]], "duration": 1.0}, timing={"duration": 2.0})
    scenario = scenario_from_dict(doc)
    run = quick(scenario, "none")
    limit = 0.05 * scenario.robot.velocity_limits
    assert (np.abs(run.qdot_requested) > limit * 1.5).any(), "the controller should ask for more than the limit"
    assert (np.abs(run.qdot) <= limit * (1 + 1e-12)).all()
    scaled = run.velocity_scale < 1
    assert scaled.any()
    # the task is scaled along its direction (SNS): the hand moves toward where eq. 19 asked, only slower
    robot = scenario.robot
    for k in np.flatnonzero(scaled)[:20]:
        J = kinematics(robot, run.q[k][None, :]).J_task[0]
        asked = J @ damped_pseudo_inverse(J, 0.05, 0.05)[0] @ J @ run.qdot_requested[k]
        moved = J @ run.qdot[k]
        assert moved @ asked / np.linalg.norm(moved) / np.linalg.norm(asked) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("step_correction", [True, False])
def test_a_step_leaves_the_error_of_the_continuous_law_with_the_step_correction(step_correction: bool) -> None:
    """Panda, 2 mm off a path turning within the period, with a fast null-space motion: held for dt, the
    corrected command leaves e(t + dt) = exp(−K_p dt) e(t) to 0.1 µm; eq. 19 as printed misses it by the
    hand's second-order motion and the turn (0.7 mm here)."""
    robot = load_robot("panda")
    q, dt, t = np.array(PANDA_Q0), 0.01, 0.995
    tip = kinematics(robot, q[None, :]).tip_position[0]
    corner = tip + np.array([0.002, 0.0, 0.0])  # the hand is 2 mm behind the corner it reaches at t = 1 s
    path = HandPath(corner + np.array([[-0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.1, 0.0]]), 2.0)
    params = ControllerParams(step_correction=step_correction)
    v = np.array([1.0, -0.8, 1.0, 0.6, -1.0, 0.8, 1.0])  # [rad/s], projected on the null space
    qdot, info = track(robot, state_for(robot, q, path, t=t, dt=dt), v, params)
    assert not info.executed.clamped and info.executed.null_scale == 1.0
    assert np.linalg.norm(info.reference.qdot_null) > 0.5
    after = kinematics(robot, integrate(robot, q, qdot, dt)[None, :]).tip_position[0]
    miss = np.linalg.norm(path.position(t + dt) - after
                          - np.exp(-params.feedback_gain * dt) * info.reference.task_error)
    if step_correction:
        assert miss < 1e-7
    else:
        assert miss > 1e-4


def test_a_joint_at_its_position_limit_is_held_and_the_others_track(panda_scenario: Scenario) -> None:
    robot = panda_scenario.robot
    q = np.array(PANDA_Q0)
    q[3] = robot.upper_limits[3] - 1e-3  # elbow 1 mm-rad below its upper limit
    J = kinematics(robot, q[None, :]).J_task[0]
    row = np.linalg.pinv(J)[3]
    velocity = 0.3 * row / (row @ row)  # asks the elbow for +0.3 rad/s, three times what is left to its limit
    start = kinematics(robot, q[None, :]).tip_position[0]
    state = state_for(robot, q, HandPath(np.array([start, start + velocity]), 1.0))
    out, info = track(robot, state, np.zeros(7), ControllerParams(feedback_gain=0.0, step_correction=False))
    assert info.reference.qdot_task[3] == pytest.approx(0.3)
    assert info.executed.clamped and info.executed.scale == 1.0
    assert q[3] + out[3] * 0.01 == pytest.approx(robot.upper_limits[3])
    np.testing.assert_allclose(J @ out, velocity, atol=1e-12)


def test_position_limits_hold_when_the_null_space_drive_pushes_past_them(panda_scenario: Scenario) -> None:
    # a (fake) imaginary arm beyond joint 7's upper limit pulls it up (joint 7 turns the hand about the
    # TCP axis: pure self-motion for a position task): it must stop exactly at the limit
    robot = panda_scenario.robot
    beyond = np.array(PANDA_Q0)
    beyond[6] = robot.upper_limits[6] + 0.5
    spec = ControllerSpec("single", ControllerParams(gain=(5.0,)))
    scenario = replace(panda_scenario, scene=Scene(), controller=spec)
    ev = Evaluator(robot, scenario.scene)
    controller = make_controller(scenario, search_factory=lambda i, rng: FakeGA(beyond))
    run = simulate(scenario, controller=controller, exact_evaluator=ev)
    lo, hi = robot.lower_limits, robot.upper_limits
    assert (run.q >= lo - 1e-9).all() and (run.q <= hi + 1e-9).all()
    assert np.isclose(run.q[:, 6], hi[6], atol=1e-9).any(), "joint 7 should reach its limit"
    assert run.hand_error.max() < TRACKING_TOLERANCE
    assert (np.abs(run.qdot) <= robot.velocity_limits * (1 + 1e-12)).all()


# -------------------------------------------------------------------------------- weights k_i


@pytest.mark.parametrize(
    ("weights", "message"),
    [
        ([0.5, 0.6], "weights = [0.5, 0.6]: the k_i must sum to 1, they sum to 1.1"),
        ([1.0], "weights = [1.0]: k_1 = 1.0 must satisfy 0 < k_i < 1; for one preview use the 'single'"),
        ([0.0, 1.0], "k_1 = 0.0"),
        ([1.2, -0.2], "k_1 = 1.2"),
        ([], "weights must be a non-empty list"),
        (["a", 0.5], "weights[0] must be a finite number, got 'a'"),
    ],
)
def test_preview_weights_validation(weights: list[Any], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        ControllerParams(weights=tuple(weights))
    assert message in str(info.value)


def test_preview_weights_accept_the_paper_values() -> None:
    assert ControllerParams(weights=[0.3, 0.65, 0.05]).weights == (0.3, 0.65, 0.05)  # type: ignore[arg-type]
    assert ControllerParams().preview_weights("single") == (1.0,)
    assert ControllerParams(weights=(0.5, 0.5)).preview_weights("multi") == (0.5, 0.5)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"velocity_scale": 1.5}, "velocity_scale must lie in (0, 1], got 1.5"),
        ({"gain": (-1.0,)}, "gain[0] must be > 0, got -1.0"),
        ({"gain": ()}, "gain must have at least 1 entry"),
        ({"feedback_gain": "5"}, "feedback_gain must be a finite number, got '5'"),
        ({"damping": float("nan")}, "damping must be finite, got nan"),
        ({"previews": 0}, "previews must be >= 1, got 0"),
        ({"population": 3}, "population must be >= 4, got 3"),  # the GA's own bound
        ({"population": 4, "elite": 4}, "elite + top_k must be below population: 4 + 4 >= 4"),
        ({"ga_options": (("mutaton_scale", 0.1),)},
         "unknown key 'ga_options.mutaton_scale' (did you mean 'ga_options.mutation_scale'?); valid keys in "
         "[ga_options]: mutation_scale, niche_radius"),
        ({"ga_options": (("immigrants", 0.8),)}, "ga_options.immigrants must lie in [0, 0.5], got 0.8"),
        ({"with_gradient": 1}, "with_gradient must be true or false, got 1"),
    ],
)
def test_controller_params_reject_bad_values(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        ControllerParams(**kwargs)
    assert message in str(info.value)


def test_controller_names_come_from_one_list() -> None:
    names = ("none", "qp", "gradient", "single", "multi", "reach", "horizon", "oracle")
    assert get_args(ControllerName) == CONTROLLER_NAMES == names
    assert PREVIEW_MODES == ("single", "multi", "reach")
    with pytest.raises(ParameterError, match=r"controller = 'fancy' is not valid; valid: none, qp, gradient, single"):
        ControllerSpec("fancy")
    with pytest.raises(ParameterError, match=r"\(did you mean 'multi'\?\)"):
        ControllerSpec("mult")


# -------------------------------------------------------------------------- preview skeleton


@dataclass(frozen=True)
class FakeCandidate:
    genes: Array
    branch: int
    q: Array
    S: float


class FakeGA:
    """A stand-in for ``previewctl.search.ga.OneStepGA``: ``step`` returns a fixed candidate."""

    def __init__(self, q: Array, S: float = 100.0) -> None:
        self.candidate = FakeCandidate(np.zeros(2), 0, np.array(q, dtype=float), S)
        self.calls: list[tuple[Array, float]] = []
        self.seeded: list[Array] = []

    def step(self, target: Array, t: float) -> FakeCandidate:
        self.calls.append((np.array(target), t))
        return self.candidate

    def peaks(self) -> tuple[FakeCandidate, ...]:
        return (self.candidate,)

    def seed(self, q: Array) -> None:
        self.seeded.append(np.array(q))


def planar_ik(robot: Robot, q12: tuple[float, float], tip: Array, elbow: int = 1) -> Array:
    """A planar4 configuration with the given (q1, q2) and the hand at ``tip`` (closed-form 2-link IK)."""
    q1, q2 = q12
    link = 0.75
    o3 = link * np.array([np.cos(q1), np.sin(q1)]) + link * np.array([np.cos(q1 + q2), np.sin(q1 + q2)])
    d = tip - o3
    c4 = (d @ d - 2 * link**2) / (2 * link**2)
    q4 = elbow * np.arccos(np.clip(c4, -1, 1))
    phi = np.arctan2(d[1], d[0]) - np.arctan2(link * np.sin(q4), link + link * np.cos(q4))
    return np.array([q1, q2, phi - q1 - q2, q4])


def test_preview_with_gradient_adds_the_local_term(planar4: Robot) -> None:
    """with_gradient: v = K_v (sum k_i q~_i - q) + K_g grad S. With the imaginary arms at q the pull
    vanishes and v is exactly the gradient controller's input; the factory gives the law that local term
    (on the scene's evaluator) only with with_gradient."""
    path = HandPath(np.array([PLANAR_START, [1.6069, 0.6417]]), 5.0)
    scene = Scene((Obstacle("ball", Sphere(0.2), Static(np.array([0.3, 1.2, 0.0]))),))  # 7 cm from the arm
    evaluator = Evaluator(planar4, scene)
    params = ControllerParams(gradient_gain=(2e-4,), weights=(0.25, 0.75), with_gradient=True, imaginary_arms="peaks")
    q = np.array(PLANAR_Q0)
    law = law_on(planar4, "multi", params, [FakeGA(q), FakeGA(q)], scene=scene)
    assert isinstance(law, MultiPreview) and isinstance(law.local, AmsipGradient)
    null = law.null_input(state_for(planar4, q, path, t=1.0))
    local = AmsipGradient(planar4, evaluator, params)(q, 1.0)
    assert np.linalg.norm(local) > 0
    np.testing.assert_allclose(null.v, local, rtol=1e-12, atol=1e-15)
    plain = law_on(planar4, "multi", replace(params, with_gradient=False), [FakeGA(q)] * 2, scene=scene)
    assert isinstance(plain, MultiPreview) and plain.local is None
    np.testing.assert_allclose(plain.null_input(state_for(planar4, q, path, t=1.0)).v, 0.0, atol=1e-15)
    with pytest.raises(ParameterError, match="with_gradient must be true or false"):
        ControllerParams(with_gradient=1)  # type: ignore[arg-type]


def test_preview_controller_computes_eq21_with_fake_searches(planar4: Robot) -> None:
    """The paper-literal mode (coherent=False): eq. 21 on each search's best, at full gain at once."""
    path = HandPath(np.array([PLANAR_START, [1.6069, 0.6417]]), 5.0)
    params = ControllerParams(gain=(2.0,), weights=(0.25, 0.75), preview_time=0.5, coherent=False)
    q = np.array(PLANAR_Q0)
    targets = [q + np.array([0.1, -0.2, 0.05, 0.0]), q + np.array([-0.3, 0.1, 0.2, -0.1])]
    fakes = [FakeGA(targets[0], 10.0), FakeGA(targets[1], 20.0)]
    law = law_on(planar4, "multi", params, fakes)
    null = law.null_input(state_for(planar4, q, path, t=1.0))
    expected_v = 2.0 * (0.25 * targets[0] + 0.75 * targets[1] - q)
    np.testing.assert_allclose(null.v, expected_v, atol=1e-12)
    assert null.targets is not None and null.target_amsip is not None
    np.testing.assert_allclose(null.targets, np.array(targets))
    np.testing.assert_allclose(null.target_amsip, np.array([10.0, 20.0]))
    # each imaginary arm works on its own future time t + i t~ and hand target r_d(t + i t~)
    assert [c[1] for c in fakes[0].calls] == [1.5] and [c[1] for c in fakes[1].calls] == [2.0]
    np.testing.assert_allclose(fakes[1].calls[0][0], path.position(2.0))
    assert all(len(f.seeded) == 1 for f in fakes)
    # no frame due: no new generation, same targets
    law.null_input(state_for(planar4, q, path, t=1.01, frame_due=False))
    assert len(fakes[0].calls) == 1
    law.null_input(state_for(planar4, q, path, t=1.02, frame_due=True))
    assert len(fakes[0].calls) == 2


def test_coherent_preview_ramps_the_pull_in_from_zero(planar4: Robot) -> None:
    """Coherent mode: the same targets, but the pull starts at 0 and reaches eq. 21 after settle_frames."""
    path = HandPath(np.array([PLANAR_START, [1.6069, 0.6417]]), 5.0)
    params = ControllerParams(gain=(2.0,), weights=(0.25, 0.75), preview_time=0.5, settle_frames=2,
                              imaginary_arms="peaks")
    q = np.array(PLANAR_Q0)
    targets = [q + np.array([0.1, -0.2, 0.05, 0.0]), q + np.array([-0.3, 0.1, 0.2, -0.1])]
    law = law_on(planar4, "multi", params, [FakeGA(targets[0], 10.0), FakeGA(targets[1], 20.0)])
    full = 2.0 * (0.25 * targets[0] + 0.75 * targets[1] - q)
    for ramp in (0.0, 0.5, 1.0, 1.0):
        null = law.null_input(state_for(planar4, q, path, t=1.0))
        np.testing.assert_allclose(null.v, ramp * full, atol=1e-12)


def test_coherent_preview_pulls_nowhere_when_no_imaginary_arm_is_feasible(planar4: Robot) -> None:
    """Coherent mode: a search with nothing at S > 0 contributes no pull (the literal mode would pull)."""
    path = HandPath(np.array([PLANAR_START, [1.6069, 0.6417]]), 5.0)
    q = np.array(PLANAR_Q0)
    target = q + np.array([0.1, -0.2, 0.05, 0.0])
    for coherent, pulled in ((True, False), (False, True)):
        params = ControllerParams(gain=(2.0,), preview_time=0.5, settle_frames=1, coherent=coherent)
        law = law_on(planar4, "single", params, [FakeGA(target, -1.0)])
        assert isinstance(law, SinglePreview)
        null = law.null_input(state_for(planar4, q, path, t=1.0))
        assert bool(np.any(null.v != 0.0)) == pulled


def test_single_preview_drives_the_arm_to_the_imaginary_arm_in_the_null_space(planar4: Robot) -> None:
    doc = planar_doc(path={"waypoints": [PLANAR_START, [1.9069, 1.0317]], "duration": 0.5},
                     controller={"name": "single", "gain": 2.0}, timing={"duration": 4.0})
    scenario = scenario_from_dict(doc)
    goal_tip = np.array([1.9069, 1.0317])
    target = planar_ik(scenario.robot, (0.9, 0.6), goal_tip)
    fake = FakeGA(target)
    ev = Evaluator(scenario.robot, scenario.scene)
    controller = make_controller(scenario, search_factory=lambda i, rng: fake)
    run = simulate(scenario, controller=controller, exact_evaluator=ev)
    assert run.controller == "single"
    assert run.hand_error.max() < TRACKING_TOLERANCE
    assert np.abs(run.q[0] - target).max() > 0.3
    np.testing.assert_allclose(run.q[-1], target, atol=0.01)
    assert 0 < len(fake.calls) <= int(np.ceil(4.0 / 0.033)) + 1


def test_wrapped_difference_goes_the_short_way(planar4: Robot) -> None:
    q = np.array([3.0, 0.0, 0.0, 0.0])
    target = np.array([-3.0, 0.0, 0.0, 0.0])  # 6 rad apart, 0.28 rad the other way round
    diff = wrapped_difference(planar4, q, target)
    assert diff[0] == pytest.approx(2 * np.pi - 6.0)


class FakePeaksGA(FakeGA):
    """A fake search whose best (``step``) is ``best`` and whose peaks are ``peaks``."""

    def __init__(self, best: FakeCandidate, peaks: list[FakeCandidate]) -> None:
        super().__init__(best.q, best.S)
        self.candidate, self._peaks = best, tuple(peaks)

    def peaks(self) -> tuple[FakeCandidate, ...]:
        return self._peaks


def test_coherent_imaginary_arms_form_a_chain_from_the_arm(planar4: Robot) -> None:
    """Coherent mode: imaginary arm 2 starts from arm 1's peak, not from the real arm. Arm 2 has a better peak
    ``N`` next to the arm and a worse one ``M`` next to arm 1's peak ``P1``; it takes ``M``."""
    path = HandPath(np.array([PLANAR_START, [1.6069, 0.6417]]), 5.0)
    params = ControllerParams(gain=(1.0,), weights=(0.5, 0.5), preview_time=0.5, settle_frames=1,
                              imaginary_arms="peaks")
    q = np.array(PLANAR_Q0)
    P1 = q + np.array([0.45, 0.0, 0.0, 0.0])  # 0.45 rad from the arm: arm 1's peak
    N = q + np.array([-0.3, 0.0, 0.0, 0.0])  # 0.3 rad from the arm, 0.75 rad from P1
    M = q + np.array([0.55, 0.0, 0.0, 0.0])  # 0.55 rad from the arm, 0.1 rad from P1
    first = FakeCandidate(np.zeros(2), 0, P1, 100.0)
    second = FakeCandidate(np.zeros(2), 0, N, 200.0)
    searches = [FakePeaksGA(first, [first]), FakePeaksGA(second, [second, FakeCandidate(np.zeros(2), 0, M, 50.0)])]
    null = law_on(planar4, "multi", params, searches).null_input(state_for(planar4, q, path))
    assert null.targets is not None
    np.testing.assert_allclose(null.targets, np.array([P1, M]), atol=1e-12)


def reach_setup(planar4: Robot, near_S: tuple[float, float], *, coherent: bool = False,
                settle_frames: int = 1) -> tuple[Reach, Array, HandPath, list[Array]]:
    """Two preview levels, each with a 'near' peak (close to q, same elbow) and a better 'far' one.

    ``coherent=False``: the routes of straight sweeps (the paper-literal ``reach``); ``True``: the moves planned by
    the reachability DP (coherent ``reach`` on planar arms of up to 4 joints)."""
    path = HandPath(np.array([PLANAR_START, [1.6069, 0.6417]]), 5.0)
    params = ControllerParams(gain=(1.0,), weights=(0.5, 0.5), preview_time=0.5, settle_frames=settle_frames,
                              coherent=coherent)
    q = np.array(PLANAR_Q0)
    searches, nears = [], []
    for i, S_near in enumerate(near_S, start=1):
        tip = path.position(0.5 * i)
        near = planar_ik(planar4, (0.6 + 0.02 * i, 1.0), tip, elbow=-1)
        far = planar_ik(planar4, (-2.0, 2.5), tip, elbow=1)  # > 2 rad away: beyond 1 rad/s over 0.5 s
        best = FakeCandidate(np.zeros(2), 0, far, 1000.0)
        searches.append(FakePeaksGA(best, [best, FakeCandidate(np.zeros(2), 1, near, S_near)]))
        nears.append(near)
    law = law_on(planar4, "reach", params, searches)
    assert isinstance(law, Reach) and isinstance(law.route, PeakPlanner if coherent else SweepRoutes)
    return law, q, path, nears


def test_reach_follows_a_reachable_route_not_each_times_best(planar4: Robot) -> None:
    law, q, path, nears = reach_setup(planar4, (100.0, 100.0))
    null = law.null_input(state_for(planar4, q, path))
    assert isinstance(law.route, SweepRoutes)
    route = law.route.route
    assert route is not None and route.complete
    np.testing.assert_allclose(route.nodes, np.array(nears), atol=1e-12)
    np.testing.assert_allclose(route.S, [100.0, 100.0])
    assert null.targets is not None
    np.testing.assert_allclose(null.targets, np.array(nears), atol=1e-12)
    # the arm follows the planned move: v = (q_lead - q) / dtau, q_lead one sweep step toward node 1,
    # on the path at t + dtau (hand on r_d) and within the speed limits
    dtau = 0.5 / (law.route.sweep_samples + 1)
    np.testing.assert_allclose(null.v, (route.lead - q) / dtau, atol=1e-9)
    lead_hand = kinematics(planar4, route.lead[None, :]).tip_position[0, :2]
    np.testing.assert_allclose(lead_hand, path.position(dtau), atol=1e-9)
    assert np.all(np.abs(route.lead - q) <= planar4.velocity_limits * dtau + 1e-12)


def test_reach_drops_a_route_at_its_first_negative_node(planar4: Robot) -> None:
    law, q, path, nears = reach_setup(planar4, (100.0, -1.0))
    law.null_input(state_for(planar4, q, path))
    assert isinstance(law.route, SweepRoutes)
    route = law.route.route
    assert route is not None and not route.complete  # level 2 has no reachable positive node
    np.testing.assert_allclose(route.nodes, np.array(nears[:1]), atol=1e-12)


def held_hand_and_peak(panda: Robot) -> tuple[Array, Array, HandPath, Any, Array]:
    """A Panda configuration ``q``, its hand ``tip`` held still by ``path``, the Newton map ``red`` and a ``peak``:
    ``q`` moved by 0.4-0.6 rad on four joints and solved back onto the hand (within the speed limits over 1 s)."""
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7])
    tip = kinematics(panda, q[None, :]).tip_position[0]
    path = HandPath(np.array([tip, tip + 1e-9]), 5.0)  # the hand holds still
    red = redundancy_map(panda)
    peak, reachable = red.solve(q[None, :] + np.array([0.6, 0.0, 0.4, 0.0, -0.5, 0.0, 0.3]), np.zeros(1, int), tip)
    assert reachable[0]
    return q, tip, path, red, peak[0]


def test_reach_on_a_spatial_arm_sweeps_toward_the_peak(panda: Robot) -> None:
    """Paper-literal ``reach`` (``coherent = false``) on a spatial arm. The straight sweep of a Newton redundancy
    map: each sample is the interpolated joint vector solved onto the hand target, so the move goes toward the peak
    step by step. (Seeding every sample's Newton with the sample before it, as was done, solved back onto the
    start: the sweep stood still and jumped to the peak at its last step, so a route of the Panda almost never
    passed the speed test.)"""
    q, tip, path, _, peak = held_hand_and_peak(panda)
    params = ControllerParams(gain=(1.0,), weights=(0.5, 0.5), preview_time=1.0, settle_frames=1, coherent=False)
    best = FakeCandidate(np.zeros(7), 0, peak, 100.0)
    searches = [FakePeaksGA(best, [best]), FakePeaksGA(best, [best])]
    law = law_on(panda, "reach", params, searches)
    assert isinstance(law, Reach) and isinstance(law.route, SweepRoutes)  # the paper-literal mode: straight sweeps
    law.null_input(state_for(panda, q, path))
    route = law.route.route
    assert route is not None and route.complete
    samples = law.route.sweep_samples + 1
    moved = np.abs(wrapped_difference(panda, q, route.lead))
    whole = np.abs(wrapped_difference(panda, q, peak))
    assert np.all(moved <= panda.velocity_limits / samples + 1e-12)  # one step within the speed limits
    assert np.linalg.norm(moved) == pytest.approx(np.linalg.norm(whole) / samples, rel=0.3)  # a share of the way
    np.testing.assert_allclose(kinematics(panda, route.lead[None, :]).tip_position[0], tip, atol=1e-4)


def test_coherent_reach_on_a_spatial_arm_plans_to_the_latest_peak_by_the_sampled_search(panda: Robot) -> None:
    """A peak 0.6 rad away (within the speed limits over 1 s) at both preview times, with the hand held still: the
    sampled search's goal is the peak of the later time, and its motion ends there, near the peak."""
    q, tip, path, _, peak = held_hand_and_peak(panda)
    params = ControllerParams(gain=(1.0,), weights=(0.5, 0.5), preview_time=1.0, settle_frames=1)
    best = FakeCandidate(np.zeros(7), 0, peak, 100.0)
    law = law_on(panda, "reach", params, [FakePeaksGA(best, [best])] * 2)
    assert isinstance(law, Reach) and isinstance(law.route, PeakPlanner)  # planned moves, no straight sweeps
    planner = law.route.planner
    assert planner.kind == "sampled" and planner.timing.window == pytest.approx(2.0)
    law.null_input(state_for(panda, q, path))
    assert planner.goal == (1, 0)
    goal = law.route.goal
    assert goal is not None and goal[0] == 1
    np.testing.assert_allclose(goal[1], peak, atol=1e-12)
    motion = planner.motion
    assert motion is not None and motion.times[-1] == pytest.approx(2.0)
    assert np.linalg.norm(motion.q[-1] - peak) <= planner.roadmap.goal_radius
    np.testing.assert_allclose(kinematics(panda, motion.q[-1][None, :]).tip_position[0], tip, atol=1e-4)


@pytest.mark.parametrize("near_S", [(100.0, 100.0), (100.0, -1.0)])
def test_coherent_reach_on_a_planar_arm_follows_the_dp_to_the_latest_reachable_peak(
        planar4: Robot, near_S: tuple[float, float]) -> None:
    """The better 'far' peaks lie beyond the joint speed limits, so the DP reaches only the 'near' ones; the goal is
    the near peak of the latest level that has a positive one, and the arm follows the DP's move toward it."""
    law, q, path, nears = reach_setup(planar4, near_S, coherent=True)
    state = state_for(planar4, q, path)
    null = law.null_input(state)
    assert isinstance(law.route, PeakPlanner)  # no straight-sweep route: the DP plans the move
    goal = law.route.goal
    level = 1 if near_S[1] > 0 else 0
    assert goal is not None and goal[0] == level
    np.testing.assert_allclose(goal[1], nears[level], atol=1e-12)
    assert null.targets is not None
    np.testing.assert_allclose(null.targets[level], nears[level], atol=1e-12)
    planner = law.route.planner
    assert planner.kind == "dp" and planner.motion is not None and planner.result is not None
    motion = planner.motion
    assert motion.times[-1] == pytest.approx(0.5 * (level + 1), abs=0.5 * planner.result.dt)  # ends at the goal's time
    genes, branch = PlanarRedundancy(planar4).genes_of(np.vstack([motion.q[-1], nears[level]]))
    assert branch[0] == branch[1]
    assert np.all(np.abs(genes[0] - genes[1]) <= np.radians(planner.options.resolution_deg) + 1e-9)
    # the input is the planner's: toward its motion at the lookahead, v = q̇*(t_l) + K_v (q*(t_l) ⊖ q)
    q_ref, rate, _ = planner.point(planner.timing.lookahead)
    np.testing.assert_allclose(null.v, rate + 1.0 * pin.difference(planar4.model, q, q_ref), atol=1e-12)


def test_coherent_reach_plans_without_goals_until_the_searches_settle(planar4: Robot) -> None:
    """Before ``settle_frames`` generations the plan is the DP's own best motion (no goal), as ``horizon``'s."""
    law, q, path, _ = reach_setup(planar4, (100.0, 100.0), coherent=True, settle_frames=2)
    law.null_input(state_for(planar4, q, path))
    assert isinstance(law.route, PeakPlanner)
    planner = law.route.planner
    assert planner.result is not None
    assert law.route.goal is None and planner.result.goal is None
    assert planner.motion is planner.result.motion and planner.motion.min_S == pytest.approx(planner.result.best_min_S)


def test_coherent_reach_at_the_path_end_keeps_no_goal_of_an_earlier_plan(planar4: Robot) -> None:
    """A plan due at the path's end has nothing to track: the arm holds ``q`` and no goal of the last plan
    (whose peaks may be gone by then) is looked up again."""
    law, q, path, _ = reach_setup(planar4, (100.0, 100.0), coherent=True)
    law.null_input(state_for(planar4, q, path))
    assert isinstance(law.route, PeakPlanner)
    assert law.route.goal is not None and law.route.goal[0] == 1
    for search in law.arms.searches:
        search._peaks = search._peaks[:1]  # type: ignore[attr-defined]  # only the far peak is left
    v = law.null_input(state_for(planar4, q, path, t=path.end_time)).v
    planner = law.route.planner
    assert planner.result is None and law.route.goal is None
    np.testing.assert_allclose(planner.motion.q, [q])  # type: ignore[union-attr]
    assert np.all(np.isfinite(v))


def test_compose_builds_reach_with_real_searches(planar4: Robot) -> None:
    law = compose(ControllerSpec("reach", ControllerParams(weights=(0.3, 0.65, 0.05))), planar4, Scene(),
                  Evaluator(planar4), np.random.default_rng(0)).law
    assert isinstance(law, Reach) and len(law.arms) == 3
    assert all(isinstance(search, OneStepGA) for search in law.arms.searches)


def test_pose_task_tracks_orientation() -> None:
    """The orientation rows of the error are the world-frame rotation vector: R exp(w) -> R w."""
    robot = load_robot("ur5", task="pose")
    q = np.array([0.1, -1.2, 1.5, -0.8, 1.1, 0.3])
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    tip = data.oMf[robot.tip_frame_id]
    target_R = tip.rotation @ pin.exp3(np.array([0.0, 0.0, 0.1]))
    p0 = tip.translation
    path = HandPath(np.array([p0, p0 + np.array([0.001, 0.0, 0.0])]), 1.0, orientation=target_R)
    _, info = track(robot, state_for(robot, q, path), np.zeros(robot.nv), ControllerParams())
    assert info.reference.task_error.shape == (6,)
    np.testing.assert_allclose(info.reference.task_error[3:], tip.rotation @ np.array([0.0, 0.0, 0.1]), atol=1e-9)


def test_null_space_budget_closed_forms() -> None:
    """The largest α in [0, 1] with |q̇_task + α q̇_null| <= limit, per joint and overall (compiled loop)."""
    inf = np.inf
    # joint 0: |0.5 + α| <= 1 gives α <= 0.5; joint 1: |α| <= 1 gives 1; the budget is the smaller
    assert null_space_budget(np.array([0.5, 0.0]), np.array([1.0, 1.0]), np.array([1.0, 1.0])) == 0.5
    # a negative null direction: |-0.2 - 2α| <= 1 gives α <= 0.4
    assert null_space_budget(np.array([-0.2]), np.array([-2.0]), np.array([1.0])) == pytest.approx(0.4, abs=1e-15)
    assert null_space_budget(np.array([1.5, 0.0]), np.array([0.1, 0.1]), np.array([1.0, 1.0])) == 0.0  # task over
    assert null_space_budget(np.array([0.1, 0.1]), np.array([0.2, -0.2]), np.array([1.0, 1.0])) == 1.0  # room
    assert null_space_budget(np.array([0.0, 0.9]), np.array([50.0, 0.0]), np.array([inf, 1.0])) == 1.0  # no limit


def test_limit_avoidance_pushes_inside_the_margin_only(panda: Robot) -> None:
    """``K_l`` times the depth inside the margin, away from the limit; 0 outside the margins."""
    params = ControllerParams(limit_gain=2.0, limit_margin=0.1)
    lower, upper = panda.joints.lower, panda.joints.upper
    margin = 0.1 * (upper - lower)
    q = (lower + upper) / 2
    np.testing.assert_array_equal(LimitAvoidance(panda, params)(q), np.zeros(panda.nv))
    q[0] = lower[0] + margin[0] / 4  # a quarter into the lower margin: pushed up by 2 × 3/4 of it
    q[3] = upper[3] - margin[3] / 2  # half into the upper margin: pushed down
    v = LimitAvoidance(panda, params)(q)
    assert v[0] == pytest.approx(2.0 * 0.75 * margin[0], rel=1e-12)
    assert v[3] == pytest.approx(-2.0 * 0.5 * margin[3], rel=1e-12)
    np.testing.assert_array_equal(np.delete(v, [0, 3]), 0.0)
