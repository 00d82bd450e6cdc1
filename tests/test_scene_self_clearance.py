"""Tests of :mod:`previewctl.scene.self_clearance`: self-pair distances and witnesses against Coal called directly,
and the numpy bounds that spare Coal the far pairs (never above the true distance)."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from previewctl import load_robot
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import kinematics
from previewctl.robot.model import Geometry, Robot
from previewctl.scene.clearance import Clearance
from previewctl.scene.self_clearance import _DIRECTIONS, SelfClearance
from previewctl.scene.shapes import Scene
from previewctl.types import Array


def coal_pair(robot: Robot, data: pin.Data, pair: int) -> tuple[float, coal.DistanceResult]:
    """Coal's own distance between the two geometries of self pair ``pair`` at the joint placements in ``data``."""
    geometry = robot.self_pairs.geometry
    p = geometry.collisionPairs[pair]
    shapes, transforms = [], []
    for g in (geometry.geometryObjects[p.first], geometry.geometryObjects[p.second]):
        placement = data.oMi[g.parentJoint] * g.placement
        shapes.append(g.geometry)
        transforms.append(coal.Transform3s(placement.rotation, placement.translation))
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    distance = coal.distance(shapes[0], transforms[0], shapes[1], transforms[1], request, result)
    return float(distance), result


def configurations(robot: Robot, count: int, seed: int) -> Array:
    return robot.random_configurations(np.random.default_rng(seed), count)


def test_self_distances_and_witnesses_match_coal_called_on_each_pair(panda: Robot) -> None:
    clearance = Clearance(robot=panda, scene=Scene())
    data = panda.model.createData()
    near_seen = 0
    for q in configurations(panda, 40, 3):
        pin.computeJointJacobians(panda.model, data, q)  # what the QP calls before asking for witnesses
        ours = clearance.self_clearance.pair_distances(data)
        direct = [coal_pair(panda, data, k) for k in range(len(ours))]
        np.testing.assert_allclose(ours, [d for d, _ in direct], atol=1e-6)
        witnesses = clearance.self_witnesses(data, within=0.05)
        expected = [k for k, (d, _) in enumerate(direct) if d < 0.05]
        assert witnesses.pairs.tolist() == expected  # the bounds never hide a pair within reach
        near_seen += len(expected)
        for i, k in enumerate(witnesses.pairs):
            d, result = direct[k]
            assert witnesses.distance[i] == pytest.approx(d, abs=1e-6)
            np.testing.assert_allclose(witnesses.point_a[i], result.getNearestPoint1(), atol=1e-6)
            np.testing.assert_allclose(witnesses.point_b[i], result.getNearestPoint2(), atol=1e-6)
            np.testing.assert_allclose(np.linalg.norm(witnesses.normal[i]), 1.0, atol=1e-9)
            if d > 1e-4:  # apart: the normal points from a's nearest point to b's, and spans the distance
                gap = witnesses.point_b[i] - witnesses.point_a[i]
                np.testing.assert_allclose(gap, d * witnesses.normal[i], atol=1e-5)
            first = panda.self_pairs.geometry.collisionPairs[int(k)]
            objects = panda.self_pairs.geometry.geometryObjects
            assert witnesses.joint_a[i] == objects[first.first].parentJoint
            assert witnesses.joint_b[i] == objects[first.second].parentJoint
        every = clearance.self_witnesses(data)  # no reach: every pair
        assert every.pairs.tolist() == list(range(len(ours)))
    assert near_seen >= 5  # random Panda configurations do bring links close


@pytest.mark.parametrize("name, geometry", [("panda", "convex"), ("panda", "mesh"), ("ur5", "capsules"),
                                            ("kinova", "convex")])
def test_bounds_never_exceed_the_distance(name: str, geometry: Geometry) -> None:
    robot = load_robot(name, geometry=geometry)
    self_clearance = SelfClearance(robot)
    Q = configurations(robot, 60 if geometry == "mesh" else 300, 5)
    placements = kinematics(robot, Q, reader=Evaluator(robot)._kinematics).joint_placements
    data = robot.model.createData()
    exact = []
    for q in Q:
        pin.forwardKinematics(robot.model, data, q)
        exact.append(self_clearance.pair_distances(data))
    exact_array = np.maximum(np.array(exact), 0.0)
    bounds = self_clearance.bounds(placements)
    assert (bounds <= exact_array).all()
    rows, pairs = np.nonzero(bounds < 0.05)
    refined = self_clearance.refine(placements, rows, pairs)
    assert (refined <= exact_array[rows, pairs]).all()
    assert (np.maximum(refined, bounds[rows, pairs]) >= 0.05).mean() > 0.2  # the second step does prune


def test_batch_nearest_is_exact_below_the_influence_distance_and_a_bound_above(panda: Robot) -> None:
    evaluator = Evaluator(panda)
    within = evaluator.potential.self_influence_distance
    Q = configurations(panda, 200, 8)
    result = evaluator(Q)
    data = panda.model.createData()
    close = 0
    for b, q in enumerate(Q):
        pin.forwardKinematics(panda.model, data, q)
        exact = np.maximum(evaluator.clearance.self_clearance.pair_distances(data), 0.0)  # unsigned in batches
        if exact.min() < within:
            close += 1
            assert result.self_distance[b] == pytest.approx(exact.min(), abs=1e-9)
            assert exact[result.self_pair[b]] == pytest.approx(exact.min(), abs=1e-9)
        else:
            assert within <= result.self_distance[b] <= exact.min()
    np.testing.assert_array_equal(result.self_collision, result.self_distance <= 0.0)
    assert 10 < close < 190


def test_compiled_bounds_equal_their_formulas_in_numpy(panda: Robot) -> None:
    """Step 1 (spheres) and step 2 (DOP against capsule) over random joint placements, against the formulas of the
    module docstring written in numpy."""
    clearance = SelfClearance(panda)
    rng = np.random.default_rng(8)
    count = len(clearance.joints)
    placements = np.zeros((20, count, 4, 4))
    for b in range(20):
        for j in range(count):
            placements[b, j] = pin.SE3.Random().homogeneous
    carried = placements[:, clearance._slot]
    centres = np.einsum("bgij,gj->bgi", carried[..., :3, :3], clearance._centres) + carried[..., :3, 3]
    gap = centres[:, clearance._a] - centres[:, clearance._b]
    np.testing.assert_allclose(clearance.bounds(placements), np.linalg.norm(gap, axis=2) - clearance._reach,
                               rtol=0, atol=1e-12)
    rows, pairs = rng.integers(0, 20, 50), rng.integers(0, len(clearance), 50)
    held = placements[rows, clearance._dop_slot[pairs]]
    other = placements[rows, clearance._capsule_slot[pairs]]
    world = np.einsum("cij,cej->cei", other[:, :3, :3], clearance._capsule_ends[pairs]) + other[:, None, :3, 3]
    local = np.einsum("cji,cej->cei", held[:, :3, :3], world - held[:, None, :3, 3])
    along = local @ _DIRECTIONS.T  # (C, 2, 26)
    expected = (np.minimum(along[:, 0], along[:, 1]) - clearance._dop_support[pairs]).max(axis=1)
    np.testing.assert_allclose(clearance.refine(placements, rows, pairs), expected - clearance._capsule_radius[pairs],
                               rtol=0, atol=1e-12)
