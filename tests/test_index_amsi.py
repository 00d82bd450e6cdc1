"""Tests of :mod:`previewctl.index.amsi` (eqs. 3-17) and :mod:`previewctl.kinematics`: null-space
identities, Jacobians against finite differences, the AMSI against a hand computation, ranks,
continuity at singularities, the planar closed form (:mod:`previewctl.index.planar`) against the general
(Pinocchio + Coal) path, batched frame kinematics against Pinocchio, and the Gram pseudo-inverse."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import random_chain_urdf, rot_z
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

import previewctl
from previewctl import IndexParams, Obstacle, Scene, avoidance, evaluate, unit_ball_volume
from previewctl.errors import RobotLoadError
from previewctl.robot.model import Robot
from previewctl.scene.motion import ConstantVelocity, Static

Array = NDArray[np.float64]
LINK = 0.75  # planar4 link length [m]


# ------------------------------------------------------------------------------------ identities


PROJECTOR_TOLERANCE = 1e-12
"""``|J_n N| <= 1e-12 max(1, |J_n|)`` and ``|N N - N| <= 1e-12``: what the SVD projector guarantees (docs/math.md)."""


def check_identities(robot: Robot, Q: Array) -> None:
    """J_n N = 0, N symmetric and idempotent, M_i = J_i N, batch == one at a time."""
    batch = avoidance(robot, Q)
    B, nv = Q.shape[0], robot.nv
    assert batch.N.shape == (B, nv, nv)
    assert batch.amsi.shape == (B,)
    for b in range(B):
        one = avoidance(robot, Q[b])
        J = one.J_task
        scale = max(1.0, float(np.linalg.norm(J)))
        # SVD projector: exact to rounding at every configuration, near-singular ones included
        np.testing.assert_allclose(J @ one.N, 0.0, atol=PROJECTOR_TOLERANCE * scale)
        np.testing.assert_allclose(one.N, one.N.T, atol=1e-12)
        np.testing.assert_allclose(one.N @ one.N, one.N, atol=PROJECTOR_TOLERANCE)
        # N is an orthogonal projector of rank nv - rank(J)
        assert np.isclose(np.trace(one.N), nv - np.linalg.matrix_rank(J, tol=1e-9 * np.linalg.norm(J, 2)))
        for i in range(len(robot.control_points)):
            np.testing.assert_allclose(one.M[i], one.J_points[i] @ one.N, atol=1e-12)
        for field in ("J_task", "J_points", "N", "M", "singular_values", "volumes"):
            np.testing.assert_allclose(getattr(batch, field)[b], getattr(one, field), rtol=1e-10, atol=1e-13)
        np.testing.assert_array_equal(batch.ranks[b], one.ranks)
        np.testing.assert_allclose(batch.amsi[b], one.amsi, rtol=1e-10)
        assert np.all(one.volumes >= 0.0)
        assert np.isfinite(one.amsi)


@pytest.mark.parametrize("name", ["planar4", "panda", "ur5"])
def test_identities_shipped_robots(name: str, request: pytest.FixtureRequest) -> None:
    robot: Robot = request.getfixturevalue(name)
    rng = np.random.default_rng(20240611)
    check_identities(robot, robot.random_configurations(rng, 12))


@st.composite
def chain_urdfs(draw: st.DrawFn) -> str:
    return random_chain_urdf(draw, draw(st.integers(4, 8)))


@settings(max_examples=25, deadline=None)
@given(urdf=chain_urdfs(), seed=st.integers(0, 2**32 - 1))
def test_identities_random_chains(urdf: str, seed: int, tmp_path_factory: pytest.TempPathFactory) -> None:
    path = tmp_path_factory.mktemp("chain") / "chain.urdf"
    path.write_text(urdf)
    try:
        robot = previewctl.load_robot(path, task="position")
    except RobotLoadError as exc:  # a degenerate draw (e.g. every origin at 0): refused, and rightly
        assert "has no control point" in str(exc) or "cannot follow task 'position'" in str(exc)
        reject()
    assert robot.task == "position"
    assert robot.tip_frame == "tip"
    rng = np.random.default_rng(seed)
    check_identities(robot, robot.random_configurations(rng, 4))


# ------------------------------------------------------------------------------------ ranks


def test_planar4_ranks_at_generic_configurations(planar4: Robot) -> None:
    """The paper: rank(M_1) = rank(M_3) = 1, rank(M_2) = 2."""
    assert tuple(planar4.structural_ranks) == (1, 2, 1)
    rng = np.random.default_rng(3)
    result = avoidance(planar4, planar4.random_configurations(rng, 200))
    assert result.ranks.shape == (200, 3)
    assert np.all(result.ranks == np.array([1, 2, 1]))
    np.testing.assert_array_equal(result.structural_ranks, [1, 2, 1])
    # rank 1 points: exactly one non-zero singular value
    assert np.all(result.singular_values[:, [0, 2], 1] < 1e-10)
    assert np.all(result.singular_values[:, 1, 1] > 1e-10)


# ------------------------------------------------------------------------------ finite differences


def perturbed_placements(robot: Robot, q: Array, frame: str, eps: float) -> list[tuple[pin.SE3, pin.SE3]]:
    """Placements of ``frame`` at ``q (+) eps e_k`` and ``q (-) eps e_k`` for every tangent direction k,
    by Pinocchio's forward kinematics directly."""
    model = robot.model
    data = model.createData()
    fid = model.getFrameId(frame)
    pairs = []
    for k in range(model.nv):
        step = np.zeros(model.nv)
        step[k] = eps
        ends = []
        for sign in (1.0, -1.0):
            pin.framesForwardKinematics(model, data, pin.integrate(model, q, sign * step))
            ends.append(data.oMf[fid].copy())
        pairs.append((ends[0], ends[1]))
    return pairs


def fd_position_jacobian(robot: Robot, q: Array, frame: str, rows: slice, eps: float = 1e-6) -> Array:
    """Central differences of a frame position, on the tangent space."""
    pairs = perturbed_placements(robot, q, frame, eps)
    J = np.column_stack([(plus.translation - minus.translation) / (2 * eps) for plus, minus in pairs])
    return J[rows]


def fd_rotation_jacobian(robot: Robot, q: Array, frame: str, eps: float = 1e-6) -> Array:
    """World angular-velocity Jacobian of a frame by central differences: log3(R+ R-^T) / 2 eps."""
    pairs = perturbed_placements(robot, q, frame, eps)
    return np.column_stack([pin.log3(plus.rotation @ minus.rotation.T) / (2 * eps) for plus, minus in pairs])


def check_jacobians(robot: Robot, Q: Array) -> None:
    task_rows = slice(0, 2) if robot.task == "planar" else slice(0, 3)
    point_rows = task_rows
    for q in Q:
        result = avoidance(robot, q)
        expected = fd_position_jacobian(robot, q, robot.tip_frame, task_rows)
        np.testing.assert_allclose(result.J_task[task_rows], expected, atol=1e-7)
        if robot.task == "pose":
            np.testing.assert_allclose(result.J_task[3:], fd_rotation_jacobian(robot, q, robot.tip_frame), atol=1e-7)
        assert result.J_points.shape == (len(robot.control_points), point_rows.stop, robot.nv)
        for i, frame in enumerate(robot.control_points):
            expected = fd_position_jacobian(robot, q, frame, point_rows)
            np.testing.assert_allclose(result.J_points[i], expected, atol=1e-7, err_msg=frame)


@pytest.mark.parametrize("name", ["planar4", "panda", "ur5", "kinova"])
def test_jacobians_against_finite_differences(name: str, request: pytest.FixtureRequest) -> None:
    robot: Robot = request.getfixturevalue(name)
    rng = np.random.default_rng(11)
    Q = robot.random_configurations(rng, 3)
    if name == "kinova":
        assert (robot.nq, robot.nv) == (9, 6)
        assert Q.shape == (3, 9)
    check_jacobians(robot, Q)


def test_pose_task_jacobian_against_finite_differences() -> None:
    robot = previewctl.load_robot("ur5", task="pose")
    assert robot.task == "pose"
    rng = np.random.default_rng(5)
    check_jacobians(robot, robot.random_configurations(rng, 2))


@settings(max_examples=10, deadline=None)
@given(urdf=chain_urdfs(), seed=st.integers(0, 2**32 - 1))
def test_jacobians_random_chains(urdf: str, seed: int, tmp_path_factory: pytest.TempPathFactory) -> None:
    path = tmp_path_factory.mktemp("chain") / "chain.urdf"
    path.write_text(urdf)
    try:
        robot = previewctl.load_robot(path, task="position")
    except RobotLoadError as exc:  # a degenerate draw (e.g. every origin at 0): refused, and rightly
        assert "has no control point" in str(exc) or "cannot follow task 'position'" in str(exc)
        reject()
    check_jacobians(robot, robot.random_configurations(np.random.default_rng(seed), 1))


# ------------------------------------------------------------------------------ hand computation


def test_unit_ball_volume() -> None:
    assert unit_ball_volume(1) == pytest.approx(2.0, rel=1e-15)
    assert unit_ball_volume(2) == pytest.approx(np.pi, rel=1e-15)
    assert unit_ball_volume(3) == pytest.approx(4.0 * np.pi / 3.0, rel=1e-15)


def planar4_by_hand(q: Array) -> tuple[Array, Array]:
    """(volumes V_1..V_3 [m, m^2, m], singular values) of planar4 from the link angles."""
    theta = np.cumsum(q)
    origins = np.zeros((5, 2))  # joint origins o_0..o_3, then the tip
    for k in range(4):
        origins[k + 1] = origins[k] + LINK * np.array([np.cos(theta[k]), np.sin(theta[k])])

    def jac(point: int) -> Array:
        """Planar Jacobian of origins[point]: column j is e_z x (r - o_j) for j < point."""
        J = np.zeros((2, 4))
        r = origins[point]
        for j in range(point):
            J[:, j] = [-(r[1] - origins[j, 1]), r[0] - origins[j, 0]]
        return J

    Jn = jac(4)
    N = np.eye(4) - np.linalg.pinv(Jn) @ Jn
    sv = np.array([np.linalg.svd(jac(i) @ N, compute_uv=False) for i in (1, 2, 3)])
    volumes = np.array([2.0 * sv[0, 0], np.pi * sv[1, 0] * sv[1, 1], 2.0 * sv[2, 0]])
    return volumes, sv


@pytest.mark.parametrize("q", [(0.4, 0.7, -0.5, 1.1), (-1.2, 0.3, 2.0, -0.8), (2.5, -1.9, 0.6, 0.25)])
def test_amsi_by_hand_planar4(planar4: Robot, q: tuple[float, ...]) -> None:
    qa = np.array(q)
    volumes, sv = planar4_by_hand(qa)
    expected = volumes[0] / 0.01 + volumes[1] / 0.01**2 + volumes[2] / 0.01
    result = avoidance(planar4, qa)
    np.testing.assert_allclose(result.singular_values, sv, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(result.volumes, volumes, rtol=1e-9)
    np.testing.assert_allclose(result.amsi, expected, rtol=1e-9)
    # the same number through both evaluation paths
    for method in ("planar", "general"):
        np.testing.assert_allclose(evaluate(planar4, None, qa, method=method).amsi, [expected], rtol=1e-9)
    # metres: the plain sum of the volumes
    in_metres = avoidance(planar4, qa, IndexParams(length_unit=1.0))
    np.testing.assert_allclose(in_metres.amsi, volumes.sum(), rtol=1e-9)
    # weights a_i multiply each term
    weighted = avoidance(planar4, qa, IndexParams(weights=(1.0, 0.0, 2.0), length_unit=1.0))
    np.testing.assert_allclose(weighted.amsi, volumes[0] + 2.0 * volumes[2], rtol=1e-9)


# ------------------------------------------------------------------------------ singularities


def test_volumes_continuous_where_m_loses_rank(planar4: Robot) -> None:
    """q* = (0.3, 0.5, 0, 0): links 3-4 aligned, J_n full rank, M_1 and M_2 lose rank.

    With the structural rank as p, V_i falls continuously to 0 instead of jumping to a
    lower-dimensional volume (design note "Rank drops")."""
    q_star = np.array([0.3, 0.5, 0.0, 0.0])
    at = avoidance(planar4, q_star)
    assert np.linalg.matrix_rank(at.J_task) == 2
    assert tuple(at.ranks) == (0, 1, 1)
    np.testing.assert_allclose(at.volumes[:2], 0.0, atol=1e-12)
    rng = np.random.default_rng(8)
    for _ in range(3):
        v = rng.normal(size=4)
        v /= np.linalg.norm(v)
        gaps = [np.abs(avoidance(planar4, q_star + eps * v).volumes - at.volumes).max() for eps in (1e-2, 1e-4, 1e-6)]
        assert gaps[-1] < 1e-5
        assert gaps[0] > gaps[1] > gaps[2]  # converging, no jump


def test_volumes_at_stretched_arm_nonnegative_and_area_vanishes(planar4: Robot) -> None:
    """q = 0 (arm stretched along +x): J_n has rank 1; V_2 falls continuously to 0."""
    at = avoidance(planar4, np.zeros(4))
    assert np.linalg.matrix_rank(at.J_task) == 1
    assert np.all(at.volumes >= 0.0)
    assert at.volumes[1] == pytest.approx(0.0, abs=1e-12)
    rng = np.random.default_rng(9)
    directions = [np.array([0.0, 1.0, 0.0, 0.0]), np.array([0.0, 1.0, 1.0, 1.0]), *rng.normal(size=(3, 4))]
    for v in directions:
        for eps in (1e-2, 1e-4, 1e-6):
            near = avoidance(planar4, eps * v)
            assert np.all(near.volumes >= 0.0)
            assert np.isfinite(near.amsi)
        assert near.volumes[1] < 1e-5


def test_volumes_at_hand_singularity_depend_on_approach(planar4: Robot) -> None:
    """Documented limitation: where J_n itself loses rank (stretched arm), N = I - J+ J gains a
    dimension and the limit of V_1, V_3 depends on the direction of approach (docs/math.md, "Rank")."""
    directions = (np.array([0.0, 1.0, 0.0, 0.0]), np.array([0.0, 1.0, 1.0, 1.0]))
    limits = [avoidance(planar4, 1e-5 * v).volumes for v in directions]
    assert abs(limits[0][0] - limits[1][0]) > 0.1
    assert np.all(np.isfinite(avoidance(planar4, np.zeros(4)).volumes))


# ------------------------------------------------------------------------ planar == general path


def obstacle_scene() -> Scene:
    """Sphere, a box turned about z straddling z = 0, a tilted capsule and a half-space."""
    lie_down = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # capsule axis along y
    return Scene(
        (
            Obstacle("ball", previewctl.Sphere(0.2), Static(np.array([1.2, 0.8, 0.05]))),
            Obstacle("box", previewctl.Box((0.3, 0.5, 0.4)), Static(np.array([-0.8, 1.0, 0.05]), rot_z(0.6))),
            Obstacle("bar", previewctl.Capsule(0.1, 0.6), Static(np.array([0.5, -1.2, 0.0]), rot_z(0.3) @ lie_down)),
            Obstacle("floor", previewctl.Halfspace((0.0, 1.0, 0.0), 0.0), Static(np.array([0.0, -2.0, 0.0]))),
        )
    )


def compare_paths(robot: Robot, scene: Scene, Q: Array, t: float = 0.0, distance_atol: float = 1e-6) -> None:
    """Planar closed form == general path; ``distance_atol`` [m] covers Coal's GJK tolerance."""
    fast = evaluate(robot, scene, Q, t, method="planar")
    slow = evaluate(robot, scene, Q, t, method="general")
    np.testing.assert_allclose(fast.amsi, slow.amsi, rtol=1e-7)
    np.testing.assert_array_equal(fast.collision, slow.collision)
    positive = slow.link_distances > 0
    np.testing.assert_array_equal(fast.link_distances > 0, positive)
    free = ~slow.collision
    # S = E prod(1 - phi(d_i)) with |phi'| <= 2 / d_0: Coal's GJK distance error (~1e-7 [m] for the box
    # and the capsule) propagates into S; bound it by the actual distance differences.
    d0 = previewctl.Potential().influence_distance
    gap = np.abs(np.where(positive, fast.link_distances - slow.link_distances, 0.0)).sum(axis=1)
    bound = 1e-7 * np.abs(slow.S) + slow.amsi * 2.0 / d0 * gap
    assert np.all(np.abs(fast.S - slow.S)[free] <= bound[free])
    far = free & (slow.min_distance >= d0)
    np.testing.assert_allclose(fast.S[far], slow.S[far], rtol=1e-7)
    np.testing.assert_array_equal(fast.S[~free], slow.S[~free])
    assert np.all(np.abs(fast.U - slow.U)[free] <= bound[free] + 1e-7 * np.abs(slow.amsi)[free])
    np.testing.assert_allclose(fast.link_distances[positive], slow.link_distances[positive], atol=distance_atol)
    np.testing.assert_allclose(fast.min_distance[free], slow.min_distance[free], atol=distance_atol)
    np.testing.assert_allclose(fast.tip_position, slow.tip_position, atol=1e-12)


def test_planar_path_equals_general_path(planar4: Robot) -> None:
    scene = obstacle_scene()
    ev = previewctl.Evaluator(planar4, scene)
    assert ev.uses_planar_path()
    rng = np.random.default_rng(2024)
    Q = rng.uniform(-np.pi, np.pi, size=(2000, 4))
    compare_paths(planar4, scene, Q)
    slow = evaluate(planar4, scene, Q, method="general")
    # the scene is meaningful: some configurations collide, some are inside the influence distance
    assert 0.02 < slow.collision.mean() < 0.8
    assert np.any((slow.min_distance > 0) & (slow.min_distance < 0.15))


@pytest.mark.parametrize("index", range(4))
def test_planar_path_equals_general_path_per_obstacle(planar4: Robot, index: int) -> None:
    """Each obstacle alone, so that none hides behind a closer one."""
    scene = Scene((obstacle_scene().obstacles[index],))
    Q = np.random.default_rng(100 + index).uniform(-np.pi, np.pi, size=(300, 4))
    compare_paths(planar4, scene, Q)


def test_planar_path_equals_general_path_all_links_moving_obstacle() -> None:
    """guarded_links="all" (hand link too) and a moving obstacle at t = 1.5 s."""
    robot = previewctl.load_robot("planar4", guarded_links="all")
    assert robot.planar is not None
    moving = ConstantVelocity(np.array([0.5, 0.5, 0.0]), np.array([0.4, -0.2, 0.0]))
    scene = Scene((Obstacle("runner", previewctl.Sphere(0.25), moving),))
    Q = np.random.default_rng(77).uniform(-np.pi, np.pi, size=(300, 4))
    compare_paths(robot, scene, Q, t=1.5)
    assert evaluate(robot, scene, Q, 1.5).link_distances.shape == (300, 4)


def test_planar_path_equals_general_path_vertical_cylinder(planar4: Robot) -> None:
    """Coal's cylinder distance runs through GJK, accurate to a few 1e-6 [m] (not 1e-9)."""
    flip = np.diag([1.0, -1.0, -1.0])
    scene = Scene(
        (
            Obstacle("post", previewctl.Cylinder(0.2, 0.5), Static(np.array([0.9, -0.7, 0.1]))),
            Obstacle("crate", previewctl.Box((0.3, 0.5, 0.4)), Static(np.array([0.8, 0.6, 0.1]), rot_z(0.4) @ flip)),
        )
    )
    assert previewctl.Evaluator(planar4, scene).uses_planar_path()
    Q = np.random.default_rng(55).uniform(-np.pi, np.pi, size=(300, 4))
    compare_paths(planar4, scene, Q, distance_atol=5e-6)


def test_planar_path_control_point_at_base(planar4: Robot) -> None:
    """A control point that never moves (joint1's origin) has V = 0 on both paths."""
    robot = previewctl.load_robot("planar4", control_points=["joint1", "joint3"])
    assert tuple(robot.structural_ranks) == (0, 2)
    assert robot.planar is not None
    Q = np.random.default_rng(56).uniform(-np.pi, np.pi, size=(50, 4))
    general = evaluate(robot, None, Q, method="general")
    np.testing.assert_allclose(avoidance(robot, Q).volumes[:, 0], 0.0)
    np.testing.assert_allclose(evaluate(robot, None, Q, method="planar").amsi, general.amsi, rtol=1e-9)


# --------------------------------------------------------------------- batched kinematics, Gram inverse


@pytest.mark.parametrize("name", ["panda", "kinova", "planar4"])
def test_frame_kinematics_equals_pinocchio(name: str, request: pytest.FixtureRequest) -> None:
    """Every frame's placement and world-aligned Jacobian, assembled for the batch, equal Pinocchio's own."""
    from previewctl.kinematics import FrameKinematics

    robot: Robot = request.getfixturevalue(name)
    model = robot.model
    frame_ids = tuple(range(1, len(model.frames)))  # frames with offsets, on and off the chain
    Q = robot.random_configurations(np.random.default_rng(3), 4)
    placements, jacobians = FrameKinematics(model, frame_ids)(Q)
    data = model.createData()
    for b, q in enumerate(Q):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for k, fid in enumerate(frame_ids):
            np.testing.assert_allclose(placements[b, k], data.oMf[fid].homogeneous, atol=1e-12)
            expected = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            np.testing.assert_allclose(jacobians[b, k], expected, atol=1e-12, err_msg=model.frames[fid].name)


@pytest.mark.parametrize("name", ["panda", "kinova", "planar4"])
@pytest.mark.parametrize("batch", [1, 7])
def test_frame_kinematics_keeps_the_bits_of_its_numpy_assembly(name: str, batch: int,
                                                                request: pytest.FixtureRequest) -> None:
    """The compiled assembly equals, bit for bit, the numpy expressions it replaced (the golden runs rely on it): the
    frames with offsets, the universe and extra joints among the followed ones, and partial supports."""
    from previewctl.kinematics import _SKEW_SIGNS, _SKEW_SLOTS, _SKEW_SOURCES, FrameKinematics

    robot: Robot = request.getfixturevalue(name)
    frame_ids = tuple(range(1, len(robot.model.frames)))
    reader = FrameKinematics(robot.model, frame_ids, joints=(0, robot.model.njoints - 1, 1))
    Q = robot.random_configurations(np.random.default_rng(batch), batch)
    placements, jacobians = reader(Q)
    followed, J = reader._pinocchio(Q, None)
    followed = np.concatenate([np.broadcast_to(np.eye(4), (batch, 1, 4, 4)), followed], axis=1)
    np.testing.assert_array_equal(reader.joint_placements, followed[:, reader._joint_slot])
    frames = followed[:, reader._slot]
    frames[:, reader._moved] = frames[:, reader._moved] @ reader._offset
    K = len(frame_ids)
    cross = np.zeros((batch, K, 9))
    cross[:, :, _SKEW_SLOTS] = frames[:, :, _SKEW_SOURCES, 3] * _SKEW_SIGNS
    expected = np.empty((batch, K, 6, robot.nv))
    expected[:, :, :3] = (cross.reshape(batch, 3 * K, 3) @ J[:, 3:]).reshape(batch, K, 3, robot.nv)
    expected[:, :, :3] += J[:, None, :3]
    expected[:, :, 3:] = J[:, None, 3:]
    expected *= reader._support
    assert reader._universe and reader._moved.size and not reader._support.all()
    np.testing.assert_array_equal(placements, frames)
    np.testing.assert_array_equal(jacobians, expected)


@pytest.mark.parametrize("m", [1, 2, 3, 6])
def test_gram_pseudo_inverse_against_pinv(m: int) -> None:
    """(J J^T)^+ equals numpy's pinv for well-conditioned, ill-conditioned and rank-deficient J."""
    from previewctl.index.amsi import gram_pseudo_inverse

    rng = np.random.default_rng(m)
    stacks = []
    for spread in (1.0, 1e-5, 0.0):  # smallest singular value relative to the others
        U = np.linalg.qr(rng.normal(size=(m, m)))[0]
        V = np.linalg.qr(rng.normal(size=(7, 7)))[0][:m]
        sigma = np.ones(m)
        sigma[-1] = spread
        stacks.append((U * sigma) @ V)
    J = np.array(stacks)
    got = gram_pseudo_inverse(J)
    for b in range(len(J)):
        expected = np.linalg.pinv(J[b] @ J[b].T, rcond=1e-15, hermitian=True)
        np.testing.assert_allclose(got[b], expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
