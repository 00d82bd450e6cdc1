"""Tests of the redundancy maps (:mod:`previewctl.search.redundancy`, :mod:`previewctl.search.maps`,
:mod:`previewctl.search.newton`, :mod:`previewctl.search.planar`) and of
:mod:`previewctl.search.scoring`: the planar closed form and the general Newton map put the hand on
the target.

Tolerances: the closed form is exact to 1e-9 m; the Newton map promises its ``tolerance`` (1e-4 m by
default) on every configuration it flags reachable.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot, shipped_robots_dir
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Box, Obstacle, Scene, Sphere
from previewctl.search.maps import redundancy_map
from previewctl.search.newton import NewtonRedundancy
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.redundancy import parse_target, wrap_angle
from previewctl.search.scoring import score

PLANAR_TOL = 1e-9  # [m]
NEWTON_TOL = 1e-4  # [m], NewtonRedundancy's default tolerance


def tip_positions(robot: Robot, Q: np.ndarray) -> np.ndarray:
    """Hand positions ``(B, 3)`` by Pinocchio forward kinematics (independent of the maps)."""
    data = robot.model.createData()
    out = np.empty((len(Q), 3))
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(robot.model, data, q)
        out[k] = data.oMf[robot.tip_frame_id].translation
    return out


# ------------------------------------------------------------------------------------ planar map


def test_redundancy_map_picks_the_closed_form_for_planar4(planar4: Robot) -> None:
    red = redundancy_map(planar4)
    assert isinstance(red, PlanarRedundancy)
    assert red.branches == 2
    assert red.gene_lower.shape == (2,) and red.periodic.all()
    assert red.link_lengths == pytest.approx((0.75, 0.75))
    assert isinstance(redundancy_map(planar4, general=True), NewtonRedundancy)


@pytest.mark.parametrize("target", [(0.85, 0.65), (0.10, 1.40), (1.60, -0.10), (-0.3, 0.2)])
def test_planar_solve_reaches_target_on_both_branches(planar4: Robot, target: tuple[float, float]) -> None:
    red = PlanarRedundancy(planar4)
    rng = np.random.default_rng(1)
    genes = rng.uniform(-np.pi, np.pi, (400, 2))
    for branch in (0, 1):
        Q, ok = red.solve(genes, np.full(400, branch), np.array(target))
        assert ok.sum() > 40
        assert np.all(np.isfinite(Q))
        assert Q.min() >= -np.pi and Q.max() < np.pi
        tips = tip_positions(planar4, Q[ok])
        np.testing.assert_allclose(tips[:, :2], np.broadcast_to(target, (ok.sum(), 2)), atol=PLANAR_TOL)
        np.testing.assert_allclose(Q[:, :2], wrap_angle(genes))
        q4 = Q[ok, 3]
        assert np.all(q4 >= 0) if branch == 0 else np.all(q4 <= 0)


def test_planar_unreachable_genes_are_flagged_and_score_negative(planar4: Robot) -> None:
    red = PlanarRedundancy(planar4)
    target = np.array([2.0, 0.5])
    # wrist (joint 3 origin) pointing away from the target: 1.5 m + more than 1.5 m away -> unreachable
    genes = np.array([[np.pi, 0.0], [0.0, 0.0], [np.pi / 2, np.pi]])
    Q, ok = red.solve(genes, np.zeros(3, dtype=int), target)
    assert ok.tolist() == [False, True, False]
    assert np.all(np.isfinite(Q))
    # the unreachable arm is stretched toward the target: last two links aligned (q4 = 0)
    assert Q[0, 3] == pytest.approx(0.0)
    ev = Evaluator(planar4)
    S = score(ev, red, genes, np.zeros(3, dtype=int), target).S
    assert S[0] == ev.potential.collision_value < 0 and S[2] < 0
    assert S[1] >= 0


def test_planar_target_out_of_the_plane_is_unreachable(planar4: Robot) -> None:
    red = PlanarRedundancy(planar4)
    _, ok = red.solve(np.zeros((2, 2)), np.array([0, 1]), np.array([1.0, 0.5, 0.2]))
    assert not ok.any()


def test_planar_genes_of_inverts_solve(planar4: Robot) -> None:
    red = PlanarRedundancy(planar4)
    rng = np.random.default_rng(2)
    genes = rng.uniform(-3 * np.pi, 3 * np.pi, (300, 2))
    branch = rng.integers(0, 2, 300)
    Q, ok = red.solve(genes, branch, np.array([0.85, 0.65]))
    g2, b2 = red.genes_of(Q[ok])
    np.testing.assert_allclose(g2, wrap_angle(genes[ok]), atol=1e-12)
    assert np.array_equal(b2, branch[ok])
    Q2, ok2 = red.solve(g2, b2, np.array([0.85, 0.65]))
    assert ok2.all()
    np.testing.assert_allclose(Q2, Q[ok], atol=1e-9)


def test_planar_solve_grid_matches_solve(planar4: Robot) -> None:
    red = PlanarRedundancy(planar4)
    axes = (np.radians(np.arange(0, 360, 15.0)), np.radians(np.arange(0, 360, 20.0)))
    Qg, okg = red.solve_grid(axes, np.array([1.6, 0.65]))
    mesh = np.meshgrid(*axes, indexing="ij")
    genes = np.stack([m.ravel() for m in mesh], axis=1)
    Q, ok = red.solve(np.tile(genes, (2, 1)), np.repeat([0, 1], len(genes)), np.array([1.6, 0.65]))
    np.testing.assert_allclose(Qg, Q, atol=1e-12)
    assert np.array_equal(okg, ok)


def test_planar_map_respects_narrow_joint_limits(tmp_path: Path) -> None:
    text = (shipped_robots_dir() / "planar4.urdf").read_text()
    text = text.replace('lower="-6.283185307179586" upper="6.283185307179586"', 'lower="-2.0" upper="2.0"')
    urdf = tmp_path / "narrow.urdf"
    urdf.write_text(text)
    robot = load_robot(urdf)
    red = redundancy_map(robot)
    assert isinstance(red, PlanarRedundancy) and not red.periodic.any()
    rng = np.random.default_rng(3)
    genes = rng.uniform(-2.0, 2.0, (500, 2))
    Q, ok = red.solve(genes, rng.integers(0, 2, 500), np.array([1.2, 0.8]))
    assert ok.any() and not ok.all()
    assert np.all((Q[ok] >= -2.0) & (Q[ok] <= 2.0))
    np.testing.assert_allclose(tip_positions(robot, Q[ok])[:, :2], np.broadcast_to([1.2, 0.8], (ok.sum(), 2)),
                               atol=PLANAR_TOL)


def test_planar_bad_inputs_raise(planar4: Robot) -> None:
    red = PlanarRedundancy(planar4)
    with pytest.raises(ConfigurationError, match="genes has shape"):
        red.solve(np.zeros((3, 3)), np.zeros(3, dtype=int), np.array([1.0, 1.0]))
    with pytest.raises(ConfigurationError, match="branch 2 out of range"):
        red.solve(np.zeros((1, 2)), np.array([2]), np.array([1.0, 1.0]))
    with pytest.raises(ConfigurationError, match="target position has shape"):
        red.solve(np.zeros((1, 2)), np.array([0]), np.array([1.0, 1.0, 0.0, 0.0]))
    with pytest.raises(ConfigurationError, match="finite"):
        red.solve(np.zeros((1, 2)), np.array([0]), np.array([np.nan, 1.0]))


# ------------------------------------------------------------------------------------ Newton map


@pytest.mark.parametrize("name", ["panda", "ur5"])
@pytest.mark.parametrize("target", [(0.4, 0.2, 0.5), (0.5, -0.3, 0.3)])
def test_newton_map_puts_hand_on_target(
    name: str, target: tuple[float, float, float], request: pytest.FixtureRequest
) -> None:
    robot: Robot = request.getfixturevalue(name)
    red = redundancy_map(robot)
    assert isinstance(red, NewtonRedundancy) and red.branches == 1
    rng = np.random.default_rng(4)
    genes = rng.uniform(red.gene_lower, red.gene_upper, (60, robot.nv))
    Q, ok = red.solve(genes, np.zeros(60, dtype=int), np.array(target))
    assert ok.mean() > 0.6  # from uniformly random starts; the GA repairs the rest
    err = np.linalg.norm(tip_positions(robot, Q[ok]) - np.array(target), axis=1)
    assert err.max() < NEWTON_TOL
    assert np.all(robot.lower_limits - 1e-12 <= Q) and np.all(robot.upper_limits + 1e-12 >= Q)
    # genes_of inverts solve: the genes of a solution solve to itself, already converged
    g2, b2 = red.genes_of(Q[ok])
    assert np.all(b2 == 0)
    Q2, ok2 = red.solve(g2, b2, np.array(target))
    assert ok2.all()
    np.testing.assert_allclose(Q2, Q[ok], atol=1e-12)


def test_newton_unreachable_target_is_flagged_and_scores_negative(panda: Robot) -> None:
    red = NewtonRedundancy(panda, iterations=15)
    rng = np.random.default_rng(5)
    genes = rng.uniform(red.gene_lower, red.gene_upper, (8, panda.nv))
    target = np.array([3.0, 0.0, 0.5])  # 3 m away: the Panda reaches < 1 m
    Q, ok = red.solve(genes, np.zeros(8, dtype=int), target)
    assert not ok.any() and np.all(np.isfinite(Q))
    ev = Evaluator(panda)
    scored = score(ev, red, genes, np.zeros(8, dtype=int), target)
    np.testing.assert_array_equal(scored.S, ev.potential.collision_value)
    assert scored.S.max() < 0


def test_newton_solve_many_equals_solve_per_target(panda: Robot) -> None:
    """Rows aimed at different targets in one call give exactly what one call per target gives, warm-started or
    not."""
    red = NewtonRedundancy(panda)
    genes = np.random.default_rng(8).uniform(red.gene_lower, red.gene_upper, (12, panda.nv))
    targets = [np.array([0.45, 0.1, 0.45]), np.array([0.3, -0.3, 0.6])]
    groups = np.array([0, 1] * 6)
    Q, ok = red.solve_many(genes, np.zeros(12, dtype=int), targets, groups)
    seeds = genes + 0.05  # warm starts away from the genes: the roadmap's sub-steps start from their guesses
    Q_seeded, ok_seeded = red.solve_many(genes, np.zeros(12, dtype=int), targets, groups, q_seed=seeds)
    for k, target in enumerate(targets):
        Qk, okk = red.solve(genes[groups == k], np.zeros(6, dtype=int), target)
        np.testing.assert_array_equal(Q[groups == k], Qk)
        np.testing.assert_array_equal(ok[groups == k], okk)
        Qk, okk = red.solve(genes[groups == k], np.zeros(6, dtype=int), target, q_seed=seeds[groups == k])
        np.testing.assert_array_equal(Q_seeded[groups == k], Qk)
        np.testing.assert_array_equal(ok_seeded[groups == k], okk)
    assert ok.any() and not np.array_equal(Q, Q_seeded)
    for bad in (np.array([0, 2] * 6), np.zeros(5, dtype=int), np.full(12, 0.5)):
        with pytest.raises(ConfigurationError, match="groups"):
            red.solve_many(genes, np.zeros(12, dtype=int), targets, bad)


def test_newton_q_seed_warm_start(panda: Robot) -> None:
    red = NewtonRedundancy(panda, iterations=3)
    rng = np.random.default_rng(6)
    genes = rng.uniform(red.gene_lower, red.gene_upper, (20, panda.nv))
    target = np.array([0.45, 0.1, 0.45])
    Q_full, ok_full = NewtonRedundancy(panda).solve(genes, np.zeros(20, dtype=int), target)
    moved = target + np.array([0.02, 0.0, 0.0])
    _, cold = red.solve(genes, np.zeros(20, dtype=int), moved)
    Q_warm, warm = red.solve(genes, np.zeros(20, dtype=int), moved, q_seed=Q_full)
    assert warm[ok_full].mean() > cold[ok_full].mean()
    assert warm[ok_full].all()
    err = np.linalg.norm(tip_positions(panda, Q_warm[warm]) - moved, axis=1)
    assert err.max() < NEWTON_TOL


@pytest.mark.parametrize(
    ("rotation", "fragments"),
    [
        (np.diag([1.0, 1.0, -1.0]), ["target rotation", "rotation matrix", "det = -1"]),
        (2.0 * np.eye(3), ["target rotation", "rotation matrix", "max|R^T R - I| = 3"]),
    ],
)
def test_pose_target_with_a_bad_rotation_is_refused(panda: Robot, rotation: np.ndarray, fragments: list[str]) -> None:
    with pytest.raises(ConfigurationError) as info:
        parse_target((np.array([0.4, 0.0, 0.4]), rotation), panda)
    for fragment in fragments:
        assert fragment in str(info.value)


def test_newton_pose_task(request: pytest.FixtureRequest) -> None:
    robot = load_robot("panda", task="pose")
    red = redundancy_map(robot)
    rng = np.random.default_rng(7)
    q_goal = robot.random_configurations(rng, 1)[0]
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q_goal)
    goal = data.oMf[robot.tip_frame_id].copy()
    genes = np.array(q_goal) + rng.normal(0.0, 0.15, (10, robot.nv))
    Q, ok = red.solve(genes, np.zeros(10, dtype=int), (goal.translation, goal.rotation))
    assert ok.mean() >= 0.8
    for q in Q[ok]:
        pin.framesForwardKinematics(robot.model, data, q)
        reached = data.oMf[robot.tip_frame_id]
        assert np.linalg.norm(reached.translation - goal.translation) < NEWTON_TOL
        assert np.linalg.norm(pin.log3(goal.rotation @ reached.rotation.T)) < 1e-3
    with pytest.raises(ConfigurationError, match="pose task"):
        red.solve(genes, np.zeros(10, dtype=int), goal.translation)
    # the same pose as an SE3 or a 4x4 matrix
    assert np.allclose(parse_target(goal, robot).position, parse_target(goal.homogeneous, robot).position)


def test_newton_map_with_continuous_joints(tmp_path: Path) -> None:
    """Continuous joints have nq = 2, nv = 1: genes stay angles, steps go through pin.integrate."""
    text = (shipped_robots_dir() / "planar4.urdf").read_text().replace('type="revolute"', 'type="continuous"')
    urdf = tmp_path / "continuous.urdf"
    urdf.write_text(text)
    robot = load_robot(urdf, task="planar")  # in the plane: "position" is refused (the hand cannot leave it)
    assert robot.nq == 8 and robot.nv == 4
    red = redundancy_map(robot)
    assert isinstance(red, NewtonRedundancy) and red.periodic.all()
    rng = np.random.default_rng(8)
    genes = rng.uniform(-np.pi, np.pi, (40, 4))
    target = np.array([0.85, 0.65, 0.0])
    Q, ok = red.solve(genes, np.zeros(40, dtype=int), target)
    assert ok.mean() > 0.8
    assert np.allclose(Q[:, 0::2] ** 2 + Q[:, 1::2] ** 2, 1.0)  # (cos, sin) pairs stay normalised
    assert np.linalg.norm(tip_positions(robot, Q[ok]) - target, axis=1).max() < NEWTON_TOL
    g2, _ = red.genes_of(Q[ok])
    assert np.all((g2 >= -np.pi) & (g2 < np.pi))
    Q2, ok2 = red.solve(g2, 0, target)
    assert ok2.all() and np.allclose(Q2, Q[ok], atol=1e-9)


def test_newton_on_planar4_agrees_with_closed_form(planar4: Robot) -> None:
    red = NewtonRedundancy(planar4)
    closed = PlanarRedundancy(planar4)
    rng = np.random.default_rng(9)
    genes = rng.uniform(-np.pi, np.pi, (30, 4))
    Q, ok = red.solve(genes, np.zeros(30, dtype=int), np.array([0.85, 0.65]))
    assert ok.mean() > 0.8
    g, b = closed.genes_of(Q[ok])
    Qc, okc = closed.solve(g, b, np.array([0.85, 0.65]))
    assert okc.all()
    np.testing.assert_allclose(wrap_angle(Qc - Q[ok]), 0.0, atol=2e-4)


def test_score_evaluates_only_reachable_and_matches_evaluator(planar4: Robot) -> None:
    scene = Scene((
        Obstacle("ball", Sphere(0.2), Static(np.array([0.3, 0.9, 0.0]))),
        Obstacle("table", Box((1.2, 0.4, 0.4)), Static(np.array([1.3, -0.55, 0.0]))),
    ))
    ev = Evaluator(planar4, scene)
    red = PlanarRedundancy(planar4)
    rng = np.random.default_rng(10)
    genes = rng.uniform(-np.pi, np.pi, (500, 2))
    branch = rng.integers(0, 2, 500)
    scored = score(ev, red, genes, branch, np.array([0.85, 0.65]))
    direct = ev(scored.Q)
    np.testing.assert_allclose(scored.S[scored.reachable], direct.S[scored.reachable])
    assert np.array_equal(scored.collision[scored.reachable], direct.collision[scored.reachable])
    assert np.all(scored.S[~scored.reachable] == ev.potential.collision_value)
    assert np.array_equal(scored.S < 0, ~scored.reachable | scored.collision)


@pytest.mark.parametrize(("name", "task"), [("planar4", None), ("panda", None), ("ur5", "pose")])
def test_newton_step_is_the_damped_least_squares_step_with_frozen_limits(name: str, task: str | None) -> None:
    """The compiled step against its formula in numpy, for tasks of 2, 3 and 6 rows: ``e`` clamped to ``max_step``,
    ``λ² = d² clip(|e| / max_step, 1e-3, 1)``, ``Jᵀ (J Jᵀ + λ² I)⁻¹ e``, again without the columns of joints at a
    limit pushed further."""
    robot = load_robot(name) if task is None else load_robot(name, task=task)
    red = NewtonRedundancy(robot)
    m = red.m
    rng = np.random.default_rng(m)
    J = rng.normal(size=(40, m, robot.nv))
    err = rng.normal(size=(40, m)) * rng.choice([0.01, 1.0], size=(40, 1))  # within and beyond max_step
    Q = robot.random_configurations(rng, 40)
    at_limit = rng.random(Q.shape) < 0.3
    Q = np.where(at_limit, np.where(rng.random(Q.shape) < 0.5, robot.lower_limits, robot.upper_limits), Q)
    step = red._step(J, err, Q)

    def reference(Jb: np.ndarray, e: np.ndarray) -> np.ndarray:
        norm = np.linalg.norm(e[: min(m, 3)])
        e = e * min(1.0, red.max_step / norm)
        damping = red.damping**2 * np.clip(np.linalg.norm(e[: min(m, 3)]) / red.max_step, 1e-3, 1.0)
        return Jb.T @ np.linalg.solve(Jb @ Jb.T + damping * np.eye(m), e)

    frozen_rows = 0
    for b in range(40):
        free = reference(J[b], err[b])
        pushed = (Q[b] <= robot.lower_limits + 1e-9) & (free < 0) | (Q[b] >= robot.upper_limits - 1e-9) & (free > 0)
        frozen_rows += pushed.any()
        expected = reference(J[b] * ~pushed, err[b]) if pushed.any() else free
        np.testing.assert_allclose(step[b], expected, rtol=1e-8, atol=1e-12)
        assert not np.any(step[b][pushed])
    assert frozen_rows > 5  # the frozen case is exercised
