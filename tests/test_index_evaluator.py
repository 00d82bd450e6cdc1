"""Tests of :mod:`previewctl.index.evaluator` (AMSIP, eq. 18) and :mod:`previewctl.index.potential`:
distances against closed forms and against Coal directly, the potential's sign and monotonicity, its
validation, and batch against one-at-a-time evaluation."""

from __future__ import annotations

import dataclasses
from dataclasses import fields
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
from numpy.typing import NDArray

import previewctl
from previewctl import (
    Evaluator,
    IndexParams,
    Obstacle,
    ParameterError,
    Potential,
    PreviewctlError,
    Scene,
    avoidance,
    evaluate,
)
from previewctl.control.nullspace import AmsipGradient
from previewctl.control.params import ControllerParams
from previewctl.robot.model import Robot
from previewctl.scene.motion import ConstantVelocity, Static
from previewctl.search.scoring import score_configurations

Array = NDArray[np.float64]
LINK, RADIUS = 0.75, 0.03  # planar4 link length and capsule radius [m]
METHODS = ("planar", "general")
# Coal's GJK stops at DistanceRequest().gjk_tolerance = 1e-6 [m]: convex-hull and box distances
# carry errors up to that (measured ~3.5e-7 [m] on panda).
GJK_TOL = 1e-6


def sphere_at(center: tuple[float, float, float], radius: float, name: str = "ball") -> Obstacle:
    return Obstacle(name, previewctl.Sphere(radius), Static(np.array(center, dtype=float)))


def point_segment_distance(p: Array, a: Array, b: Array) -> float:
    d = b - a
    t = np.clip((p - a) @ d / (d @ d), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * d)))


# ------------------------------------------------------------------------------ closed forms


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    ("center", "radius"),
    [
        ((1.0, 0.5, 0.0), 0.1),
        ((-0.3, 0.2, 0.0), 0.05),
        ((2.6, -0.4, 0.0), 0.2),
        ((1.9, 0.1, 0.0), 0.02),
        ((0.4, -0.3, 0.15), 0.1),  # off the plane: the distance is 3-D
    ],
)
def test_sphere_distances_closed_form(
    planar4: Robot, method: str, center: tuple[float, float, float], radius: float
) -> None:
    """planar4 at q = 0 lies along +x: link i's axis runs from (0.75 i, 0) to (0.75 (i + 1), 0)."""
    assert planar4.guarded_links == ("link1", "link2", "link3", "link4")
    result = evaluate(planar4, Scene((sphere_at(center, radius),)), np.zeros(4), method=method)
    p = np.array(center)
    expected = np.array(
        [
            point_segment_distance(p, np.array([LINK * i, 0.0, 0.0]), np.array([LINK * (i + 1), 0.0, 0.0]))
            - radius
            - RADIUS
            for i in range(4)
        ]
    )
    assert result.link_distances.shape == (1, 4)
    np.testing.assert_allclose(result.link_distances[0], expected, atol=1e-9)
    np.testing.assert_allclose(result.min_distance, [expected.min()], atol=1e-9)
    assert not result.collision[0]
    np.testing.assert_allclose(result.tip_position, [[3.0, 0.0, 0.0]], atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_halfspace_distance_closed_form(planar4: Robot, method: str) -> None:
    """The half-space y <= -0.2 is 0.2 - 0.03 from every link of the stretched arm."""
    floor = Obstacle("floor", previewctl.Halfspace((0.0, 1.0, 0.0), -0.2))
    result = evaluate(planar4, Scene((floor,)), np.zeros(4), method=method)
    np.testing.assert_allclose(result.link_distances, [[0.17] * 4], atol=1e-9)
    np.testing.assert_allclose(result.min_distance, [0.17], atol=1e-9)
    # the same half-space given by its placement instead of its offset
    moved = Obstacle("floor", previewctl.Halfspace((0.0, 1.0, 0.0), 0.0), Static(np.array([5.0, -0.2, 0.0])))
    np.testing.assert_allclose(
        evaluate(planar4, Scene((moved,)), np.zeros(4), method=method).link_distances, [[0.17] * 4], atol=1e-9
    )


@pytest.mark.parametrize("method", METHODS)
def test_sphere_distance_bent_arm(planar4: Robot, method: str) -> None:
    """q = (pi/2, -pi/2, 0, 0): link 1 goes up the y axis to (0, 0.75), links 2-4 along +x from there."""
    q = np.array([np.pi / 2, -np.pi / 2, 0.0, 0.0])
    p = np.array([0.9, 0.3, 0.0])
    result = evaluate(planar4, Scene((sphere_at(tuple(p), 0.1),)), q, method=method)
    corners = ([0, 0, 0], [0, 0.75, 0], [0.75, 0.75, 0], [1.5, 0.75, 0], [2.25, 0.75, 0])
    ends = [np.array(v, dtype=float) for v in corners]
    expected = [point_segment_distance(p, ends[i], ends[i + 1]) - 0.1 - RADIUS for i in range(4)]
    np.testing.assert_allclose(result.link_distances[0], expected, atol=1e-9)
    np.testing.assert_allclose(result.tip_position, [[2.25, 0.75, 0.0]], atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_the_hand_link_may_touch_the_work_surface_and_nothing_else(planar4: Robot, method: str) -> None:
    """The stretched arm's hand link (link 4, x in [2.25, 3]) dips 2 cm into a ball at (2.6, 0.1)."""
    ball = sphere_at((2.6, 0.1, 0.0), 0.09)
    touching = evaluate(planar4, Scene((ball,)), np.zeros(4), method=method)
    assert touching.collision[0] and touching.link_distances[0, 3] == pytest.approx(-0.02, abs=1e-9)
    surface = dataclasses.replace(ball, work_surface=True)
    worked = evaluate(planar4, Scene((surface,)), np.zeros(4), method=method)
    assert not worked.collision[0] and worked.link_distances[0, 3] == np.inf
    np.testing.assert_allclose(worked.link_distances[0, :3], touching.link_distances[0, :3], atol=1e-12)
    # link 3 (x in [1.5, 2.25]) is still guarded against the work surface
    deep = dataclasses.replace(surface, motion=Static(np.array([2.2, 0.1, 0.0])))
    assert evaluate(planar4, Scene((deep,)), np.zeros(4), method=method).collision[0]


# ------------------------------------------------------------------------------ Coal cross-check


def coal_link_distances(robot: Robot, q: Array, shape: coal.CollisionGeometry, placement: pin.SE3) -> Array:
    """Per guarded link, the minimum of ``coal.distance`` (fresh request/result per pair)."""
    model, gmodel = robot.model, robot.collision_model
    data, gdata = model.createData(), gmodel.createData()
    pin.updateGeometryPlacements(model, data, gmodel, gdata, q)
    out = np.full(len(robot.guarded_links), np.inf)
    tf_obstacle = coal.Transform3s(placement.rotation, placement.translation)
    for g, geom in enumerate(gmodel.geometryObjects):
        link = robot.guarded_links.index(model.frames[geom.parentFrame].name)
        oMg = gdata.oMg[g]
        d = coal.distance(
            geom.geometry,
            coal.Transform3s(oMg.rotation, oMg.translation),
            shape,
            tf_obstacle,
            coal.DistanceRequest(),
            coal.DistanceResult(),
        )
        out[link] = min(out[link], d)
    return out


def random_spheres_near_arm(robot: Robot, rng: np.random.Generator, Q: Array) -> list[Array]:
    """For each configuration, a centre 0.1-0.35 m from a random control point."""
    data = robot.model.createData()
    centres = []
    for q in Q:
        pin.framesForwardKinematics(robot.model, data, q)
        fid = robot.control_frame_ids[rng.integers(len(robot.control_frame_ids))]
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        centres.append(np.array(data.oMf[fid].translation) + rng.uniform(0.1, 0.35) * direction)
    return centres


@pytest.mark.parametrize("robot_name", ["panda", "panda_mesh"])
def test_distances_match_coal(robot_name: str, request: pytest.FixtureRequest) -> None:
    """Evaluator distances (one Pinocchio geometry pass, reused buffers) == direct coal.distance."""
    robot: Robot = request.getfixturevalue(robot_name)
    rng = np.random.default_rng(42)
    Q = robot.random_configurations(rng, 8)
    centres = random_spheres_near_arm(robot, rng, Q)
    radius = 0.06
    positives = 0
    for q, centre in zip(Q, centres, strict=True):
        scene = Scene((sphere_at(tuple(centre), radius),))
        ours = evaluate(robot, scene, q, method="general")
        direct = coal_link_distances(robot, q, coal.Sphere(radius), pin.SE3(np.eye(3), centre))
        free = direct > 0
        positives += int(free.sum())
        np.testing.assert_allclose(ours.link_distances[0][free], direct[free], atol=1e-6)
        assert np.all(ours.link_distances[0][~free] <= 1e-6)
        assert ours.collision[0] == bool((direct <= 0).any())
    assert positives >= 20
    # one Evaluator, one batch, every sphere in turn: same numbers (no stale Coal results)
    evaluator = Evaluator(robot, Scene((sphere_at(tuple(centres[0]), radius),)))
    batch = evaluator(Q)
    for b, q in enumerate(Q):
        direct = coal_link_distances(robot, q, coal.Sphere(radius), pin.SE3(np.eye(3), centres[0]))
        free = direct > 0
        np.testing.assert_allclose(batch.link_distances[b][free], direct[free], atol=1e-6)


# ------------------------------------------------------------------------------ the potential


def test_collision_gives_negative_s(planar4: Robot) -> None:
    """A sphere through link 2 -> collision, S = collision_value < 0; moved away -> S >= 0."""
    q = np.array([0.4, 0.7, -0.5, 1.1])
    theta = np.cumsum(q)
    o1 = LINK * np.array([np.cos(theta[0]), np.sin(theta[0])])
    o2 = o1 + LINK * np.array([np.cos(theta[1]), np.sin(theta[1])])
    mid = 0.5 * (o1 + o2)
    for method in METHODS:
        hit = evaluate(planar4, Scene((sphere_at((mid[0], mid[1], 0.0), 0.05),)), q, method=method)
        assert hit.collision[0]
        assert hit.link_distances[0, 1] < 0
        assert hit.S[0] == Potential().collision_value < 0
        np.testing.assert_allclose(hit.U, hit.S - hit.amsi)
        custom = evaluate(
            planar4,
            Scene((sphere_at((mid[0], mid[1], 0.0), 0.05),)),
            q,
            potential=Potential(collision_value=-7.5),
            method=method,
        )
        assert custom.S[0] == -7.5
        normal = np.array([-np.sin(theta[1]), np.cos(theta[1])])
        away = mid + 0.2 * normal
        clear = evaluate(planar4, Scene((sphere_at((away[0], away[1], 0.0), 0.05),)), q, method=method)
        assert not clear.collision[0]
        assert 0.0 <= clear.S[0] < clear.amsi[0]


@pytest.mark.parametrize("method", METHODS)
def test_s_sign_is_collision(planar4: Robot, method: str) -> None:
    """Over random configurations: S < 0 <=> collision <=> min distance <= 0; U <= 0; S <= E."""
    scene = Scene(
        (
            sphere_at((1.0, 0.9, 0.0), 0.3),
            sphere_at((-1.2, -0.5, 0.0), 0.25, "ball2"),
            Obstacle("floor", previewctl.Halfspace((0.0, 1.0, 0.0), -1.6)),
        )
    )
    Q = np.random.default_rng(6).uniform(-np.pi, np.pi, size=(1500 if method == "planar" else 400, 4))
    result = evaluate(planar4, scene, Q, method=method)
    assert 0.05 < result.collision.mean() < 0.95
    np.testing.assert_array_equal(result.S < 0, result.collision)
    np.testing.assert_array_equal(result.collision, result.min_distance <= 0)
    assert np.all(result.U <= 0.0)
    assert np.all(result.S[~result.collision] >= 0.0)
    assert np.all(result.S - result.amsi <= 0.0)
    np.testing.assert_allclose(result.U, result.S - result.amsi)
    np.testing.assert_allclose(result.min_distance, result.link_distances.min(axis=1))
    # the AMSI does not depend on the scene
    np.testing.assert_allclose(result.amsi, avoidance(planar4, Q).amsi, rtol=1e-9)


@pytest.mark.parametrize("robot_name", ["planar4", "panda"])
def test_s_equals_amsi_without_nearby_obstacles(robot_name: str, request: pytest.FixtureRequest) -> None:
    robot: Robot = request.getfixturevalue(robot_name)
    Q = robot.random_configurations(np.random.default_rng(12), 30)
    empty = evaluate(robot, Scene(), Q)
    none = evaluate(robot, None, Q)
    far = evaluate(robot, Scene((sphere_at((40.0, 0.0, 0.0), 1.0),)), Q)
    expected = avoidance(robot, Q).amsi
    # the Panda's own links may be near each other: where they are, the self term lowers S (tested on its own)
    alone = empty.self_distance >= Potential().self_influence_distance
    assert alone.all() if robot_name == "planar4" else 0.5 < alone.mean() < 1.0
    for result in (empty, none, far):
        np.testing.assert_array_equal(result.self_distance, empty.self_distance)
        np.testing.assert_allclose(result.S[alone], result.amsi[alone])
        np.testing.assert_allclose(result.amsi, expected, rtol=1e-9)
        np.testing.assert_array_equal(result.U[alone], 0.0)
        assert not result.collision.any()
    assert np.all(np.isinf(empty.min_distance))
    assert np.all(far.min_distance > 30.0)
    # an obstacle just beyond the influence distance has no effect either
    potential = Potential(influence_distance=0.05)
    if robot_name == "planar4":
        q = np.zeros(4)
        just_out = evaluate(robot, Scene((sphere_at((1.0, 0.1 + 0.03 + 0.0501, 0.0), 0.1),)), q, potential=potential)
        assert just_out.min_distance[0] > 0.05
        assert just_out.S[0] == just_out.amsi[0]


@pytest.mark.parametrize("method", METHODS)
def test_s_decreases_as_sphere_approaches(planar4: Robot, method: str) -> None:
    """q = 0; a sphere of radius 0.1 comes down onto the middle of link 2 from y = 0.6."""
    q = np.zeros(4)
    heights = np.linspace(0.6, 0.131, 60)
    S, dist = [], []
    for y in heights:
        result = evaluate(planar4, Scene((sphere_at((1.125, float(y), 0.0), 0.1),)), q, method=method)
        S.append(result.S[0])
        dist.append(result.min_distance[0])
    S_arr, d_arr = np.array(S), np.array(dist)
    np.testing.assert_allclose(d_arr, heights - 0.13, atol=1e-9)
    E = avoidance(planar4, q).amsi
    d0 = Potential().influence_distance
    assert np.all(np.diff(S_arr) <= 0.0)
    inside = d_arr < d0
    assert inside.sum() > 10
    assert np.all(np.diff(S_arr[inside]) < 0.0)  # strictly, once within the influence distance
    np.testing.assert_allclose(S_arr[~inside], E)
    assert 0.0 < S_arr[-1] < 0.05 * E  # gain 1: S -> 0 at contact
    touching = evaluate(planar4, Scene((sphere_at((1.125, 0.12, 0.0), 0.1),)), q, method=method)
    assert touching.S[0] < 0


def test_potential_shape(planar4: Robot) -> None:
    """phi(d) = g clip((d0 - d) / d0, 0, 1)^2 and S = E (1 - phi(d)) for one link in range."""
    q = np.zeros(4)
    potential = Potential(influence_distance=0.2, gain=0.5)
    d = 0.08
    # a sphere only near link 3: centre above (1.8, .) so links 1-2 and 4 are out of range
    result = evaluate(planar4, Scene((sphere_at((1.8, 0.13 + d, 0.0), 0.1),)), q, potential=potential)
    np.testing.assert_allclose(result.link_distances[0, 2], d, atol=1e-12)
    assert result.link_distances[0, 1] > 0.2 and result.link_distances[0, 3] > 0.2
    phi = 0.5 * ((0.2 - d) / 0.2) ** 2
    np.testing.assert_allclose(result.S, result.amsi * (1.0 - phi), rtol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gain": 0.0}, "gain"),
        ({"gain": 1.5}, "gain"),
        ({"influence_distance": -0.1}, "influence_distance"),
        ({"influence_distance": 0.0}, "influence_distance"),
        ({"influence_distance": float("nan")}, "influence_distance"),
        ({"collision_value": 1.0}, "collision_value"),
        ({"collision_value": 0.0}, "collision_value"),
    ],
)
def test_potential_validation(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ParameterError, match=match) as info:
        Potential(**kwargs)
    assert isinstance(info.value, PreviewctlError)
    assert repr(next(iter(kwargs.values())))[:3] in str(info.value)


def test_index_params_validation() -> None:
    with pytest.raises(ParameterError, match=r"length_unit must be > 0, got 0\.0"):
        IndexParams(length_unit=0.0)
    with pytest.raises(ParameterError, match=r"weights\[1\] must be >= 0, got -1\.0"):
        IndexParams(weights=(1.0, -1.0, 1.0))
    with pytest.raises(ParameterError, match=r"rank_tolerance must lie in \(0, 1\), got 2\.0"):
        IndexParams(rank_tolerance=2.0)


def test_evaluator_method_errors(planar4: Robot, panda: Robot) -> None:
    with pytest.raises(ParameterError, match=r"method = 'fast' is not valid; valid: auto, planar, general"):
        Evaluator(planar4, method="fast")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="planar path"):
        evaluate(panda, None, panda.neutral(), method="planar")
    # a box tilted out of the plane cannot take the planar path: "auto" falls back to general
    tilted = Obstacle(
        "box", previewctl.Box((0.2, 0.2, 0.2)), Static(np.array([1.0, 1.0, 0.0]), pin.rpy.rpyToMatrix(0.5, 0.3, 0.0))
    )
    evaluator = Evaluator(planar4, Scene((tilted,)))
    assert not evaluator.uses_planar_path()
    with pytest.raises(ParameterError, match="box"):
        Evaluator(planar4, Scene((tilted,)), method="planar")(np.zeros(4))


# ------------------------------------------------------------------------------ batch == single


def moving_scene() -> Scene:
    return Scene(
        (
            sphere_at((1.0, 0.9, 0.0), 0.3),
            Obstacle(
                "runner",
                previewctl.Sphere(0.2),
                ConstantVelocity(np.array([-1.0, 1.0, 0.0]), np.array([0.3, 0.0, 0.0])),
            ),
            Obstacle("floor", previewctl.Halfspace((0.0, 1.0, 0.0), -1.6)),
        )
    )


def assert_same_evaluation(a: previewctl.Evaluation, b: previewctl.Evaluation, distance_atol: float = 1e-12) -> None:
    """Equal evaluations; distances within ``distance_atol`` [m], S within what that allows.

    Coal's GJK (convex hulls, boxes) stops at ``gjk_tolerance = 1e-6`` [m], so its distances carry
    errors of ~1e-7 [m]; with ``|d phi / d d| <= 2 g / d_0`` they move S by at most
    ``E * 2 / d_0 * sum_i |delta d_i|``.
    """
    for name in ("amsi", "tip_position"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-12, err_msg=name)
    np.testing.assert_array_equal(a.collision, b.collision)
    finite = np.isfinite(b.link_distances)
    np.testing.assert_array_equal(np.isfinite(a.link_distances), finite)
    np.testing.assert_allclose(a.link_distances[finite], b.link_distances[finite], rtol=0, atol=distance_atol + 1e-12)
    np.testing.assert_allclose(a.min_distance, b.min_distance, rtol=0, atol=distance_atol + 1e-12)
    gap = np.abs(np.where(finite, a.link_distances - b.link_distances, 0.0)).sum(axis=1)
    bound = 1e-12 * (1.0 + np.abs(b.S)) + b.amsi * 2.0 / Potential().influence_distance * gap
    assert np.all(np.abs(a.S - b.S) <= bound)
    assert np.all(np.abs(a.U - b.U) <= bound + 1e-12 * np.abs(b.amsi))


def row(evaluation: previewctl.Evaluation, b: int) -> previewctl.Evaluation:
    """Entry ``b`` of a batch evaluation, as a batch of one."""
    return previewctl.Evaluation(**{f.name: getattr(evaluation, f.name)[b : b + 1] for f in fields(evaluation)})


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("t", [0.0, 2.0])
def test_batch_equals_single_planar4(planar4: Robot, method: str, t: float) -> None:
    scene = moving_scene()
    Q = np.random.default_rng(31).uniform(-np.pi, np.pi, size=(40, 4))
    batch = evaluate(planar4, scene, Q, t, method=method)
    assert batch.S.shape == (40,)
    assert batch.link_distances.shape == (40, 4)
    for b in range(len(Q)):
        single = evaluate(planar4, scene, Q[b], t, method=method)
        assert single.S.shape == (1,)
        assert_same_evaluation(single, row(batch, b))


def test_batch_equals_single_panda_and_evaluator_reuse(panda: Robot) -> None:
    """General path; one Evaluator called at several times gives what fresh ones give."""
    rng = np.random.default_rng(4)
    Q = panda.random_configurations(rng, 12)
    scene = Scene(
        (
            Obstacle(
                "runner",
                previewctl.Sphere(0.12),
                ConstantVelocity(np.array([0.3, -0.4, 0.4]), np.array([0.0, 0.4, 0.0])),
            ),
            Obstacle("table", previewctl.Box((1.0, 1.0, 0.05)), Static(np.array([0.5, 0.0, 0.1]))),
        )
    )
    evaluator = Evaluator(panda, scene)
    assert not evaluator.uses_planar_path()
    for t in (1.0, 0.0, 2.0):
        batch = evaluator(Q, t)
        fresh = evaluate(panda, scene, Q, t)
        assert_same_evaluation(batch, fresh, GJK_TOL)
        for b in range(len(Q)):
            single = evaluate(panda, scene, Q[b], t)
            assert_same_evaluation(single, row(batch, b), GJK_TOL)
    # the moving sphere actually changes the distances
    assert not np.allclose(evaluator(Q, 0.0).link_distances, evaluator(Q, 2.0).link_distances)


@pytest.mark.parametrize("robot_name", ["panda", "panda_mesh"])
def test_screened_distances_keep_s_and_bound_the_far_pairs(robot_name: str, request: pytest.FixtureRequest) -> None:
    """``exact_below``: S bit for bit, every distance below the screen exact, the others lower bounds at least it; a
    half-space is never screened out."""
    robot: Robot = request.getfixturevalue(robot_name)
    rng = np.random.default_rng(7)
    Q = robot.random_configurations(rng, 40)
    obstacles = [Obstacle(f"ball{i}", previewctl.Sphere(0.06), Static(centre))
                 for i, centre in enumerate(random_spheres_near_arm(robot, rng, Q[:3]))]
    floor = Obstacle("floor", previewctl.Halfspace((0.0, 0.0, 1.0), -0.3), Static(np.zeros(3)))
    evaluator = Evaluator(robot, Scene((*obstacles, floor)))
    exact = evaluator(Q, 0.0)
    for below in (0.0, 0.2):
        screened = evaluator(Q, 0.0, exact_below=below)
        within = max(below, evaluator.potential.influence_distance)
        np.testing.assert_array_equal(screened.S, exact.S)
        near = exact.link_distances < within
        assert near.any() and (~near).any()
        np.testing.assert_array_equal(screened.link_distances[near], exact.link_distances[near])
        far = screened.link_distances[~near]
        assert np.all(far >= within) and np.all(far <= exact.link_distances[~near] + 1e-12)
        assert np.any(far < exact.link_distances[~near])  # bounds, not the exact distances
    # the half-space alone: every pair computed
    alone = Evaluator(robot, Scene((floor,)))
    np.testing.assert_array_equal(alone(Q, exact_below=0.0).link_distances, alone(Q).link_distances)


def test_the_s_only_callers_screen_and_get_the_exact_s(panda: Robot) -> None:
    """The GA's scoring and the gradient ask for ``POTENTIAL_ONLY``: the same ``S`` and collisions as exact distances
    everywhere, on balls near and far, some touching the arm."""
    rng = np.random.default_rng(11)
    Q = panda.random_configurations(rng, 60)
    obstacles = [Obstacle(f"ball{i}", previewctl.Sphere(0.06), Static(centre))
                 for i, centre in enumerate(random_spheres_near_arm(panda, rng, Q[:4]))]
    evaluator = Evaluator(panda, Scene(tuple(obstacles)))
    exact = evaluator(Q, 0.0)
    assert exact.collision.any() and (exact.min_distance > evaluator.potential.influence_distance).any()
    assert (np.isfinite(exact.S) & (exact.S > 0.0)).any()
    scored = score_configurations(evaluator, Q, np.ones(len(Q), dtype=bool))
    np.testing.assert_array_equal(scored.S, exact.S)
    np.testing.assert_array_equal(scored.collision, exact.collision | exact.self_collision)
    q, h, nv = Q[0], 1e-4, panda.nv
    steps = np.concatenate([np.eye(nv), -np.eye(nv)]) * h
    batch = np.stack([pin.integrate(panda.model, q, d) for d in steps])
    S = evaluator(batch, 0.0).S
    params = ControllerParams(gradient_gain=(1.0,), fd_step=h)
    np.testing.assert_array_equal(AmsipGradient(panda, evaluator, params).gradient(q, 0.0),
                                  (S[:nv] - S[nv:]) / (2.0 * h))


def test_evaluator_is_reproducible(panda: Robot) -> None:
    """The same batch through the same Evaluator, again and in reverse order: identical numbers."""
    Q = panda.random_configurations(np.random.default_rng(4), 12)
    table = Obstacle("table", previewctl.Box((1.0, 1.0, 0.05)), Static(np.array([0.5, 0.0, 0.1])))
    evaluator = Evaluator(panda, Scene((table,)))
    first = evaluator(Q)
    again = evaluator(Q)
    reverse = evaluator(Q[::-1])
    np.testing.assert_array_equal(again.link_distances, first.link_distances)
    np.testing.assert_array_equal(reverse.link_distances[::-1], first.link_distances)
    np.testing.assert_array_equal(again.S, first.S)


def test_evaluate_does_not_mutate_input(planar4: Robot) -> None:
    Q = np.random.default_rng(1).uniform(-np.pi, np.pi, size=(5, 4))
    copy = Q.copy()
    evaluate(planar4, moving_scene(), Q)
    evaluate(planar4, moving_scene(), Q, method="general")
    avoidance(planar4, Q)
    np.testing.assert_array_equal(Q, copy)


# ---------------------------------------------------------------------------------------- self pairs


def srdf_disabling(path: Path, pairs: list[tuple[str, str]], robot: str) -> Path:
    lines = "\n".join(f'  <disable_collisions link1="{a}" link2="{b}" reason="test"/>' for a, b in pairs)
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{robot}">\n{lines}\n</robot>\n')
    return path


def test_self_term_is_zero_beyond_its_influence_distance_and_s_negative_in_self_contact() -> None:
    potential = Potential()
    d_s = potential.self_influence_distance
    assert d_s == 0.05
    amsi = np.full(7, 1234.5)
    links = np.full((7, 2), np.inf)
    self_distance = np.array([np.inf, 1.0, d_s, d_s * 0.999, 0.5 * d_s, 0.0, -0.01])
    S, U, collision = potential.apply(amsi, links, self_distance)
    np.testing.assert_array_equal(S[:3], amsi[:3])  # at and beyond d_s: nothing, bit for bit
    np.testing.assert_array_equal(U[:3], 0.0)
    ramp = (d_s - self_distance[3:5]) / d_s
    np.testing.assert_allclose(S[3:5], amsi[3:5] * (1.0 - ramp**2), rtol=1e-12)
    assert 0.0 < S[4] < S[3] < amsi[3]  # nearer, lower
    np.testing.assert_array_equal(S[5:], potential.collision_value)  # in contact: negative
    assert not collision.any()  # the flag is the obstacles'; self-contact is Evaluation.self_collision


def test_s_is_negative_exactly_where_the_panda_hits_itself(panda: Robot) -> None:
    evaluator = Evaluator(panda)
    Q = panda.random_configurations(np.random.default_rng(21), 300)
    result = evaluator(Q)
    assert 0.01 < result.self_collision.mean() < 0.3
    np.testing.assert_array_equal(result.S < 0, result.self_collision)
    np.testing.assert_array_equal(result.S[result.self_collision], evaluator.potential.collision_value)
    far = result.self_distance >= evaluator.potential.self_influence_distance
    np.testing.assert_array_equal(result.S[far], result.amsi[far])
    near = ~far & ~result.self_collision
    assert near.any() and np.all((result.S[near] < result.amsi[near]) & (result.S[near] > 0))
    assert not result.collision.any()
    names = {panda.self_pairs.pair_names(int(k)) for k in result.self_pair[result.self_collision]}
    assert names and names <= set(panda.self_pairs.links)


@pytest.mark.parametrize("method", METHODS)
def test_an_arm_without_self_pairs_keeps_its_s_bit_for_bit(planar4: Robot, method: str) -> None:
    """planar4 (its SRDF disables every pair): S is the obstacle potential alone, as before self pairs existed."""
    scene = Scene((sphere_at((1.0, 0.9, 0.0), 0.3), sphere_at((-1.2, -0.5, 0.0), 0.25, "ball2")))
    Q = np.random.default_rng(4).uniform(-np.pi, np.pi, (300, 4))
    result = evaluate(planar4, scene, Q, method=method)
    S, U, collision = Potential().apply(result.amsi, result.link_distances)  # without a self term
    np.testing.assert_array_equal(result.collision, collision)
    np.testing.assert_array_equal(result.S, S)
    np.testing.assert_array_equal(result.U, U)
    assert np.all(np.isinf(result.self_distance)) and np.all(result.self_pair == -1)
    assert not result.self_collision.any()


def test_a_panda_whose_pairs_are_all_disabled_keeps_its_s_bit_for_bit(panda: Robot, tmp_path: Path) -> None:
    links = sorted({link for pair in panda.self_pairs.links for link in pair} | {"panda_link3", "panda_link4"})
    every = [(a, b) for i, a in enumerate(links) for b in links[i + 1:]]
    none = previewctl.load_robot("panda", srdf=srdf_disabling(tmp_path / "none.srdf", every, "panda"))
    assert len(none.self_pairs) == 0
    scene = Scene((sphere_at((0.4, 0.2, 0.5), 0.1),))
    Q = panda.random_configurations(np.random.default_rng(2), 64)
    result = evaluate(none, scene, Q)
    S, _, _ = Potential().apply(result.amsi, result.link_distances)
    np.testing.assert_array_equal(result.S, S)


def test_a_planar_arm_with_self_pairs_takes_the_general_path(tmp_path: Path) -> None:
    adjacent = [("link1", "link2"), ("link2", "link3"), ("link3", "link4")]
    crossing = previewctl.load_robot("planar4", srdf=srdf_disabling(tmp_path / "adjacent.srdf", adjacent, "planar4"))
    assert crossing.self_pairs.links == (("link1", "link3"), ("link1", "link4"), ("link2", "link4"))
    evaluator = Evaluator(crossing)
    assert crossing.planar is not None and not evaluator.uses_planar_path()
    with pytest.raises(ParameterError, match=r"without self pairs.*\(3 self pairs\)"):
        Evaluator(crossing, method="planar")(np.zeros(4))
    Q = np.random.default_rng(9).uniform(-np.pi, np.pi, (300, 4))
    result = evaluator(Q)
    assert result.self_collision.any()  # in one plane, crossing links touch
    np.testing.assert_array_equal(result.S < 0, result.self_collision)
